"""A fleet_sim run, replayed: every observation of a ``fleet_sim.py --trace`` file through an in-process
twin on the same model, one at a time, in the order they arrived, the twin's clock at each one's arrival.

``fleet_sim.py`` is threads and a daemon process: the same seed never gives the same run twice, so a
duplicate or a ghost it found once may not come back. Its trace holds every acked observation (the
payload as sent, the robot, when it was sent) and the script's events; replayed here, the run's fusion
decisions come back the same every time (the order within the daemon's batches aside: a few acks
differ), so a rule can be followed through one object's story and a change to the rules compared on
the same run (``PYTHONPATH`` picks the code).

Every second of the run it counts the **duplicates** as fleet_sim does: the twin's IfcFurniture
elements within ``MATCH_M`` of an object (the object nearest each element), two or more for one object;
an element whose footprint holds two objects (a clusterer's box over pushed desks) is theirs, no
duplicate. Where the objects stand comes from the trace: each one's first box from a robot whose boxes
are neither late nor biased, then the script's events. It prints the seconds with duplicates, the
merges, how many acks differ from the run's, and the elements and revision at the end; and the
**false-free cells** as fleet_sim counts them (``FreeWatch``), each second with some and who saw the object.

    python benchmarks/fleet_sim.py --robots 10 --duration 240 --objects 30 --moves 20 --removals 10 \\
        --tucks 4 --pushes 4 --behaviours mixed --trace fleet.jsonl
    python benchmarks/fleet_replay.py fleet.jsonl
    python benchmarks/fleet_replay.py fleet.jsonl --late 2.2 --until 120   # the late robot 2.2 s late
"""

from __future__ import annotations

import argparse
import json
import math
import random
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fleet_sim  # benchmarks/ is not a package
import live

MATCH_M = 0.5
"""fleet_sim's: a twin element within this of an object's centre is that object."""


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    p.add_argument("trace", type=Path, help="a fleet_sim.py --trace file")
    p.add_argument("--model", default="lab", help="fleet_sim's --model")
    p.add_argument("--tentative", type=int, default=1, help="fleet_sim's --tentative")
    p.add_argument("--until", type=float, default=math.inf, help="stop after this many seconds of the run")
    p.add_argument("--late", type=float, default=0.0, help="the late robots' reports arrive this long after")
    p.add_argument(
        "--jitter", type=float, default=0.0, help="each arrival later by up to this (s), at random"
    )
    p.add_argument("--seed", type=int, default=0, help="of --jitter")
    return p


def arrivals(records: list[dict[str, Any]], args: argparse.Namespace) -> list[dict[str, Any]]:
    """The traced observations in the order they arrive (``sent``; ``--late``, ``--jitter`` applied)."""
    rng = random.Random(args.seed)
    out = []
    for r in records:
        sent = r["sensed"] + args.late if args.late and r["behaviour"] == "late" else r["sent"]
        out.append({**r, "sent": sent + (rng.uniform(0.0, args.jitter) if args.jitter else 0.0)})
    return sorted(out, key=lambda r: r["sent"])


def duplicates(service: Any, objects: dict[int, tuple[float, float]]) -> dict[int, list[str]]:
    """Object -> its elements, for the objects held by two elements or more (see the module's doc)."""
    import numpy as np

    from twin.fusion.footprints import corners, points_in_polygon, pose_of

    keys = list(objects)
    centres = np.array([objects[k] for k in keys]) if keys else np.zeros((0, 2))
    per: dict[int, list[str]] = {}
    for iri, state in service.states.items():
        shape = service.live_maps.shape_of(iri)
        if state.is_static or state.removed or "IfcFurniture" not in state.ifc_types or shape is None:
            continue
        pose = pose_of(shape)
        if keys and points_in_polygon(centres, corners(pose)).sum() >= 2:
            continue  # a box over two objects: theirs (a cluster)
        near = [(math.dist((pose.cx, pose.cy), objects[k]), k) for k in keys]
        near = [(d, k) for d, k in near if d <= MATCH_M]
        if near:
            per.setdefault(min(near)[1], []).append(iri)
    return {k: v for k, v in sorted(per.items()) if len(v) > 1}


def follow(objects: dict[int, tuple[float, float]], moved: set[int], record: dict[str, Any]) -> None:
    """Where the objects stand after ``record``: an event of the script, or a robot's report (an object's
    first box, from a robot whose boxes are neither late nor biased, until an event moves it)."""
    if "event" in record:
        key = int(record["obj"])
        moved.add(key)
        if record["present"]:
            objects[key] = (float(record["x"]), float(record["y"]))
        else:
            objects.pop(key, None)
        return
    if record["behaviour"] in ("late", "bias"):
        return
    for key, _, x, y in record["boxes"]:
        if key >= 0 and key not in moved and key not in objects:
            objects[key] = (float(x), float(y))


class FreeWatch:
    """fleet_sim's **false-free cells**, replayed: the cells more than one cell inside a true object's
    footprint that the navigation map shows free, for objects a robot saw (``SIGHTINGS`` times) at least
    ``SETTLE_S`` ago since their last change (its rules: ``_counts``, a ``late`` robot's sighting on
    arrival, not before the clocks settle). An object's footprint: where it stands (``follow``) with the
    sizes and heading the script's event gives (traces since they are), else those of the latest box a
    robot whose boxes are neither late nor biased reported of it (its detector noise, 3 cm and 2
    degrees: a cell or two counted now and then)."""

    def __init__(self, t0: float) -> None:
        self.t0 = t0
        self.shape: dict[int, tuple[float, float, float, float]] = {}  # key -> sx, sy, sz, yaw
        self.truth: dict[int, tuple[float, float, float, float]] = {}  # from the script's events
        self.seen_since: dict[int, float] = {}
        self.seen_by: dict[int, set[str]] = {}
        self.sightings: dict[tuple[int, str], int] = {}  # (object, robot) -> since its change

    def event(self, record: dict[str, Any], objects: dict[int, tuple[float, float]]) -> None:
        """A move, removal, push or push apart: the objects it changed are unseen since (a push changes
        the desk it was pushed against too: the nearest other object)."""
        keys = [int(record["obj"])]
        if record["event"] in ("push", "apart"):
            x, y = record["old"]
            others = [(math.dist((x, y), p), k) for k, p in objects.items() if k != keys[0]]
            if others:
                keys.append(min(others)[1])
                if record["event"] == "push" and keys[1] in self.shape:  # a desk like it
                    self.shape[keys[0]] = self.shape[keys[1]]
        if "shape" in record:  # traced since the shapes were: the truth
            self.truth[keys[0]] = tuple(record["shape"])
        for k in keys:
            self.seen_since.pop(k, None)
            self.seen_by.pop(k, None)
            self.sightings = {s: n for s, n in self.sightings.items() if s[0] != k}

    def report(self, record: dict[str, Any]) -> None:
        """A traced observation: each object's box shape, and who saw it since its change."""
        behaviour, sensed = record["behaviour"], float(record["sensed"])
        settles = self.t0 + fleet_sim.CLOCK_SETTLE_S
        keys = {int(k) for k, *_ in record["boxes"] if k >= 0}
        for _, iri, *_ in record["boxes"]:
            if ":blob-" in iri:  # a clusterer's box over two pushed desks: both seen
                keys.update(int(k) for k in iri.rsplit(":blob-", 1)[1].split("-"))
        if behaviour not in ("late", "bias"):
            boxes = {iri: k for k, iri, *_ in record["boxes"] if k >= 0}
            for line in record["payload"].splitlines():
                if line.startswith("<") and 'twin:box "' in line and line[1 : line.index(">")] in boxes:
                    v = [float(x) for x in line.split('twin:box "', 1)[1].split('"')[0].split()]
                    self.shape[boxes[line[1 : line.index(">")]]] = (v[3], v[4], v[5], v[6])
        if not fleet_sim._counts(behaviour, sensed, settles):
            return
        when = float(record["sent"]) if behaviour == "late" else sensed
        robot = f"{record['robot']}:{behaviour}"
        for k in keys:
            n = self.sightings[k, robot] = self.sightings.get((k, robot), 0) + 1
            if n >= fleet_sim.SIGHTINGS:
                self.seen_since.setdefault(k, when)
                self.seen_by.setdefault(k, set()).add(robot)

    def count(
        self, service: Any, objects: dict[int, tuple[float, float]], now: float, skill: tuple[str, str]
    ) -> dict[int, int]:
        """Object -> its false-free cells now (the objects with any)."""
        grid = service.live_maps.skill_maps[skill].grid()
        out = {}
        for k, (x, y) in objects.items():
            since, shape = self.seen_since.get(k), self.truth.get(k, self.shape.get(k))
            if since is None or shape is None:
                continue
            if now - max(since, self.t0 + fleet_sim.CLOCK_SETTLE_S) < fleet_sim.SETTLE_S:
                continue
            sx, sy, sz, yaw = shape
            n = fleet_sim.false_free_cells(grid, fleet_sim.Obj(k, x, y, yaw, sx, sy, sz))
            if n:
                out[k] = n
        return out


def replay(args: argparse.Namespace) -> int:
    from twin.config import load_config
    from twin.graph.store import EmbeddedStore
    from twin.live import TwinService

    lines = [json.loads(line) for line in args.trace.open()]
    t0 = float(lines[0]["t0"])
    records = [r for r in lines[1:] if "payload" in r]
    if not records:
        print(f"{args.trace} holds no payloads: a fleet_sim.py --trace from before they were traced")
        return 2
    events = sorted(({**r, "sent": r["at"]} for r in lines[1:] if "event" in r), key=lambda r: r["sent"])
    stream = sorted([*arrivals(records, args), *events], key=lambda r: r["sent"])
    work = Path(tempfile.mkdtemp(prefix="fleet-replay-"))
    clock = [0]
    try:
        path = live.prepare_store(args.model, work)
        skill = (
            ("ground-floor", "lab-navigation")
            if args.model == "lab"
            else (live.busiest(path)[0], "navigation")
        )
        store = EmbeddedStore.open(path)
        config = work / "fleet.toml"
        config.write_text(f"[fusion]\ntentative_sightings = {args.tentative}\n")
        service = TwinService(store, load_config(config), clock=lambda: clock[0])
        service.start()
        objects: dict[int, tuple[float, float]] = {}
        moved: set[int] = set()
        differ, merges, seconds = 0, 0, 0
        watch = FreeWatch(t0)
        free_max, free_seconds = 0, 0
        next_sample = t0 + 1.0
        for r in stream:
            if r["sent"] - t0 > args.until:
                break
            if "event" in r:
                watch.event(r, objects)
            follow(objects, moved, r)
            if "event" in r:
                continue
            watch.report(r)
            clock[0] = int(r["sent"] * 1e9)
            replies: list[Any] = []
            service.submit_observation(r["robot"], r["payload"].encode(), replies.append)
            service.process()
            ack = replies[0].body
            differ += any(
                sorted(ack.get(k) or []) != sorted(r["ack"].get(k) or []) for k in ("upserted", "removed")
            )
            if ack.get("merged"):
                merges += 1
                print(f"{r['sent'] - t0:7.2f} {r['robot']}: merged {ack['merged']}")
            if r["sent"] >= next_sample:
                next_sample += 1.0
                found = duplicates(service, objects)
                seconds += bool(found)
                if found:
                    print(f"{r['sent'] - t0:7.2f} duplicates {found}")
                free = watch.count(service, objects, r["sent"], skill)
                if free:
                    free_max, free_seconds = max(free_max, sum(free.values())), free_seconds + 1
                    seen = {k: sorted(watch.seen_by.get(k, ())) for k in free}
                    print(f"{r['sent'] - t0:7.2f} false-free cells {free} seen by {seen}")
        elements = sum(1 for s in service.states.values() if not s.is_static and not s.removed)
        print(
            f"replayed {len(records)} observations: {seconds} seconds with duplicates, {merges} merges, "
            f"{differ} acks differ from the run's; {elements} elements, revision {service.revision}; "
            f"false-free cells max {free_max} ({free_seconds} seconds)"
        )
        store.close()
        return 1 if seconds else 0
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(replay(parser().parse_args()))
