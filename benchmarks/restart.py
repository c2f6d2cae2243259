"""Restart benchmark: ``twin serve`` on a store imported earlier, until a robot has its maps again.

For each model the store is imported once; then the daemon is started on it again and again, as its
own process, with a map subscriber in another process (listening; the daemon connects to it):

- ``clean``: after a clean stop (SIGTERM), ``--repeat`` times;
- ``kill -9``: after ``kill -9`` of a daemon that had just acked ``--observations`` observations (a
  table moved around the busiest storey), so the store opens through its recovery path, ``--repeat``
  times. The revision at serving must include every acked observation.

Both kinds run twice: without the derived-state snapshot (``--no-snapshot``: the scene decoded and
every map rendered from the store) and with it (a first, unmeasured start writes it; after a clean
stop it is current, after ``kill -9`` it is older than the store and the changes since are replayed).
``from`` says where the daemon took its maps from (``store`` or ``snapshot rN``).

Measured from the process start (``Popen``): the daemon's "serving" line (store opened, scene loaded,
every map built and published; ``maps_published_s`` is the part the daemon reports), the first full
map received by the subscriber, and the last of the N maps. Nothing is re-imported: the IFC file is
not even given to the daemon.

Usage::

    python benchmarks/restart.py [--models lab janesville PATH.ifc ...] [--repeat 3] [--json OUT.json]
    python benchmarks/restart.py --subscriber ENDPOINT       # (internal) the subscriber process
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
import live  # the live benchmark's machinery: models, store preparation, the twin command, ports

MAP_KEYS = "twin/*/map/**"


def subscriber(endpoint: str) -> int:
    """Listen on ``endpoint``; print ``{"ready": true}``, then ``{"key", "t"}`` for each map's first
    full version (``t`` = ``time.time()``), until stdin closes."""
    import zenoh
    import zenoh.ext

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    seen: set[str] = set()
    lock = threading.Lock()

    def on_map(sample: zenoh.Sample) -> None:
        t = time.time()
        key = str(sample.key_expr)
        with lock:
            if key in seen:
                return
            seen.add(key)
        print(json.dumps({"key": key, "t": t}), flush=True)

    with zenoh.open(conf) as session:
        sub = zenoh.ext.declare_advanced_subscriber(
            session, MAP_KEYS, on_map, history=zenoh.ext.HistoryConfig(detect_late_publishers=True)
        )
        print(json.dumps({"ready": True}), flush=True)
        sys.stdin.read()
        sub.undeclare()
    return 0


class Subscriber:
    """The subscriber process; :meth:`wait` collects the arrival time of each map's first version."""

    def __init__(self) -> None:
        self.endpoint = f"tcp/127.0.0.1:{live._free_port()}"
        self.proc = subprocess.Popen(
            [sys.executable, __file__, "--subscriber", self.endpoint],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            cwd=live.ROOT,
        )
        assert self.proc.stdout is not None
        self.arrivals: dict[str, float] = {}
        if "ready" not in self.proc.stdout.readline():
            raise RuntimeError("the subscriber did not start")
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()
        self._cond = threading.Condition()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            msg = json.loads(line)
            with self._cond:
                self.arrivals[msg["key"]] = float(msg["t"])
                self._cond.notify_all()

    def wait(self, count: int, timeout_s: float = 120.0) -> dict[str, float]:
        with self._cond:
            self._cond.wait_for(lambda: len(self.arrivals) >= count, timeout=timeout_s)
            return dict(self.arrivals)

    def close(self) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.close()
        self.proc.wait(timeout=30)


def start_daemon(
    store: Path, connect: str | None, *flags: str
) -> tuple[subprocess.Popen[str], float, str, str]:
    """Start ``twin serve``; return it, its start time (``time.time()``), its serving line, endpoint."""
    endpoint = f"tcp/127.0.0.1:{live._free_port()}"
    extra = ["--connect", connect] if connect else []
    t0 = time.time()
    daemon, line = live.serve("--store", str(store), "--listen", endpoint, "--no-record", *extra, *flags)
    return daemon, t0, line, endpoint


def _source(serving: str) -> str:
    """Where the maps came from, as the serving line says: ``store`` or ``snapshot rN``."""
    if "(from the snapshot of revision " not in serving:
        return "store"
    return "snapshot r" + serving.rsplit("revision ", 1)[1].split(")", maxsplit=1)[0]


def measured_start(store: Path, *flags: str) -> tuple[subprocess.Popen[str], dict[str, Any], str]:
    """Start the daemon with a fresh subscriber; the times to serving, first and last map."""
    sub = Subscriber()
    try:
        daemon, t0, line, endpoint = start_daemon(store, sub.endpoint, *flags)
        t_serving = time.time()
        n_maps = int(line.rsplit(":", 1)[1].split()[0])
        arrivals = sub.wait(n_maps)
    finally:
        sub.close()
    times = sorted(arrivals.values())
    row = {
        "from": "snapshot r" + line.rsplit("revision ", 1)[1].split(")")[0]
        if "(from the snapshot" in line
        else "store",
        "to_serving_s": round(t_serving - t0, 2),
        "maps_published_s": float(line.rsplit(" in ", 1)[1].split()[0]),
        "to_first_map_s": round(times[0] - t0, 2) if times else float("nan"),
        "to_all_maps_s": round(times[-1] - t0, 2) if len(times) >= n_maps else float("nan"),
        "maps": n_maps,
        "revision": int(line.split(" at revision ")[1].split()[0]),
    }
    return daemon, row, endpoint


def observe(endpoint: str, store: Path, count: int) -> int:
    """Send ``count`` acked observations (a table moved over the busiest storey); the last revision."""
    import numpy as np

    from adapters.zenoh.client import TwinClient

    storey, (xmin, ymin, xmax, ymax), _ = live.busiest(store)
    rng = np.random.default_rng(int(time.time()))
    revision = -1
    with TwinClient.connect([endpoint], timeout_s=30) as client:
        for i in range(count):
            x, y = float(rng.uniform(xmin + 1, xmax - 1)), float(rng.uniform(ymin + 1, ymax - 1))
            revision = int(client.observe("bench", live._table(storey, x, y, i))["revision"])
    return revision


def run_model(name: str, repeat: int, observations: int) -> list[dict[str, Any]]:
    work = Path(tempfile.mkdtemp(prefix=f"restart-{live.model_label(name)}-"))
    rows: list[dict[str, Any]] = []
    try:
        t = time.perf_counter()
        store = live.prepare_store(name, work)
        import_s = round(time.perf_counter() - t, 2)
        print(f"  imported in {import_s} s", file=sys.stderr, flush=True)
        for snapshot in (False, True):
            flags = () if snapshot else ("--no-snapshot",)
            label = {"model": live.model_label(name), "snapshot": "yes" if snapshot else "no"}
            for i in range(repeat + snapshot):  # with a snapshot, the first start writes it: not measured
                daemon, row, _ = measured_start(store, *flags)
                daemon.send_signal(signal.SIGTERM)
                daemon.wait(timeout=60)
                if snapshot and i == 0:
                    continue
                rows.append({**label, "after": "clean stop", "run": i + 1 - snapshot, **row})
                print(f"  {rows[-1]}", file=sys.stderr, flush=True)
            acked = -1
            for i in range(repeat + 1):  # the first start follows the clean stops: not a recovery
                daemon, row, endpoint = measured_start(store, *flags)
                if i > 0:
                    row["acked_revision_before_kill"] = acked
                    rows.append({**label, "after": "kill -9", "run": i, **row})
                    print(f"  {rows[-1]}", file=sys.stderr, flush=True)
                    if row["revision"] < acked:
                        print(f"  LOST: revision {row['revision']} < acked {acked}", file=sys.stderr)
                acked = observe(endpoint, store, observations)
                time.sleep(
                    1.0
                )  # let a background snapshot (after a replay) finish: kill -9 may still cut one
                daemon.kill()
                daemon.wait(timeout=60)
        for r in rows:
            r["import_s"] = import_s
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return rows


def summary(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Median and max per (model, after) of each time."""
    out = []
    for key in dict.fromkeys((r["model"], r["snapshot"], r["after"]) for r in rows):
        group = [r for r in rows if (r["model"], r["snapshot"], r["after"]) == key]
        entry: dict[str, Any] = {
            "model": key[0],
            "snapshot": key[1],
            "after": key[2],
            "runs": len(group),
            "maps": group[0]["maps"],
        }
        for col in ("to_serving_s", "maps_published_s", "to_first_map_s", "to_all_maps_s"):
            values = [float(r[col]) for r in group]
            entry[col] = f"{statistics.median(values):.2f} (max {max(values):.2f})"
        entry["import_s"] = group[0]["import_s"]
        out.append(entry)
    return out


def _table(rows: list[dict[str, Any]]) -> None:
    keys = list(rows[0])
    print("| " + " | ".join(keys) + " |")
    print("|" + "---|" * len(keys))
    for r in rows:
        print("| " + " | ".join(str(r.get(k, "")) for k in keys) + " |")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--models", nargs="+", default=["lab", "janesville"])
    p.add_argument("--repeat", type=int, default=3, help="measured restarts of each kind (default 3)")
    p.add_argument("--observations", type=int, default=20, help="acked before each kill -9 (default 20)")
    p.add_argument("--json", type=Path)
    p.add_argument("--subscriber", metavar="ENDPOINT", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.subscriber:
        return subscriber(args.subscriber)
    rows: list[dict[str, Any]] = []
    for name in args.models:
        path = live.model_path(name)
        if path is not None and not path.exists():
            print(f"skipping {name}: {path} not found (../shared is absent)", file=sys.stderr)
            continue
        print(f"running {name} ...", file=sys.stderr, flush=True)
        rows += run_model(name, args.repeat, args.observations)
    if not rows:
        return 0
    _table(summary(rows))
    print()
    _table(rows)
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    "date": time.strftime("%Y-%m-%d"),
                    "machine": {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count()},
                    "load_average": os.getloadavg(),
                    "rows": rows,
                },
                indent=2,
            )
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
