"""What a confirming array costs the writer: ms of CPU per array of 20 boxes that all confirm, with a view.

In process, no Zenoh, no ROS: a :class:`~twin.live.TwinService` on the box lab (the core's test
building) holds 20 tables that one robot created in Room B; the robot then submits typed records (as
the ROS ingest workers do) at the tables' poses with a camera's noise (5 mm, 0.5 deg), each array with
a view of the room with its sensor origin (so absence and occlusion run). The figure is the writer's
CPU (``time.process_time`` around ``submit_observation`` + ``process``) per array, the median of
``--repeat`` blocks (on a shared machine the best block shows the code, the median the machine too);
``--gc freeze`` (the default) freezes the collector after the warm-up as ``twin serve`` does after
start-up; ``--profile`` prints cProfile's top functions instead.

    PYTHONPATH=$PWD python benchmarks/confirm_cost.py --arrays 300 [--profile] [--json out.json]
"""

from __future__ import annotations

import argparse
import cProfile
import gc
import json
import pstats
import random
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from tests.twin.box_lab import OX, OY
from tests.twin.live_helpers import box_turtle, observe, started
from twin.live import TwinService
from twin.records import ElementReport, Observation, ObservedBox, ObservedView

ROBOT = "robot1"
SX, SY, SZ = 0.5, 0.4, 0.75
SPOTS = [(8.5 + 0.9 * c, 0.5 + 0.75 * r) for r in range(5) for c in range(4)]
"""20 table spots in Room B (x 8..12, y 0..4), storey frame."""


def setup(others: int, *, alias: bool = False) -> TwinService:
    """The service with the robot's 20 tables, and ``others`` tables of other robots on the storey
    (south of the building, in rows: the rooms of the fleet's other robots). With ``alias``, another
    robot made the tables and the robot's first array resolved its own IRIs to them (aliases)."""
    service, _ = started()
    for i, (x, y) in enumerate(SPOTS):
        maker = "robot0" if alias else ROBOT
        reply = observe(service, maker, box_turtle(f"urn:bench:{maker}:t{i}", x, y, sx=SX, sy=SY, sz=SZ))
        assert reply.ok, reply
    for i in range(others):
        x, y = -19.0 + 0.9 * (i % 40), -19.0 + 0.75 * (i // 40)
        reply = observe(service, "robot2", box_turtle(f"urn:bench:o{i}", x, y, sx=SX, sy=SY, sz=SZ))
        assert reply.ok, reply
    return service


def array(rng: random.Random, sense_ns: int) -> Observation:
    reports = tuple(
        ElementReport(
            f"urn:bench:{ROBOT}:t{i}",
            ifc_class="IfcFurniture",
            storey="ground-floor",
            box=ObservedBox(
                OX + x + rng.gauss(0, 0.005),
                OY + y + rng.gauss(0, 0.005),
                SZ / 2,
                SX,
                SY,
                SZ,
                rng.gauss(0, 0.009),
            ),
        )
        for i, (x, y) in enumerate(SPOTS)
    )
    room = np.array([[OX + x, OY + y] for x, y in ((8.1, 0.1), (11.9, 0.1), (11.9, 3.9), (8.1, 3.9))])
    view = ObservedView(
        "ground-floor", (room,), ("IfcFurniture",), sense_ns=sense_ns, origin=(OX + 10.0, OY + 2.0, 1.2)
    )
    return Observation(reports, view)


def run(service: TwinService, n: int, seed: int = 1) -> float:
    rng = random.Random(seed)
    replies: list[object] = []
    total = 0.0
    for _ in range(n):
        obs = array(rng, time.time_ns())
        t = time.process_time()
        service.submit_observation(ROBOT, obs, replies.append)
        service.process()
        total += time.process_time() - t
    return 1e3 * total / n


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--arrays", type=int, default=300, help="arrays per block")
    p.add_argument(
        "--repeat", type=int, default=1, help="blocks: the median block is the figure (and the best)"
    )
    p.add_argument("--others", type=int, default=480, help="other robots' tables on the storey")
    p.add_argument("--alias", action="store_true", help="the robot's IRIs are aliases of another's tables")
    p.add_argument("--profile", action="store_true")
    p.add_argument("--sort", default="cumulative", help="cProfile sort key (cumulative, tottime)")
    p.add_argument(
        "--gc",
        choices=("on", "freeze", "off"),
        default="freeze",
        help="the collector after warm-up: on, frozen after start-up as `twin serve` does (default), off",
    )
    p.add_argument("--json", type=Path)
    args = p.parse_args()
    service = setup(args.others, alias=args.alias)
    run(service, 20)  # warm up (with --alias: the first array associates the robot's IRIs)
    if args.gc == "freeze":
        gc.collect()
        gc.freeze()
    elif args.gc == "off":
        gc.disable()
    if args.profile:
        prof = cProfile.Profile()
        prof.enable()
        run(service, args.arrays, seed=2)
        prof.disable()
        pstats.Stats(prof).sort_stats(args.sort).print_stats(45)
        return 0
    blocks = sorted(run(service, args.arrays, seed=2 + i) for i in range(args.repeat))
    ms, best = statistics.median(blocks), blocks[0]
    head = f"{'arrays':>7} {'boxes':>6} {'others':>7} {'aliases':>8} {'gc':>6}"
    print(f"{head} {'writer CPU ms/array':>20} {'best':>6}")
    print(
        f"{args.arrays * args.repeat:7d} {len(SPOTS):6d} {args.others:7d} {'yes' if args.alias else 'no':>8} "
        f"{args.gc:>6} {ms:20.3f} {best:6.3f}"
    )
    if args.json:
        row = {
            "arrays": args.arrays * args.repeat,
            "others": args.others,
            "alias": args.alias,
            "gc": args.gc,
            "writer_ms": ms,
            "best_ms": best,
        }
        args.json.write_text(json.dumps(row))
    return 0


if __name__ == "__main__":
    sys.exit(main())
