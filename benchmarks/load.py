"""Load test of the live twin: many robot processes sending acked observations, many map subscribers.

The daemon (``twin serve``, on-disk store of the generated lab, no recording), every robot and every
subscriber run as separate processes on loopback. Each robot owns a table that it moves around the
ground floor's corridor at ``--rate`` acked observations per second (every 40th observation it removes
the table and adds a new one), for ``--duration`` seconds. Each subscriber keeps a copy of every
ground-floor map (``MapWatcher``: the latched map, then the updates). At the end:

- no acknowledged observation lost: each robot's last acked change of each of its tables is the one in
  the graph (its ``twin:revision``), and each removed table is removed;
- no map left behind: every subscriber's final copy of every map equals the daemon's final map (same
  version, same cells);
- latency: from sending an observation to a subscriber's receipt of the first navigation map version
  that includes it (an update of its revision or later: under load the daemon commits queued
  observations one by one but brings the maps up to date once for all of them), over every
  subscriber and every acked observation that changed the navigation map, p50/p99;
- memory: the daemon's RSS sampled every 0.25 s; growth after warm-up (the first quarter of the run).

The full run (the benchmark)::

    python benchmarks/load.py --robots 10 --rate 20 --duration 60 --subscribers 10 --json load.json

The suite runs a short one (``tests/integration/test_load.py``). Exit code 1 if an ack was lost or a
subscriber was left behind.
"""

from __future__ import annotations

import argparse
import bisect
import hashlib
import json
import random
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import live  # benchmarks/ is not a package

TWIN = live.TWIN
STOREY = "ground-floor"
SKILLS = ("navigation", "lab-navigation", "localization", "lab-localization")
CORRIDOR = (11.0, 21.0, 5.5, 8.5)  # x0, x1, y0, y1 on the lab's ground floor


def _digest(data: np.ndarray) -> str:
    return hashlib.sha1(np.ascontiguousarray(data).tobytes()).hexdigest()[:16]


# --- the child processes -------------------------------------------------------------------------------
def robot(endpoint: str, index: int, rate: float, duration: float, start_at: float) -> int:
    """Send acked observations at ``rate`` per second until ``duration`` has passed; one JSON line each."""
    from adapters.zenoh.client import TwinClient
    from twin.errors import TwinError

    rng = random.Random(index)
    last = (-1e9, -1e9)  # where its table was last sent
    name = f"robot{index}"
    x0, x1, y0, y1 = CORRIDOR
    table, generation, added = f"urn:load:{name}:table-0", 0, False
    with TwinClient.connect([endpoint], timeout_s=10.0) as twin:
        time.sleep(max(0.0, start_at - time.time()))
        i, t_end = 0, start_at + duration
        while time.time() < t_end:
            due = start_at + i / rate
            time.sleep(max(0.0, due - time.time()))
            if added and i % 40 == 39:
                op, payload = "remove", f"<{table}> <{TWIN}removed> true ."
            else:
                op = "move" if added else "add"
                x, y, yaw = rng.uniform(x0, x1), rng.uniform(y0, y1), rng.uniform(0, 3)
                while abs(x - last[0]) + abs(y - last[1]) < 0.8:  # a move fusion applies at once
                    x, y = rng.uniform(x0, x1), rng.uniform(y0, y1)
                last = (x, y)
                box = f"{x:.3f} {y:.3f} 0.375 0.8 0.6 0.75 {yaw:.3f}"
                payload = (
                    f'<{table}> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}distinct> true ; '
                    f'<{TWIN}storey> "{STOREY}" ; '
                    f'<{TWIN}box> "{box}" .'
                )
            sent = time.time()
            try:
                ack = twin.observe(name, payload)
                ok, revision = bool(ack.get("ok")), int(ack.get("revision", -1))
                nav = any(m["skill"] == "navigation" and m["storey"] == STOREY for m in ack.get("maps", []))
            except TwinError as err:
                ok, revision, nav = False, -1, False
                print(json.dumps({"error": str(err)}), file=sys.stderr, flush=True)
            line = {
                "iri": table,
                "op": op,
                "sent": sent,
                "acked": time.time(),
                "ok": ok,
                "revision": revision,
            }
            print(json.dumps(line | {"nav": nav}), flush=True)
            if ok and op == "remove":
                generation += 1
                table, added = f"urn:load:{name}:table-{generation}", False
            elif ok:
                added = True
            i += 1
    return 0


def subscriber(endpoint: str, storey: str = STOREY) -> int:
    """Watch every map of ``storey``; on EOF of stdin print the receipts and the final copies as JSON."""
    from adapters.zenoh.client import MapVersion, TwinClient

    lock = threading.Lock()
    receipts: list[tuple[str, int, float]] = []

    def on_version(v: MapVersion) -> None:
        with lock:
            receipts.append((v.grid.skill, v.revision, time.time()))

    with TwinClient.connect([endpoint], timeout_s=30.0) as twin:
        watchers = [twin.watch(storey, skill, on_version) for skill in SKILLS]
        print(json.dumps({"ready": True}), flush=True)
        sys.stdin.read()
        final = {
            w.skill: [w.latest.version, _digest(w.latest.grid.data)] if w.latest else None for w in watchers
        }
        for w in watchers:
            w.close()
    with lock:
        print(json.dumps({"final": final, "receipts": receipts}), flush=True)
    return 0


# --- the run -----------------------------------------------------------------------------------------
def _child(*args: str, stdin: bool = False) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, __file__, "--child", *args],
        stdin=subprocess.PIPE if stdin else subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=live.ROOT,
    )


def _check_graph(
    endpoint: str, attempts: list[dict[str, Any]], *, prefix: str = "urn:load:"
) -> tuple[int, list[str]]:
    """Compare the robots' acked changes with the graph: (acked changes checked, problems)."""
    from adapters.zenoh.client import TwinClient

    last: dict[str, dict[str, Any]] = {}
    for a in attempts:
        if a["ok"]:
            last[a["iri"]] = a
    with TwinClient.connect([endpoint], timeout_s=30.0) as twin:
        rows = twin.sparql(
            "SELECT ?e ?rev ?removed WHERE { ?e twin:revision ?rev . "
            f"FILTER(STRSTARTS(STR(?e), '{prefix}')) OPTIONAL {{ ?e twin:removed ?removed }} }}"
        )
    assert isinstance(rows, dict)
    graph = {b["e"]["value"]: (int(b["rev"]["value"]), "removed" in b) for b in rows["results"]["bindings"]}
    problems = []
    for iri, a in last.items():
        got = graph.get(iri)
        if got is None:
            problems.append(f"{iri}: acked at revision {a['revision']} but absent")
        elif got != (a["revision"], a["op"] == "remove"):
            problems.append(f"{iri}: acked {a['op']} at revision {a['revision']}, graph has {got}")
    return len(last), problems


def run(
    *, robots: int, rate: float, duration: float, subscribers: int, store: Path | None = None
) -> dict[str, Any]:
    from adapters.zenoh.client import TwinClient

    work = Path(tempfile.mkdtemp(prefix="load-"))
    store = store or live.prepare_store("lab", work)
    endpoint = f"tcp/127.0.0.1:{live._free_port()}"
    daemon, _ = live.serve("--store", str(store), "--listen", endpoint, "--no-record")
    assert daemon.stdout is not None
    threading.Thread(target=daemon.stdout.read, daemon=True).start()  # drain its log
    subs = [_child("subscriber", endpoint, stdin=True) for _ in range(subscribers)]
    for s in subs:
        assert s.stdout is not None and json.loads(s.stdout.readline())["ready"]
    start_at = time.time() + 1.0 + 0.1 * robots
    bots = [_child("robot", endpoint, str(i), str(rate), str(duration), str(start_at)) for i in range(robots)]
    outputs: list[tuple[list[str], list[str]]] = [([], []) for _ in bots]
    readers = []
    for b, (out, err) in zip(bots, outputs, strict=True):  # drain the pipes while the robots run
        readers += [
            threading.Thread(target=out.extend, args=(b.stdout,), daemon=True),
            threading.Thread(target=err.extend, args=(b.stderr,), daemon=True),
        ]
    for r in readers:
        r.start()
    rss: list[tuple[float, float]] = []
    while any(b.poll() is None for b in bots):
        rss.append((time.time() - start_at, live._proc_mb(daemon.pid, "VmRSS")))
        time.sleep(0.25)
    for r in readers:
        r.join(timeout=60)
    attempts: list[dict[str, Any]] = []
    errors: list[str] = []
    for out, err in outputs:
        attempts += [json.loads(ln) for ln in out if ln.startswith("{")]
        errors += [ln.strip() for ln in err if ln.strip()][:3]
    time.sleep(1.0)  # the last updates reach every subscriber
    with TwinClient.connect([endpoint], timeout_s=30.0) as twin:
        daemon_final = {}
        for skill in SKILLS:
            grid, _, version = twin.get_map(STOREY, skill)
            daemon_final[skill] = [version, _digest(grid.data)]
    checked, problems = _check_graph(endpoint, attempts)
    behind, receipts = 0, []
    for s in subs:
        out, _ = s.communicate(input="", timeout=60)
        result = json.loads(out.strip().splitlines()[-1])
        behind += int(result["final"] != daemon_final)
        receipts.append(result["receipts"])
    rss_peak = live._proc_mb(daemon.pid, "VmHWM")
    daemon.terminate()
    daemon.wait(timeout=30)

    acked = [a for a in attempts if a["ok"]]
    latencies = []
    for rec in receipts:  # per subscriber: the first navigation map version that includes the revision
        nav = sorted((int(r), float(t)) for skill, r, t in rec if skill == "navigation")
        revs = [r for r, _ in nav]
        first = np.minimum.accumulate([t for _, t in nav][::-1])[::-1] if nav else np.array([])
        for a in acked:
            k = bisect.bisect_left(revs, a["revision"])
            if a["nav"] and k < len(revs):
                latencies.append(float(first[k]) - a["sent"])
    acks = [a["acked"] - a["sent"] for a in acked]
    span = [(t, mb) for t, mb in rss if t >= duration / 4]  # after warm-up
    warm = [mb for _, mb in span]
    slope = (
        float(np.polyfit([t for t, _ in span], [mb for _, mb in span], 1)[0]) * 60 if len(span) > 2 else 0.0
    )
    return {
        "robots": robots,
        "rate_per_robot_hz": rate,
        "duration_s": duration,
        "subscribers": subscribers,
        "observations_sent": len(attempts),
        "observations_acked": len(acked),
        "acked_per_s": round(len(acked) / duration, 1),
        "refused_or_timed_out": len(attempts) - len(acked),
        "acked_changes_checked": checked,
        "lost_acks": len(problems),
        "subscribers_behind": behind,
        "update_latencies": len(latencies),
        "update_latency_p50_ms": round(live._pct(latencies, 50) * 1e3, 1),
        "update_latency_p99_ms": round(live._pct(latencies, 99) * 1e3, 1),
        "ack_p50_ms": round(live._pct(acks, 50) * 1e3, 1),
        "ack_p99_ms": round(live._pct(acks, 99) * 1e3, 1),
        "rss_after_warmup_mb": round(warm[0], 1) if warm else None,
        "rss_end_mb": round(rss[-1][1], 1) if rss else None,
        "rss_peak_mb": round(rss_peak, 1),
        "rss_growth_after_warmup_mb": round(warm[-1] - warm[0], 1) if warm else None,
        "rss_slope_mb_per_min": round(slope, 2),
        "problems": problems[:10],
        "robot_errors": errors[:10],
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--robots", type=int, default=10)
    p.add_argument("--rate", type=float, default=20.0, help="acked observations per second per robot")
    p.add_argument("--duration", type=float, default=60.0, help="seconds")
    p.add_argument("--subscribers", type=int, default=10)
    p.add_argument("--json", metavar="OUT.json", help="also write the result here")
    p.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child:
        kind, *rest = args.child
        if kind == "robot":
            return robot(rest[0], int(rest[1]), float(rest[2]), float(rest[3]), float(rest[4]))
        return subscriber(*rest[:2])
    print(
        f"load: {args.robots} robots x {args.rate:g} obs/s for {args.duration:g} s, "
        f"{args.subscribers} subscribers ...",
        file=sys.stderr,
    )
    result = run(robots=args.robots, rate=args.rate, duration=args.duration, subscribers=args.subscribers)
    width = max(map(len, result))
    for key, value in result.items():
        print(f"{key:<{width}}  {value}")
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2))
    return 1 if result["lost_acks"] or result["subscribers_behind"] else 0


if __name__ == "__main__":
    sys.exit(main())
