"""Live-twin benchmark: the daemon as a process, a robot and a map subscriber in this process.

Measures, per model:

- startup: ``twin serve`` start to all maps published (what the daemon reports, and wall time to its
  "serving" line), and its resident memory (RSS now and peak, from ``/proc``);
- end-to-end latency: from sending an acked observation (a table moved around the busiest storey) to
  the receipt of the ``OccupancyGridUpdate`` by the subscriber (another process than the daemon),
  p50/p99 over N observations; and the ack round trip;
- recompute: the same changes applied incrementally (:meth:`twin.live.live_maps.LiveMaps.redraw`) against a
  full rebuild of the affected maps, in this process.

Usage::

    python benchmarks/live.py [--models lab janesville PATH.ifc ...] [--count N] [--json OUT.json] [--remote]

``--remote`` also runs each model with the graph on an Oxigraph server (``oxigraph serve`` on disk, on
loopback) instead of the embedded store: ``twin serve --store-url``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED_IFC = ROOT.parent / "shared" / "data" / "ifc"
MODELS = {"lab": None, "janesville": SHARED_IFC / "revit2012_janesville_restaurant.ifc"}
TWIN = "https://w3id.org/building-twin#"


def _twin(*args: str) -> list[str]:
    return [sys.executable, "-m", "adapters.cli", *args]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _proc_mb(pid: int, field: str) -> float:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


def thread_cpu(pid: int) -> dict[int, tuple[str, float]]:
    """Each thread of ``pid``: its name as the system knows it (Zenoh's runtime threads are named,
    e.g. ``rx-0``, ``acc-0``; Python's threads keep the process's name) and its CPU seconds, from
    ``schedstat`` (nanoseconds: a hundred threads that run briefly each are not lost to the ticks of
    ``stat``)."""
    out: dict[int, tuple[str, float]] = {}
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            text = Path(f"/proc/{pid}/task/{tid}/stat").read_text()
            ns = int(Path(f"/proc/{pid}/task/{tid}/schedstat").read_text().split()[0])
        except (OSError, ValueError, IndexError):  # ended meanwhile
            continue
        out[int(tid)] = (text[text.index("(") + 1 : text.rindex(")")], ns / 1e9)
    return out


def py_spy_dump(pid: int) -> str:
    """``py-spy dump`` of ``pid``'s Python threads (their names and stacks; empty without py-spy)."""
    spy = shutil.which("py-spy") or str(Path(sys.executable).parent / "py-spy")
    try:
        return subprocess.run(
            [spy, "dump", "--pid", str(pid)], check=False, capture_output=True, text=True, timeout=30
        ).stdout
    except (OSError, subprocess.SubprocessError):
        return ""


def py_spy_record(pid: int, out: Path, duration_s: float) -> subprocess.Popen[bytes]:
    """Start ``py-spy record`` of ``pid``'s threads for ``duration_s`` into ``out`` (collapsed stacks,
    one line per stack with its count, threads by id); the caller waits for it."""
    spy = shutil.which("py-spy") or str(Path(sys.executable).parent / "py-spy")
    how = ["--rate", "250", "--format", "raw", "--threads", "--nonblocking", "-o", str(out)]
    return subprocess.Popen(
        [spy, "record", "--pid", str(pid), "--duration", str(max(1, round(duration_s))), *how],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


def serve(*args: str) -> tuple[subprocess.Popen[str], str]:
    """Start ``twin serve ARGS`` and wait for its "serving" line; return the process and that line."""
    daemon = subprocess.Popen(
        _twin("serve", *args),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        cwd=ROOT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    assert daemon.stdout is not None
    line = ""
    while "serving site" not in line:
        line = daemon.stdout.readline()
        if not line:
            raise RuntimeError(f"the daemon did not start: exit code {daemon.wait()}")
    return daemon, line


def _pct(values: list[float], q: float) -> float:
    return float(np.percentile(np.array(values), q)) if values else float("nan")


def model_path(name: str) -> Path | None:
    """A named model's IFC file (None for the lab, generated per run), or ``name`` as an IFC path."""
    return MODELS[name] if name in MODELS else Path(name)


def model_label(name: str) -> str:
    return name if name in MODELS else Path(name).stem


def import_store(ifc: Path, store: Path) -> Path:
    """``twin import`` of ``ifc`` into ``store``."""
    subprocess.run(_twin("import", str(ifc), "--store", str(store)), check=True, capture_output=True)
    return store


def prepare_store(name: str, work: Path) -> Path:
    store = work / "store"
    ifc = model_path(name)
    if ifc is None:
        ifc = work / "lab.ifc"
        subprocess.run(_twin("sample", "lab", str(ifc), "--storeys", "2"), check=True, capture_output=True)
    elif not ifc.exists():
        raise FileNotFoundError(ifc)
    subprocess.run(_twin("import", str(ifc), "--store", str(store)), check=True, capture_output=True)
    return store


def busiest(store: Path) -> tuple[str, tuple[float, float, float, float], float]:
    """Busiest storey for the navigation skill: key, extent, and the x/y of free floor is not known,
    so positions are drawn over the extent (boxes may overlap walls: that is still a change)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import tasks

    from twin.config import load_config
    from twin.graph.store import EmbeddedStore
    from twin.maps.scene import load_scene

    with EmbeddedStore.open(store, read_only=True) as st:
        scene = load_scene(st)
    key = tasks.busiest_storey(scene, load_config().skill("navigation"))
    info = scene.storey(key)
    return key, info.extent, info.elevation_m


def recompute(store: Path, storey: str, positions: list[tuple[float, float]]) -> dict[str, float]:
    """Incremental apply vs full rebuild of the affected maps, in process, on a copy of the store."""
    from twin.config import load_config
    from twin.graph.store import EmbeddedStore
    from twin.live import TwinService

    copy = Path(tempfile.mkdtemp()) / "store"
    shutil.copytree(store, copy)
    inc, full = [], []
    with EmbeddedStore.open(copy) as st:
        service = TwinService(st, load_config())
        service.start()
        original = service.live_maps.redraw

        def timed(*a: Any, **k: Any) -> Any:
            t0 = time.perf_counter()
            out = original(*a, **k)
            inc.append(time.perf_counter() - t0)
            for u in out:  # the rebuild of the same affected maps, for comparison
                m = service.live_maps.skill_maps[(u.storey, u.skill)]
                t1 = time.perf_counter()
                service.live_maps.rebuild(m)
                full.append(time.perf_counter() - t1)
            return out

        service.live_maps.redraw = timed  # type: ignore[method-assign]
        for i, (x, y) in enumerate(positions[:50]):
            service.submit_observation("bench", _table(storey, x, y, i).encode())
            service.process()
    shutil.rmtree(copy.parent, ignore_errors=True)
    return {
        "incremental_p50_ms": _pct(inc, 50) * 1e3,
        "full_rebuild_per_map_p50_ms": _pct(full, 50) * 1e3,
        "speedup": _pct(full, 50) / max(_pct(inc, 50), 1e-9),
    }


def start_oxigraph(work: Path, store: Path) -> tuple[subprocess.Popen[bytes], str]:
    """An ``oxigraph serve`` on disk holding a copy of ``store`` (the embedded store's graph)."""
    import io

    import pyoxigraph as ox

    from adapters.sparql.remote_store import RemoteStore
    from twin.errors import StoreUnavailableError
    from twin.graph.store import EmbeddedStore

    binary = shutil.which("oxigraph", path=str(Path(sys.executable).parent)) or "oxigraph"
    url = f"http://127.0.0.1:{_free_port()}"
    server = subprocess.Popen(
        [binary, "serve", "--location", str(work / "oxigraph"), "--bind", url.removeprefix("http://")],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 20
    while True:
        try:
            remote = RemoteStore.open(url)
            break
        except StoreUnavailableError:
            if time.monotonic() > deadline:
                server.kill()
                raise
            time.sleep(0.05)
    buf = io.BytesIO()
    with EmbeddedStore.open(store, read_only=True) as st:
        st.dump_turtle(buf)
    with remote:
        remote.bulk_add(ox.parse(buf.getvalue(), format=ox.RdfFormat.TURTLE))
    return server, url


def _table(storey: str, x: float, y: float, i: int) -> str:
    return (
        f'<urn:bench:table> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "{storey}" ; '
        f'<{TWIN}box> "{x} {y} 0.375 1.2 0.8 0.75 {0.1 * (i % 30)}" .'
    )


def _settled_size(path: Path, quiet_s: float = 2.0, timeout_s: float = 120.0) -> int:
    """The file's size once it has not grown for ``quiet_s`` (the recorder has caught up)."""
    deadline, size, since = time.monotonic() + timeout_s, -1, time.monotonic()
    while time.monotonic() < deadline:
        now = path.stat().st_size if path.exists() else 0
        if now != size:
            size, since = now, time.monotonic()
        elif time.monotonic() - since >= quiet_s:
            break
        time.sleep(0.2)
    return max(size, 0)


def run_model(name: str, count: int, *, record: bool = False, remote: bool = False) -> dict[str, Any]:
    from adapters.zenoh.client import TwinClient

    work = Path(tempfile.mkdtemp(prefix=f"live-{model_label(name)}-"))
    t_import = time.perf_counter()
    store = prepare_store(name, work)
    import_s = time.perf_counter() - t_import
    storey, (xmin, ymin, xmax, ymax), _ = busiest(store)
    rng = np.random.default_rng(7)
    positions = [
        (float(rng.uniform(xmin + 1, xmax - 1)), float(rng.uniform(ymin + 1, ymax - 1))) for _ in range(count)
    ]
    server, url = start_oxigraph(work, store) if remote else (None, "")
    endpoint = f"tcp/127.0.0.1:{_free_port()}"
    t0 = time.perf_counter()
    rrd = work / "run.rrd"
    daemon, line = serve(
        *(["--store-url", url] if remote else ["--store", str(store)]),
        "--listen",
        endpoint,
        *(["--record", str(rrd)] if record else ["--no-record"]),
    )
    startup_wall = time.perf_counter() - t0
    maps_published_s = float(line.rsplit(" in ", 1)[1].split()[0])
    rss_start = _proc_mb(daemon.pid, "VmRSS")
    time.sleep(1.0)
    # The building and first maps are written by then: the recorder batches a file's rows for 10 s.
    rrd_start = _settled_size(rrd, quiet_s=12.0) if record else 0
    received: dict[int, float] = {}
    got = threading.Condition()
    latencies, acks = [], []
    try:
        with TwinClient.connect([endpoint], timeout_s=30) as client:
            revision_of: dict[int, int] = {}

            def on_update(sample: Any) -> None:
                meta = json.loads(sample.attachment.to_bytes())
                with got:
                    received.setdefault(int(meta["revision"]), time.perf_counter())
                    got.notify_all()

            sub = client.session.declare_subscriber(client.keys.map_updates(storey, "navigation"), on_update)
            time.sleep(0.5)
            for i, (x, y) in enumerate(positions):
                sent = time.perf_counter()
                ack = client.observe("bench", _table(storey, x, y, i))
                acks.append(time.perf_counter() - sent)
                rev = int(ack["revision"])
                revision_of[i] = rev
                changed = any(m["skill"] == "navigation" and m["storey"] == storey for m in ack["maps"])
                if changed:
                    with got:
                        got.wait_for(lambda r=rev: r in received, timeout=5)
                    if rev in received:
                        latencies.append(received[rev] - sent)
            sub.undeclare()
        rss_end = _proc_mb(daemon.pid, "VmRSS")
        rss_peak = _proc_mb(daemon.pid, "VmHWM")
    finally:
        daemon.terminate()
        daemon.wait(timeout=30)
        if server is not None:
            server.terminate()
            server.wait(timeout=30)
    rrd_end = rrd.stat().st_size if rrd.exists() else 0
    rec = recompute(store, storey, positions)
    shutil.rmtree(work, ignore_errors=True)
    per_obs = (rrd_end - rrd_start) / max(count, 1)
    return {
        "model": model_label(name)
        + (" (recording)" if record else "")
        + (" (remote store)" if remote else ""),
        "storey": storey,
        "import_s": round(import_s, 2),
        "startup_to_serving_s": round(startup_wall, 2),
        "maps_published_s": maps_published_s,
        "observations": count,
        "updates_received": len(latencies),
        "update_latency_p50_ms": round(_pct(latencies, 50) * 1e3, 2),
        "update_latency_p99_ms": round(_pct(latencies, 99) * 1e3, 2),
        "ack_p50_ms": round(_pct(acks, 50) * 1e3, 2),
        "ack_p99_ms": round(_pct(acks, 99) * 1e3, 2),
        "incremental_p50_ms": round(rec["incremental_p50_ms"], 2),
        "full_rebuild_per_map_p50_ms": round(rec["full_rebuild_per_map_p50_ms"], 2),
        "speedup": round(rec["speedup"], 1),
        "rss_start_mb": round(rss_start),
        "rss_end_mb": round(rss_end),
        "rss_peak_mb": round(rss_peak),
        "rrd_start_kb": round(rrd_start / 1024),
        "rrd_end_kb": round(rrd_end / 1024, 1),
        "rrd_bytes_per_observation": round(per_obs),
        "rrd_hour_10_robots_20hz_gb": round(per_obs * 200 * 3600 / 1e9, 2),
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--models", nargs="+", default=["lab", "janesville"], help=f"{', '.join(sorted(MODELS))} or IFC paths"
    )
    p.add_argument("--count", type=int, default=200)
    p.add_argument("--json", type=Path)
    p.add_argument("--record", action="store_true", help="also run each model with recording on (Rerun)")
    p.add_argument("--remote", action="store_true", help="also run each model on an Oxigraph server")
    args = p.parse_args()
    rows = []
    for name in args.models:
        path = model_path(name)
        if path is not None and not path.exists():
            print(f"skipping {name}: {path} not found (../shared is absent)", file=sys.stderr)
            continue
        print(f"running {name} ...", file=sys.stderr, flush=True)
        rows.append(run_model(name, args.count))
        if args.record:
            # The recorder writes the building and the first maps on its own schedule (a niced
            # process batching rows): the bytes an observation costs are the difference between a
            # run of --count observations and one of a single observation, both files complete.
            one = run_model(name, 1, record=True)
            row = run_model(name, args.count, record=True)
            per_obs = (row["rrd_end_kb"] - one["rrd_end_kb"]) * 1024 / max(args.count - 1, 1)
            row["rrd_bytes_per_observation"] = round(per_obs)
            row["rrd_hour_10_robots_20hz_gb"] = round(per_obs * 200 * 3600 / 1e9, 2)
            rows.append(row)
        if args.remote:
            rows.append(run_model(name, args.count, remote=True))
    if rows:
        keys = list(rows[0])
        print("| " + " | ".join(keys) + " |")
        print("|" + "---|" * len(keys))
        for r in rows:
            print("| " + " | ".join(str(r[k]) for k in keys) + " |")
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    "date": time.strftime("%Y-%m-%d"),
                    "machine": {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count()},
                    "rows": rows,
                },
                indent=2,
            )
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
