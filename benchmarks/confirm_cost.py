"""What a confirming array costs the writer: ms of CPU per array of 20 boxes that all confirm, with a view.

In process, no Zenoh, no ROS: a :class:`~twin.live.TwinService` on the box lab (the core's test
building) holds 20 tables that one robot created in Room B; the robot then submits typed records
(checked as the ROS ingest workers check them) at the tables' poses with a camera's noise (5 mm,
0.5 deg), each array with a view of the room with its sensor origin (so absence and occlusion run).
The figure is the writer's
CPU (``time.process_time`` around ``submit_observation`` + ``process``) per array, the median of
``--repeat`` blocks (on a shared machine the best block shows the code, the median the machine too);
``--gc freeze`` (the default) freezes the collector after the warm-up as ``twin serve`` does after
start-up; ``--profile`` prints cProfile's top functions instead. With ``--robots N`` (as in
``ros_ingest.py``, where every robot sees the same tables) N robots report the same 20 tables in turns,
each with its own IRIs (the others' resolve through aliases), its own noise and a sense time 1 ms
after the previous robot's (1 in 20 arrays 50 ms earlier: stale where the others saw the tables since),
one batch per round of the N arrays: the aliases, the robot pairs' bias notes and the stale notes of a
fleet. With ``--moves K`` the last table moves 1.2 m (beyond ``certain_move_m``, into the room's free
corner) every K rounds and back, as in ``ros_ingest.py``: the robots' arrays that follow the move in
its batch. With ``--single`` each array is a batch of its own, as the daemon's writer mostly takes
them at 25 robots x 10 Hz (arrays come one by one, a few ms apart).

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

try:  # the ingest workers check the records they make (not in a tree before that)
    from twin.live.validate import checked
except ImportError:  # pragma: no cover
    checked = None  # type: ignore[assignment]

ROBOT = "robot1"
SX, SY, SZ = 0.5, 0.4, 0.75
STALE = 0.05
"""With several robots, the share of arrays seen 50 ms before the latest (stale where another saw them)."""
SPOTS = [(8.5 + 0.9 * c, 0.5 + 0.75 * r) for r in range(5) for c in range(4)]
"""20 table spots in Room B (x 8..12, y 0..4), storey frame."""
MOVED = (11.75, 2.4)
"""Where the last table goes (``--moves``): 1.2 m from its spot, clear of the others."""


def offset(robot: str, distinct: bool) -> tuple[float, float]:
    """Where ``robot``'s tables and view lie, from Room B's (``--distinct``: each robot's own place, in
    rows north of the building; else every robot reports Room B's tables)."""
    if not distinct or robot == ROBOT:
        return 0.0, 0.0
    k = int(robot.removeprefix("robot"))
    return -27.0 + 5.0 * (k % 8), 6.0 + 5.0 * ((k - 2) // 8)


def setup(others: int, *, alias: bool = False, robots: int = 1, distinct: bool = False) -> TwinService:
    """The service with the robot's 20 tables, and ``others`` tables of other robots on the storey
    (south of the building, in rows: the rooms of the fleet's other robots). With ``alias``, another
    robot made the tables and the robot's first array resolved its own IRIs to them (aliases). With
    ``distinct``, each of the ``robots`` made 20 tables of its own, in a place of its own."""
    service, _ = started()
    for i, (x, y) in enumerate(SPOTS):
        maker = "robot0" if alias else ROBOT
        reply = observe(service, maker, box_turtle(f"urn:bench:{maker}:t{i}", x, y, sx=SX, sy=SY, sz=SZ))
        assert reply.ok, reply
    for robot in names(robots)[1:] if distinct else ():
        dx, dy = offset(robot, distinct)
        for i, (x, y) in enumerate(SPOTS):
            turtle = box_turtle(f"urn:bench:{robot}:t{i}", x + dx, y + dy, sx=SX, sy=SY, sz=SZ)
            reply = observe(service, robot, turtle)
            assert reply.ok, reply
    for i in range(others):
        x, y = -19.0 + 0.9 * (i % 40), -19.0 + 0.75 * (i // 40)
        reply = observe(service, "mapper", box_turtle(f"urn:bench:o{i}", x, y, sx=SX, sy=SY, sz=SZ))
        assert reply.ok, reply
    return service


def names(robots: int) -> list[str]:
    """The robots that report the tables: the maker (:data:`ROBOT`) first."""
    return [ROBOT, *(f"robot{k}" for k in range(2, robots + 1))]


def array(
    rng: random.Random, sense_ns: int, robot: str = ROBOT, *, moved: bool = False, distinct: bool = False
) -> Observation:
    spots = [*SPOTS[:-1], MOVED] if moved and (robot == ROBOT or not distinct) else SPOTS
    dx, dy = offset(robot, distinct)
    reports = tuple(
        ElementReport(
            f"urn:bench:{robot}:t{i}",
            ifc_class="IfcFurniture",
            storey="ground-floor",
            box=ObservedBox(
                OX + x + dx + rng.gauss(0, 0.005),
                OY + y + dy + rng.gauss(0, 0.005),
                SZ / 2,
                SX,
                SY,
                SZ,
                rng.gauss(0, 0.009),
            ),
        )
        for i, (x, y) in enumerate(spots)
    )
    corners = ((8.1, 0.1), (11.9, 0.1), (11.9, 3.9), (8.1, 3.9))
    room = np.array([[OX + x + dx, OY + y + dy] for x, y in corners])
    origin = (OX + 10.0 + dx, OY + 2.0 + dy, 1.2)
    view = ObservedView("ground-floor", (room,), ("IfcFurniture",), sense_ns=sense_ns, origin=origin)
    return Observation(reports, view)


def run(
    service: TwinService,
    n: int,
    seed: int = 1,
    *,
    robots: int = 1,
    moves: int = 0,
    single: bool = False,
    distinct: bool = False,
    flush: bytearray | None = None,
) -> float:
    """The writer's CPU ms per array over ``n`` rounds of one array per robot (one batch per round, or
    with ``single`` one per array); the last table moved every ``moves`` rounds (0: never)."""
    rng = random.Random(seed)
    replies: list[object] = []
    total = 0.0
    who = names(robots)
    for step in range(n):
        now = time.time_ns()
        moved = moves > 0 and (step // moves) % 2 == 1
        arrays = [(robot, array(rng, now + k * 10**6 - (50 * 10**6 if rng.random() < STALE else 0), robot,
                                moved=moved, distinct=distinct))
                  for k, robot in enumerate(who)]  # fmt: skip
        if checked is not None:  # as a worker hands them over
            arrays = [(robot, checked(obs, limits=service.config.limits)) for robot, obs in arrays]  # type: ignore[misc]
        for k, (robot, obs) in enumerate(arrays):
            if flush is not None and (single or k == 0):  # (not timed: the caches as the writer finds them)
                flush[::64] = bytes(len(flush[::64]))
            t = time.process_time()
            service.submit_observation(robot, obs, replies.append)
            if single:
                service.process()
            total += time.process_time() - t
        t = time.process_time()
        service.process()
        total += time.process_time() - t
    return 1e3 * total / (n * robots)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--arrays", type=int, default=300, help="arrays per block")
    p.add_argument(
        "--repeat", type=int, default=1, help="blocks: the median block is the figure (and the best)"
    )
    p.add_argument("--others", type=int, default=480, help="other robots' tables on the storey")
    p.add_argument("--alias", action="store_true", help="the robot's IRIs are aliases of another's tables")
    p.add_argument("--robots", type=int, default=1, help="robots reporting the same tables in turns")
    p.add_argument(
        "--distinct",
        action="store_true",
        help="each robot reports 20 tables of its own, in a place of its own (no aliases, no bias pairs)",
    )
    p.add_argument("--moves", type=int, default=0, help="the last table moves every this many rounds")
    p.add_argument(
        "--single", action="store_true", help="one batch per array (as the daemon's writer mostly takes them)"
    )
    p.add_argument(
        "--flush",
        type=int,
        default=0,
        help="MB written over between arrays, not timed (32: the caches as the daemon's writer finds them)",
    )
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
    service = setup(args.others, alias=args.alias, robots=args.robots, distinct=args.distinct)
    # warm up (the first arrays associate the robots' IRIs)
    options = {"robots": args.robots, "moves": args.moves, "single": args.single, "distinct": args.distinct}
    flush = bytearray(args.flush << 20) if args.flush else None
    run(service, 20, **options)
    if args.gc == "freeze":
        gc.collect()
        gc.freeze()
    elif args.gc == "off":
        gc.disable()
    if args.profile:
        prof = cProfile.Profile()
        prof.enable()
        run(service, args.arrays, seed=2, flush=flush, **options)
        prof.disable()
        pstats.Stats(prof).sort_stats(args.sort).print_stats(45)
        return 0
    blocks = sorted(
        run(service, args.arrays, seed=2 + k, flush=flush, **options)
        for k in range(args.repeat)
    )
    ms, best = statistics.median(blocks), blocks[0]
    head = f"{'arrays':>7} {'robots':>6} {'boxes':>6} {'others':>7} {'aliases':>8} {'moves':>6} {'single':>6}"
    head += f" {'gc':>6}"
    print(f"{head} {'writer CPU ms/array':>20} {'best':>6}")
    print(
        f"{args.arrays * args.repeat * args.robots:7d} {args.robots:6d} {len(SPOTS):6d} {args.others:7d} "
        f"{'yes' if args.alias else 'no':>8} {args.moves:6d} {'yes' if args.single else 'no':>6} "
        f"{args.gc:>6} {ms:20.3f} {best:6.3f}"
    )
    if args.json:
        row = {
            "arrays": args.arrays * args.repeat * args.robots,
            "robots": args.robots,
            "others": args.others,
            "alias": args.alias,
            "moves": args.moves,
            "single": args.single,
            "gc": args.gc,
            "writer_ms": ms,
            "best_ms": best,
        }
        args.json.write_text(json.dumps(row))
    return 0


if __name__ == "__main__":
    sys.exit(main())
