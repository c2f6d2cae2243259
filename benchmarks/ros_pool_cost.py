"""CPU time of the ROS 2 ingest workers' queues, in this process and without Zenoh: a
:class:`~adapters.zenoh.ros_workers.WorkerPool` with one worker process and ``--robots`` robots (views
on, the structure grid of ``ros_worker_cost.py``), fed per robot and tick a TF message and an array of
``--detections`` tables, ``--rate`` arrays a second in all; a thread stands in for the writer (it
holds the interpreter ``--writer-ms`` per array, as the daemon's writer does while it fuses). Reports
the CPU per array of each thread of this process (the pool's sender and reader threads, the caller
that puts, the stand-in writer) and of the worker process.

``--views shared|distinct``: the robots placed as ``ros_ingest.py --views`` places them, each its own
TF, the view cut at that building's localization map (``ros_worker_cost.py --views``), the records
checked against the twin's limits as the daemon's workers do.

    PYTHONPATH=$PWD python benchmarks/ros_pool_cost.py --robots 10 --rate 100 --seconds 10
    PYTHONPATH=$PWD python benchmarks/ros_pool_cost.py --robots 25 --rate 250 --seconds 6 --views distinct
"""

from __future__ import annotations

import argparse
import json
import os
import queue
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ros_ingest import ROBOT, base, robot_array  # benchmarks/ is not a package


def _threads_cpu_s() -> dict[int, float]:
    out = {}
    for tid in os.listdir("/proc/self/task"):
        with open(f"/proc/self/task/{tid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        out[int(tid)] = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return out


def main() -> int:
    import psutil

    from adapters.ros.detections import DetectionSettings
    from adapters.zenoh.ros_workers import RobotSpec, Translated, WorkerPool
    from tests.adapters.ros_reports import Tf, cdr_tf
    from twin.maps.grid import GridFrame, OccupancyGrid

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--robots", type=int, default=10)
    p.add_argument("--rate", type=float, default=100.0, help="arrays a second, all robots together")
    p.add_argument("--detections", type=int, default=20)
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--writer-ms", type=float, default=0.8)
    p.add_argument("--views", choices=["shared", "distinct"], help="as ros_ingest.py --views places them")
    p.add_argument("--hold-ms", type=float, default=0.0, help="[ros] hold_steady_ms of the worker")
    a = p.parse_args()
    limits = None
    if a.views is None:
        data = np.zeros((400, 800), dtype=np.int8)
        data[::80, :] = 100
        data[:, ::130] = 100
        grid = OccupancyGrid(GridFrame(0.0, 0.0, 0.05, 800, 400), data, "g", "localization", 0.0)
    else:
        from ros_worker_cost import localization_grid

        from twin.config import load_config

        grid, limits = localization_grid(a.views, a.robots), load_config().limits
    names = [f"robot{i}" for i in range(a.robots)]
    specs = [
        RobotSpec(n, DetectionSettings(robot=n, classes={"table": "IfcFurniture"}), "localization")
        for n in names
    ]
    arrived: queue.Queue[Any] = queue.Queue()

    def deliver(outcomes: list[Any]) -> None:
        for o in outcomes:
            if isinstance(o, Translated):
                arrived.put(o)

    pool = WorkerPool(
        specs, 1, deliver=deliver, replay=lambda _: [], on_restart=lambda _: None,
        fusion_terms=True, typed=True, tf_wait_s=0.5, queue_depth=100_000, limits=limits,
        hold_steady_s=a.hold_ms / 1e3,
    )  # fmt: skip
    pool.feed(("elevations", {grid.storey: 0.0}))
    pool.feed(("grid", grid))
    for name in names:
        pool.feed(("storey", name, grid.storey), robot=name)
    handled = [0]

    def writer() -> None:
        while arrived.get() is not None:
            handled[0] += 1
            t = time.thread_time()
            while time.thread_time() - t < a.writer_ms / 1000:
                pass

    writer_thread = threading.Thread(target=writer, name="writer (stand-in)")
    writer_thread.start()

    def publish(seconds: float) -> int:
        start, tick, sent = time.monotonic(), 0, 0
        while time.monotonic() - start < seconds:
            stamp = time.time_ns()
            array = robot_array(stamp, a.detections)
            if a.views is None:  # every robot the same message (one object)
                tf = cdr_tf([Tf("map", "base_link", (*ROBOT, 0.0), stamp_ns=stamp)])
                messages = [(tf, array)] * len(names)
            else:  # each robot its own pose, its own objects (as they come from Zenoh)
                at = [(*base(r, len(names), a.views), 0.0) for r in range(len(names))]
                messages = [
                    (cdr_tf([Tf("map", "base_link", p, stamp_ns=stamp)]), bytes(bytearray(array))) for p in at
                ]
            for n, (tf, det) in zip(names, messages, strict=True):
                pool.put(n, "tf", tf, stamp)
                pool.put(n, "detections", det, stamp)
                sent += 1
            tick += 1
            time.sleep(max(0.0, start + tick * len(names) / a.rate - time.monotonic()))
        return sent

    def settle(expected: int) -> None:
        deadline = time.monotonic() + 30
        while handled[0] < expected and time.monotonic() < deadline:
            time.sleep(0.05)

    worker = [c for c in psutil.Process().children() if "spawn_main" in " ".join(c.cmdline())]
    settle(publish(2.0))
    h0, t0 = handled[0], _threads_cpu_s()
    k0 = sum(sum(c.cpu_times()[:2]) for c in worker if c.is_running())
    sent = publish(a.seconds)
    settle(h0 + sent)
    arrays = handled[0] - h0
    t1 = _threads_cpu_s()
    k1 = sum(sum(c.cpu_times()[:2]) for c in worker if c.is_running())
    thread_names = {t.native_id: t.name for t in threading.enumerate()}
    per: dict[str, float] = {}
    for tid, cpu in t1.items():
        name = thread_names.get(tid, "other")
        per[name] = per.get(name, 0.0) + cpu - t0.get(tid, 0.0)
    result = {
        "arrays": arrays,
        "sent": sent,
        "threads_ms_per_array": {
            k: round(1000 * v / max(arrays, 1), 3) for k, v in sorted(per.items()) if v > 0
        },
        "worker_ms_per_array": round(1000 * (k1 - k0) / max(arrays, 1), 3),
    }
    arrived.put(None)
    writer_thread.join()
    pool.close()
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
