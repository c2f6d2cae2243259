"""CPU time of one ROS 2 ingest worker's translation, in this process: a :class:`RobotTranslator` as a
worker runs it (typed reports, views on, the view cut at a structure grid), fed what
``ros_ingest.py``'s robots send: per array a TF message (``map -> base_link`` at its stamp) and a
Detection3DArray of ``--detections`` tables with tracker ids, the robot standing still. Reports the
CPU time (``time.process_time``) per TF + array; ``--profile`` also prints a cProfile ranking.
``--moving``: the robot moves 1 cm per array (no march reused); ``--noise M``: each table's pose
jitters by ``M`` metres (and M rad of yaw), seeded, as a real detector's. ``--check OUT`` writes the
outcomes as plain values (to compare two code trees' outputs: the same bytes). ``--stages`` prints the
CPU (thread time, with the timers' own cost) of each stage per TF + array; it finds the stages of
either tree (before and after the boxes and footprints became one pass). ``--pickle`` prints what
handing the outcomes over costs: bytes per array, µs to dump and to load (best of 5), and to load an
array's reports alone (what the daemon's pool thread does per array).

``--views shared|distinct`` plays a worker of ``ros_ingest.py`` instead: ``--robots`` robots (default
25) in one translator, placed as ``ros_ingest.py --views`` places them (shared: all at one pose in the
lab's corridor; distinct: each in a room of its own of the generated rooms building), each with its
own TF and array per tick (0.1 s), handled round-robin as a worker takes its batches; the records
checked against the twin's limits and the collector set as the workers do; the view cut at the
daemon's own localization map of that building (the lab's, 14.3 x 6.4 m; the rooms building's,
33.2 x 23.2 m; made by importing the building and starting a twin on it: a few seconds).

    PYTHONPATH=$PWD python benchmarks/ros_worker_cost.py --detections 20 --repeat 10 [--profile]
    PYTHONPATH=$PWD python benchmarks/ros_worker_cost.py --views distinct --repeat 3 --stages
"""

from __future__ import annotations

import argparse
import cProfile
import dataclasses
import gc
import json
import pstats
import struct
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ros_ingest import MOVER, ROBOT, base, robot_array, tables  # benchmarks/ is not a package

NOW_NS = 1_700_000_000_000_000_000


Message = tuple[str, bytes, bytes]
"""A robot's name, its TF message and its array of the same stamp."""


def setup(
    per_robot: int, arrays: int = 50, *, moving: bool = False, noise: float = 0.0
) -> tuple[Any, list[Message]]:
    """A translator with one robot on a 40 x 20 m structure grid at 0.05 m (walls every 4 m across and
    6.5 m along: the robot in a corridor), and ``arrays`` TF + array pairs 0.1 s apart (``moving``: the
    robot 1 cm further along x at each, its tables as far before it: no view's march is reused)."""
    from adapters.ros.detections import DetectionSettings
    from adapters.zenoh.ros_workers import RobotSpec, RobotTranslator
    from tests.adapters.ros_reports import Det, Tf, cdr_detections, cdr_tf, yaw_quaternion
    from twin.maps.grid import GridFrame, OccupancyGrid

    data = np.zeros((400, 800), dtype=np.int8)
    data[::80, :] = 100
    data[:, ::130] = 100
    grid = OccupancyGrid(GridFrame(0.0, 0.0, 0.05, 800, 400), data, "g", "localization", 0.0)
    settings = DetectionSettings(robot="robot0", classes={"table": "IfcFurniture"})
    spec = RobotSpec("robot0", settings, "localization")
    t = RobotTranslator([spec], fusion_terms=True, typed=True, clock=lambda: NOW_NS)
    t.set_storey("robot0", "g")
    t.set_elevations({"g": 0.0})
    t.set_grid(grid)
    spots = tables(per_robot)
    rng = np.random.default_rng(42)
    msgs = []
    for k in range(arrays):
        stamp = NOW_NS - 6_000_000_000 + k * 100_000_000
        dx = 0.01 * k if moving else 0.0
        tf = cdr_tf([Tf("map", "base_link", (ROBOT[0] + dx, ROBOT[1], 0.0), stamp_ns=stamp)])
        jitter = rng.normal(0.0, noise, (len(spots), 3)) if noise else np.zeros((len(spots), 3))
        dets = [
            Det(
                (("table", 0.9),),
                (x - ROBOT[0] - dx + ex, y - ROBOT[1] + ey, 0.375),
                (0.2, 0.2, 0.75),
                orientation=yaw_quaternion(ez),
                id=f"t{i}",
            )
            for i, ((x, y), (ex, ey, ez)) in enumerate(zip(spots, jitter.tolist(), strict=True))
        ]
        msgs.append(("robot0", tf, cdr_detections(stamp, "base_link", dets)))
    return t, msgs


def localization_grid(views: str, robots: int) -> Any:
    """The daemon's localization map of ``ros_ingest.py``'s building (``views``: the lab's or the
    rooms building of ``robots`` rooms), made as ``twin serve`` makes it (imported, then the twin
    started on it)."""
    import tempfile

    from ros_ingest import views_store

    from twin.config import load_config
    from twin.graph.store import EmbeddedStore
    from twin.live import TwinService

    with tempfile.TemporaryDirectory() as tmp:
        store = views_store(views, robots, Path(tmp))
        with EmbeddedStore.open(store) as st:
            service = TwinService(st, load_config())
            service.start()
            return service.live_maps.skill_maps[("ground-floor", "localization")].grid()


def setup_fleet(views: str, robots: int, per_robot: int, ticks: int = 40) -> tuple[Any, list[Message]]:
    """A translator of ``robots`` robots as one worker of ``ros_ingest.py --views VIEWS`` holds them
    (the twin's limits: records checked), and ``ticks`` rounds of each robot's TF + array, 0.1 s apart,
    robot by robot (robot 0's last table 1.0 m aside every other 2 s, as its publisher moves it)."""
    from adapters.ros.detections import DetectionSettings
    from adapters.zenoh.ros_workers import WORKER_GC_THRESHOLD, RobotSpec, RobotTranslator
    from tests.adapters.ros_reports import Tf, cdr_tf
    from twin.config import load_config

    grid = localization_grid(views, robots)
    names = [f"robot{r}" for r in range(robots)]
    specs = [
        RobotSpec(
            n,
            DetectionSettings(robot=n, classes={"table": "IfcFurniture"}, max_detections=per_robot),
            "localization",
        )
        for n in names
    ]
    t = RobotTranslator(
        specs, fusion_terms=True, typed=True, clock=lambda: NOW_NS, limits=load_config().limits
    )
    for n in names:
        t.set_storey(n, grid.storey)
    t.set_elevations({grid.storey: 0.0})
    t.set_grid(grid)
    gc.freeze()  # as a worker: what its start made is not collected again, young passes rarer
    gc.set_threshold(*WORKER_GC_THRESHOLD)
    msgs = []
    for k in range(ticks):
        stamp = NOW_NS - 6_000_000_000 + k * 100_000_000
        shift = MOVER[2] * ((k // 20) % 2)
        for r, name in enumerate(names):
            tf = cdr_tf([Tf("map", "base_link", (*base(r, robots, views), 0.0), stamp_ns=stamp)])
            msgs.append((name, tf, robot_array(stamp, per_robot, shift if r == 0 else 0.0)))
    return t, msgs


def _values(v: Any) -> Any:
    """``v`` as plain values (floats as their 8 bytes, records as tuples), whose repr is the same text
    for equal outcomes whichever objects they share (a cached IRI is one object in every array)."""
    if isinstance(v, float):
        return struct.pack("<d", v)
    if isinstance(v, np.ndarray):
        return (v.dtype.str, v.shape, v.tobytes())
    if isinstance(v, tuple | list):
        return tuple(_values(x) for x in v)
    if dataclasses.is_dataclass(v):
        return (type(v).__name__, *(_values(getattr(v, f.name)) for f in dataclasses.fields(v)))
    if isinstance(v, dict):
        return tuple(sorted((k, _values(x)) for k, x in v.items()))
    return v


STAGES = (
    ("adapters.zenoh.ros_workers", "decode_tf_message", "TF decode"),
    ("adapters.zenoh.ros_workers", "RobotTranslator._must_wait", "TF wait check"),
    ("adapters.ros.detections", "decode_detections", "decode (CDR)"),
    ("adapters.ros.detections", "_boxes_in_map", "boxes into the map + footprints"),
    ("adapters.ros.detections", "_shadows", "boxes into the map + footprints"),
    ("adapters.ros.detections", "_placements", "boxes into the map + footprints"),
    ("adapters.ros.detections", "camera_view", "view"),
    ("adapters.ros.detections", "observation_records", "records"),
    ("adapters.zenoh.ros_workers", "translate_detections", "translate"),
)


def stages(t: Any, msgs: list[Message], repeat: int) -> dict[str, int]:
    """µs of thread time per TF + array in each of :data:`STAGES` (those the tree has), timed by
    wrapping them; "rest of translate" is the translation less its stages (the loop, IRIs, session)."""
    import collections
    import importlib

    spent: collections.Counter[str] = collections.Counter()

    def timed(f: Any, label: str) -> Any:
        def g(*args: Any, **kwargs: Any) -> Any:
            t0 = time.thread_time_ns()
            try:
                return f(*args, **kwargs)
            finally:
                spent[label] += time.thread_time_ns() - t0

        return g

    for module, name, label in STAGES:
        owner: Any = importlib.import_module(module)
        *path, attr = name.split(".")
        for part in path:
            owner = getattr(owner, part)
        if hasattr(owner, attr):
            setattr(owner, attr, timed(getattr(owner, attr), label))
    t0 = time.process_time()
    run(t, msgs, repeat)
    n = repeat * len(msgs)
    out = {"total": round(1e6 * (time.process_time() - t0) / n)}
    out |= {k: round(v / 1000 / n) for k, v in spent.items()}
    parts = ("decode (CDR)", "boxes into the map + footprints", "view", "records")
    out["rest of translate"] = out.pop("translate") - sum(out.get(k, 0) for k in parts)
    return out


def run(t: Any, msgs: list[Message], repeat: int) -> list[Any]:
    out = []
    for _ in range(repeat):
        for robot, tf, det in msgs:
            t.handle(robot, "tf", tf, 0)
            out.append(t.handle(robot, "detections", det, 0))
    return out


def _observation(outcome: Any) -> Any:
    """An outcome's observation (checked against the limits: inside its ``Checked``)."""
    doc = outcome.translation.document
    return getattr(doc, "observation", doc)


def pickles(outcomes: list[Any], rounds: int = 200) -> dict[str, float]:
    """What handing ``outcomes`` from a worker to the daemon costs per array (best of 5 timings)."""
    import pickle

    def best(f: Any) -> float:
        times = []
        for _ in range(5):
            t0 = time.perf_counter()
            for _ in range(rounds):
                f()
            times.append((time.perf_counter() - t0) / rounds)
        return 1e6 * min(times) / len(outcomes)

    data = pickle.dumps(outcomes, protocol=pickle.HIGHEST_PROTOCOL)
    reports = [_observation(o).reports for o in outcomes]
    data_reports = pickle.dumps(reports, protocol=pickle.HIGHEST_PROTOCOL)
    return {
        "bytes": round(len(data) / len(outcomes)),
        "dump_us": round(best(lambda: pickle.dumps(outcomes, protocol=pickle.HIGHEST_PROTOCOL)), 1),
        "load_us": round(best(lambda: pickle.loads(data)), 1),
        "load_reports_us": round(best(lambda: pickle.loads(data_reports)), 1),
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--detections", type=int, default=20)
    p.add_argument("--repeat", type=int, default=10)
    p.add_argument("--moving", action="store_true", help="the robot moves 1 cm per array")
    p.add_argument("--noise", type=float, default=0.0, help="the tables' pose noise, m (and rad)")
    p.add_argument("--profile", action="store_true")
    p.add_argument("--check", type=Path)
    p.add_argument("--stages", action="store_true", help="also the CPU of each stage (µs per array)")
    p.add_argument("--pickle", action="store_true", help="also the outcomes' pickles (bytes, µs per array)")
    p.add_argument(
        "--views",
        choices=["shared", "distinct"],
        help="play a worker of ros_ingest.py --views VIEWS (--robots robots, the daemon's localization map)",
    )
    p.add_argument("--robots", type=int, default=25, help="with --views: the robots (default 25)")
    a = p.parse_args()
    if a.views is not None:
        t, msgs = setup_fleet(a.views, a.robots, a.detections)
    else:
        t, msgs = setup(a.detections, moving=a.moving, noise=a.noise)
    first = run(t, msgs, 1)
    if a.check is not None:
        a.check.write_bytes(repr(_values([[o.translation.document for o in x] for x in first])).encode())
    views = sum(1 for x in first if x and getattr(x[0], "translation", None) and _observation(x[0]).view)
    t0 = time.process_time()
    run(t, msgs, a.repeat)
    cpu_ms = 1000 * (time.process_time() - t0) / (a.repeat * len(msgs))
    print(
        json.dumps(
            {
                "detections": a.detections,
                "views": a.views,
                "robots": a.robots if a.views else 1,
                "moving": a.moving,
                "noise": a.noise,
                "arrays_with_view": f"{views}/{len(first)}",
                "cpu_ms": round(cpu_ms, 3),
            }
        )
    )
    if a.stages:
        print(json.dumps(stages(t, msgs, a.repeat)))
    if a.pickle:
        print(json.dumps(pickles([o for x in first[:50] for o in x])))  # as many arrays as one robot's
    if a.profile:
        prof = cProfile.Profile()
        prof.enable()
        run(t, msgs, a.repeat)
        prof.disable()
        pstats.Stats(prof).sort_stats("cumtime").print_stats(30)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
