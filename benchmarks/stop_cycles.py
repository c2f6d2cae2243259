"""Stop-cycle benchmark: does every stop of ``twin serve`` end cleanly, under load?

Each cycle starts the daemon on the sample lab (imported once), acks an observation, puts SPARQL and
status queries under load from several threads of this process, and while they run stops the daemon,
SIGINT and SIGTERM alternating. Every third cycle records to Rerun (the recorder child and its threads
are stopped too), every other one starts from the snapshot the previous stop wrote. A clean stop exits
0 and prints ``stopped cleanly``; the run counts exit codes and ``FATAL`` lines (glibc's ``FATAL:
exception not rethrown`` is a thread re-entering Python during the interpreter's finalization, which
ends in SIGABRT, code -6).

Usage::

    nice -n 10 python benchmarks/stop_cycles.py [--cycles 200] [--load-threads 4] [--json OUT.json]
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
TWIN = "https://w3id.org/building-twin#"
HEAVY = "SELECT (COUNT(*) AS ?n) WHERE { ?s ?p ?o . ?s ?q ?v }"
"""A query that runs for a while on the lab (a join of every triple with its subject's others)."""


def _twin(*args: str | Path) -> list[str]:
    return [sys.executable, "-m", "adapters.cli", *map(str, args)]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _prepare(work: Path) -> Path:
    subprocess.run(_twin("sample", "lab", work / "lab.ifc"), check=True, cwd=ROOT, capture_output=True)
    subprocess.run(_twin("import", work / "lab.ifc", "--store", work / "store"), check=True, cwd=ROOT,
                   capture_output=True)  # fmt: skip
    return work / "store"


def _load(endpoint: str, stop: threading.Event, counts: collections.Counter[str]) -> None:
    """SPARQL (light and heavy) and status queries until ``stop`` or the daemon is gone."""
    from adapters.zenoh.client import TwinClient

    try:
        with TwinClient.connect([endpoint], prefix="twin/lab", timeout_s=2.0) as client:
            i = 0
            while not stop.is_set():
                i += 1
                try:
                    if i % 3 == 0:
                        client.sparql(HEAVY)
                    elif i % 3 == 1:
                        client.sparql("SELECT ?s WHERE { ?s a <https://w3id.org/bot#Storey> }")
                    else:
                        client.status()
                    counts["answered"] += 1
                except Exception:  # the daemon is stopping: expected
                    counts["failed"] += 1
    except Exception:
        counts["no-session"] += 1


def _robots_config(work: Path, robots: int, workers: int) -> Path:
    """``robots`` robots with detections (bridge keys) and ``workers`` ingest worker processes."""
    path = work / "robots.toml"
    path.write_text(
        f"[ros]\ningest_workers = {workers}\n"
        + "".join(
            f'[robots.robot{r}]\nnamespace = "/robot{r}"\nstorey = "ground-floor"\nros = ["bridge"]\n'
            f'[robots.robot{r}.detections]\nclasses = {{ table = "IfcFurniture" }}\n'
            for r in range(robots)
        )
    )
    return path


def _arrays(endpoint: str, robots: int, stop: threading.Event) -> None:
    """Every robot's TF and an array of 5 tables at 10 Hz until ``stop`` (the workers busy at the stop)."""
    import zenoh

    from adapters.zenoh.session import client_config
    from tests.adapters.ros_reports import Det, Tf, cdr_detections, cdr_tf

    try:
        with zenoh.open(client_config([endpoint])) as session:
            while not stop.is_set():
                stamp = time.time_ns()
                for r in range(robots):
                    session.put(
                        f"robot{r}/tf", cdr_tf([Tf("map", "base_link", (15.0, 7.0, 0.0), stamp_ns=stamp)])
                    )
                    dets = [Det((("table", 0.9),), (0.3 * i - 0.6, 0.8, 0.375), (0.2, 0.2, 0.75), id=f"t{i}")
                            for i in range(5)]  # fmt: skip
                    session.put(f"robot{r}/detections", cdr_detections(stamp, "base_link", dets))
                time.sleep(0.1)
    except Exception:  # the daemon is stopping: expected
        return


def cycle(
    store: Path, work: Path, i: int, *, load_threads: int, robots: int = 0, workers: int = 1
) -> dict[str, Any]:
    sig = signal.SIGINT if i % 2 == 0 else signal.SIGTERM
    endpoint = f"tcp/127.0.0.1:{_free_port()}"
    record = ["--record", str(work / f"run{i}.rrd")] if i % 3 == 0 else ["--no-record"]
    snapshot = [] if i % 2 == 1 else ["--no-snapshot"]
    config = ["--config", str(_robots_config(work, robots, workers))] if robots else []
    t0 = time.monotonic()
    process = subprocess.Popen(
        _twin(*config, "serve", "--store", store, "--listen", endpoint, *record, *snapshot),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    assert process.stdout is not None
    lines: list[str] = []
    while (line := process.stdout.readline()) and "serving site" not in line:
        lines.append(line.rstrip())
    if not line:
        process.wait(timeout=30)
        return {"cycle": i, "signal": sig.name, "code": process.returncode, "fatal": 0, "started": False,
                "log": lines[-20:]}  # fmt: skip
    started_s = time.monotonic() - t0
    from adapters.zenoh.client import TwinClient

    acked = False
    with TwinClient.connect([endpoint], prefix="twin/lab", timeout_s=10.0) as client:
        box = f"{15 + (i % 20) * 0.1:.1f} 7.0 0.375 0.6 0.6 0.75 0.0"
        turtle = (f'<urn:stop-cycle:table> <{TWIN}ifcClass> "IfcFurniture" ; '
                  f'<{TWIN}storey> "ground-floor" ; <{TWIN}box> "{box}" .')  # fmt: skip
        acked = bool(client.observe("robot1", turtle).get("ok"))
    stop = threading.Event()
    counts: collections.Counter[str] = collections.Counter()
    threads = [threading.Thread(target=_load, args=(endpoint, stop, counts)) for _ in range(load_threads)]
    if robots:
        threads.append(threading.Thread(target=_arrays, args=(endpoint, robots, stop)))
    for t in threads:
        t.start()
    time.sleep(0.5)  # queries in flight, some heavy
    t1 = time.monotonic()
    process.send_signal(sig)
    try:
        out, _ = process.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        process.kill()
        out, _ = process.communicate()
    stop_s = time.monotonic() - t1
    stop.set()
    for t in threads:
        t.join()
    lines += out.splitlines()
    return {
        "cycle": i,
        "signal": sig.name,
        "code": process.returncode,
        "fatal": sum("FATAL" in ln for ln in lines),
        "clean_line": any("stopped cleanly" in ln for ln in lines),
        "started": True,
        "start_s": round(started_s, 2),
        "stop_s": round(stop_s, 2),
        "acked": acked,
        "queries": dict(counts),
        "log": [ln for ln in lines if "FATAL" in ln or "rror" in ln or "stop" in ln][-10:],
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cycles", type=int, default=200)
    p.add_argument("--load-threads", type=int, default=4)
    p.add_argument("--json", type=Path, help="write every cycle's result here")
    p.add_argument("--robots", type=int, default=0, help="robots with detections publishing arrays at 10 Hz")
    p.add_argument("--workers", type=int, default=1, help="[ros] ingest_workers with --robots")
    args = p.parse_args()
    sys.path.insert(0, str(ROOT))
    results: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="stop-cycles-") as tmp:
        work = Path(tmp)
        store = _prepare(work)
        for i in range(args.cycles):
            r = cycle(
                store, work, i, load_threads=args.load_threads, robots=args.robots, workers=args.workers
            )
            results.append(r)
            for rrd in work.glob("run*.rrd"):
                rrd.unlink()
            bad = r["code"] != 0 or r["fatal"] or not r.get("clean_line")
            print(f"cycle {i:4d} {r['signal']:7s} exit {r['code']:4d} fatal {r['fatal']} "
                  f"stop {r.get('stop_s', 0):5.2f} s" + ("  <-- " + " | ".join(r["log"]) if bad else ""),
                  file=sys.stderr, flush=True)  # fmt: skip
    codes = collections.Counter((r["signal"], r["code"]) for r in results)
    stops = [r["stop_s"] for r in results if "stop_s" in r]
    print("| signal | exit code | cycles |")
    print("|---|---:|---:|")
    for (sig, code), n in sorted(codes.items()):
        print(f"| {sig} | {code} | {n} |")
    fatal = sum(r["fatal"] for r in results)
    print(f"\n{len(results)} cycles: {sum(r['code'] == 0 for r in results)} exited 0, {fatal} FATAL line(s); "
          f"stop median {statistics.median(stops):.2f} s, max {max(stops):.2f} s")  # fmt: skip
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0 if all(r["code"] == 0 and not r["fatal"] for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
