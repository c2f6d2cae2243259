"""A fleet against ground truth: simulated robots report what they see to a real daemon, and every second
the twin is compared with the true world.

The daemon (``twin serve`` on the lab, or ``--model janesville``) runs as a process; each robot is a
thread with its own Zenoh session. A robot drives random straight paths through the free floor of one
storey, and at ``--rate`` Hz sends an acked observation: the objects whose centre lies in its view
(range ``--range``, all around, cut by the building's structure: rays cast over the navigation map of
the empty building), each as a box with noise (``--sigma-pos``, ``--sigma-yaw``), missed with
``--p-miss``, with a tracker IRI of its own that it renumbers when it loses an object for 3 s; now and
then a false detection; and its view (``a twin:View``: the polygon, ``twin:detects "IfcFurniture"``,
the sense time). Objects move, vanish and appear at scripted times (``--moves``, ``--removals``,
``--appears``, spread over the middle of the run; ``--tucks``: a chair tucked under a table, pulled out
8 s later; ``--pushes``: a desk pushed against another's end, which the robots' clusterer then reports
as one box over both, pushed 0.8 m apart 10 s later). The truth is also applied, exactly, to a twin of its
own in this process (fusion off), whose maps are the maps of the true world.

Every second: the twin's IfcFurniture elements (SPARQL) against the true objects (within 0.5 m):
duplicates (elements beyond an object's nearest within 0.5 m), ghosts (elements where no object is),
and the **viewed** ones: those the views since they became one held as the daemon's absence rule asks
(the footprint 0.1 m inside its edges wholly in a view, ``misses_to_remove`` views over ``miss_span_s``)
10 s ago or more (fusion should have removed them; a view from before the object left, or one that held
only part of the footprint, is no miss), objects missing, the navigation map's cells that differ from the
true world's, and the **false-free cells**: the cells more than one cell inside a true object's
footprint that the navigation map shows free, for objects a robot saw at least ``SETTLE_S`` ago since
their last change, twice (``SIGHTINGS``: the daemon's M of N; one glimpse creates or moves nothing)
(a ``late`` robot's sighting counts once its report arrives, and only if it was
sensed after that change; a ``clock_behind`` or ``late`` robot's sightings sensed before the daemon's
clock estimate settles do not count: the daemon refuses them as stale), and not before the daemon's
clocks settle (``CLOCK_SETTLE_S``) (free floor where a
real object stands: a robot would plan through it; cells of objects only the ``bias`` robot saw, while
the daemon does not know its bias, are counted apart: nothing can place them right). An element
whose footprint holds two objects' centres (a clusterer's box over pushed desks) is a **cluster**:
theirs, neither a duplicate nor a ghost. At the
end: removals (precision and recall within 10 s of the first view without the object; a move or
removal whose old place an object fills again before that is not counted), the time
from a move's first sighting to the ack that shows it, revisions per true change, acked sightings
per second, and the daemon's CPU per acked observation. ``--saturate S`` adds S seconds in which the
robots send as fast as acks come back (the acked sightings per second at saturation).
``--trace FILE`` writes every acked observation (the robot, the true sense time, sent, acked, each box
with its object, the ack, the payload as sent) and every view of a moved or removed object's old place,
with the script's events, as JSON lines: one object's story, to diagnose a false-free cell or a late
removal; ``fleet_replay.py`` replays it through an in-process twin, the same way every time.

    python benchmarks/fleet_sim.py --robots 10 --objects 30 --duration 600 --moves 20 --removals 10 \\
        --json fleet.json --plot fleet.png
    python benchmarks/fleet_sim.py --model janesville --robots 5 --objects 30 --duration 600
    python benchmarks/fleet_sim.py --robots 6 --behaviours mixed --duration 120   # see BEHAVIOURS

Exit code 1 when a duplicate or a viewed ghost remains at the end (the suite runs a short version:
``tests/integration/test_fleet.py``).
"""

from __future__ import annotations

import argparse
import json
import math
import random
import shutil
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import live  # benchmarks/ is not a package

TWIN = live.TWIN
PREFIX = f"@prefix twin: <{TWIN}> .\n@prefix xsd: <http://www.w3.org/2001/XMLSchema#> .\n"
MATCH_M = 0.5
"""A twin element within this of an object's centre is that object."""
GHOST_VIEWED_S = 10.0
RAYS = 72


def _iso(ns: int) -> str:
    s, n = divmod(ns, 1_000_000_000)
    return time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(s)) + f".{n:09d}Z"


@dataclass
class Obj:
    """A true object: an upright box on the storey's floor."""

    key: int
    x: float
    y: float
    yaw: float
    sx: float
    sy: float
    sz: float
    present: bool = True
    changed_at: float = 0.0
    seen_at: float = -1.0
    seen_since_change: float | None = None
    """When a robot first saw it after its last change (its false-free cells count from then)."""
    seen_by: dict[str, float] = field(default_factory=dict)
    """The robots (``index:behaviour``) that saw it since its last change -> when each first did
    (``SIGHTINGS`` times: the second sighting)."""
    sightings: dict[str, int] = field(default_factory=dict)
    """How many times each robot saw it since its last change."""

    def sighted(self, robot: str, when: float) -> None:
        """``robot`` (``index:behaviour``) saw it at ``when``: counts from its ``SIGHTINGS``-th sighting."""
        n = self.sightings[robot] = self.sightings.get(robot, 0) + 1
        if n >= SIGHTINGS:
            self.seen_by.setdefault(robot, when)
            if self.seen_since_change is None:
                self.seen_since_change = when

    def unseen(self, now: float) -> None:
        """It changed at ``now``: nobody has seen it since."""
        self.changed_at, self.seen_since_change, self.seen_by, self.sightings = now, None, {}, {}

    def corners(self) -> np.ndarray:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        local = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * (self.sx / 2, self.sy / 2)
        return np.asarray(local @ np.array([[c, s], [-s, c]]) + (self.x, self.y))


@dataclass
class Event:
    kind: str  # move | remove | appear
    obj: int
    at: float
    place: tuple[float, float]  # the old place (move, remove) or the new one (appear)
    corners: np.ndarray
    first_view: float | None = None
    detected: float | None = None
    first_sighting: float | None = None
    refilled: float | None = None
    """When an object was first seen standing at the old place again (moved or put back there) while its
    element was still there: nothing left to remove (not counted in the removals' recall)."""
    shown: float | None = None


@dataclass
class World:
    """The free floor, the structure that hides things, the objects, and what happened."""

    free: np.ndarray  # bool grid: a robot or an object may stand here
    blocked: np.ndarray  # bool grid: the structure (rays stop)
    origin: tuple[float, float]
    res: float
    elevation: float
    objects: dict[int, Obj] = field(default_factory=dict)
    events: list[Event] = field(default_factory=list)
    views: list[tuple[float, np.ndarray]] = field(default_factory=list)  # (time, polygon), recent
    together: dict[int, int] = field(default_factory=dict)
    """Desks pushed together: the pushed one -> the one it stands against (one box for a clusterer)."""
    ghosts: dict[str, GhostWatch] = field(default_factory=dict)
    """The twin's elements where no object is (the sampler's): the views since that held each."""
    lock: threading.Lock = field(default_factory=threading.Lock)

    def cell(self, x: float, y: float) -> tuple[int, int]:
        return int((y - self.origin[1]) / self.res), int((x - self.origin[0]) / self.res)

    def is_free(self, x: float, y: float) -> bool:
        r, c = self.cell(x, y)
        return 0 <= r < self.free.shape[0] and 0 <= c < self.free.shape[1] and bool(self.free[r, c])

    def line_free(self, a: tuple[float, float], b: tuple[float, float]) -> bool:
        n = max(2, int(math.dist(a, b) / (self.res / 2)))
        return all(
            self.is_free(a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t) for t in np.linspace(0, 1, n)
        )

    def random_free(self, rng: random.Random) -> tuple[float, float]:
        rows, cols = np.nonzero(self.free)
        i = rng.randrange(len(rows))
        return (
            self.origin[0] + (cols[i] + 0.5) * self.res,
            self.origin[1] + (rows[i] + 0.5) * self.res,
        )

    def view(self, x: float, y: float, reach: float) -> np.ndarray:
        """The floor a sensor at (x, y) sees: rays over the structure, to ``reach``."""
        angles = np.linspace(0, 2 * math.pi, RAYS, endpoint=False)
        steps = np.arange(0, reach, self.res / 2)[:, None]
        px = x + steps * np.cos(angles)[None, :]
        py = y + steps * np.sin(angles)[None, :]
        rows = ((py - self.origin[1]) / self.res).astype(int)
        cols = ((px - self.origin[0]) / self.res).astype(int)
        inside = (rows >= 0) & (rows < self.blocked.shape[0]) & (cols >= 0) & (cols < self.blocked.shape[1])
        hit = (
            ~inside
            | self.blocked[
                np.clip(rows, 0, self.blocked.shape[0] - 1), np.clip(cols, 0, self.blocked.shape[1] - 1)
            ]
        )
        first = np.where(hit.any(axis=0), hit.argmax(axis=0), len(steps))
        dist = np.maximum(first - 1, 0) * (self.res / 2)
        return np.stack([x + dist * np.cos(angles), y + dist * np.sin(angles)], axis=1)

    def place(
        self, rng: random.Random, near: tuple[float, float] | None = None
    ) -> tuple[float, float, float] | None:
        for _ in range(500):
            if near is None:
                x, y = self.random_free(rng)
            else:
                a, d = rng.uniform(0, 2 * math.pi), rng.uniform(1.0, 4.0)
                x, y = near[0] + d * math.cos(a), near[1] + d * math.sin(a)
            yaw = rng.uniform(0, math.pi)
            probe = Obj(-1, x, y, yaw, 0.9, 0.6, 1.0)
            if not all(self.is_free(*c) for c in probe.corners()) or not self.is_free(x, y):
                continue
            if any(o.present and math.dist((o.x, o.y), (x, y)) < 1.0 for o in self.objects.values()):
                continue
            return x, y, yaw
        return None


def _inside(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    from twin.fusion.footprints import points_in_polygon

    return points_in_polygon(points, polygon)


# --- the robots ------------------------------------------------------------------------------------------


@dataclass
class RobotStats:
    sent: int = 0
    acked: int = 0
    sightings: int = 0
    errors: int = 0
    saturated_sightings: int = 0
    saturated_s: float = 0.0
    false_detections: int = 0


BEHAVIOURS = ("normal", "restart", "clock_behind", "clock_ahead", "late", "bias")
"""What can be wrong with a robot (``--behaviours``, assigned round-robin): ``restart``: its detector
restarts every 30 s and numbers its tracks from 1 again (its IRIs carry the tracker session, as the ROS
adapter's do); ``clock_behind`` / ``clock_ahead``: its clock is 1.5 s behind / ahead; ``late``: its
reports arrive 2 s late (sent 2 s after they were sensed); ``bias``: its detector places every object
20 cm off (+x)."""
RESTART_EVERY_S = 30.0
CLOCK_OFFSET_S = 1.5
LATE_S = 2.0
BIAS_M = 0.2
SETTLE_S = 3.0
"""An object's false-free cells count from this long after a robot first saw it since its last change
(the sightings a short move needs, the acks, and the maps' coalescing)."""
SIGHTINGS = 2
"""A robot has seen an object since its change once it has sighted it this many times: the daemon's
``stream_sightings`` and ``move_sightings`` (M of N: one glimpse of a desk moved out of its element's
reach, a robot passing a doorway, creates nothing, as a false detection does not)."""
CLOCK_SETTLE_S = 5.0
"""The daemon's ``[fusion] clock_settle_s``: before a robot's reports span it, its sense times are compared
uncorrected (a robot 1.5 s behind has its sightings refused as stale); false-free cells count from
``SETTLE_S`` after it."""


def robot(  # noqa: PLR0917 (a thread's target)
    index: int,
    endpoint: str,
    prefix: str,
    world: World,
    storey: str,
    args: argparse.Namespace,
    t_end: float,
    sat_end: float,
    stats: RobotStats,
    stop: threading.Event,
    trace: Trace | None = None,
) -> None:
    from adapters.zenoh.client import TwinClient
    from twin.errors import TwinError

    rng = random.Random(1000 + index)
    world_t0 = time.time()
    name = f"robot{index}"
    behaviour = args.behaviours[index % len(args.behaviours)]
    x, y = world.random_free(rng)
    goal = (x, y)
    epochs: dict[int, int] = {}
    last_seen: dict[int, float] = {}
    false_count = 0
    tracks: dict[int, int] = {}  # object -> tracker id (restart behaviour)
    next_track, session, restart_at = 1, 0, world_t0 + RESTART_EVERY_S
    clock_offset_ns = {"clock_behind": -1, "clock_ahead": 1}.get(behaviour, 0) * int(CLOCK_OFFSET_S * 1e9)
    # late behaviour: (due, payload, seen, sensed, the IRIs' objects)
    outbox: list[tuple[float, str, list[int], float, dict[str, int]]] = []
    settles = world_t0 + CLOCK_SETTLE_S  # before, the daemon refuses its sightings as stale (behind, late)
    with TwinClient.connect([endpoint], prefix=prefix, timeout_s=30.0) as twin:
        period = 1.0 / args.rate
        due = time.time()
        while not stop.is_set():
            now = time.time()
            if now >= sat_end:
                break
            saturating = now >= t_end
            if not saturating:
                time.sleep(max(0.0, due - now))
                due += period
            # drive
            step = args.speed * period
            if math.dist((x, y), goal) < step:
                for _ in range(50):
                    cand = world.random_free(rng)
                    if math.dist(cand, (x, y)) > 2.0 and world.line_free((x, y), cand):
                        goal = cand
                        break
            d = math.dist((x, y), goal)
            if d > 1e-9:
                x, y = x + (goal[0] - x) * min(1.0, step / d), y + (goal[1] - y) * min(1.0, step / d)
            polygon = world.view(x, y, args.range)
            sense = time.time_ns() + clock_offset_ns
            if behaviour == "restart" and now >= restart_at:
                tracks.clear()
                next_track, session, restart_at = 1, session + 1, now + RESTART_EVERY_S
            keys: dict[str, int] = {}  # IRI -> object (the trace; VIEWED + object: its old place viewed)
            with world.lock:
                objs = [o for o in world.objects.values() if o.present]
                pushed = dict(world.together)
                world.views.append((time.time(), polygon))
                for ev in world.events:
                    if ev.kind not in ("move", "remove") or ev.detected is not None:
                        continue
                    if _inside(ev.corners, polygon).all():
                        if ev.first_view is None:
                            ev.first_view = time.time()
                        keys[f"{VIEWED}{ev.obj}"] = ev.obj
            lines = []
            seen_now = []
            sensed = now
            if objs:
                centres = np.array([(o.x, o.y) for o in objs])
                visible = _inside(centres, polygon) & (
                    np.hypot(centres[:, 0] - x, centres[:, 1] - y) <= args.range
                )
                by_key = {o.key: o for o in objs}
                blobbed: set[tuple[int, int]] = set()
                for o, v in zip(objs, visible, strict=True):
                    if not v or rng.random() < args.p_miss:
                        continue
                    if o.key in pushed or o.key in pushed.values():  # a clusterer's one box over both
                        pair = next((b, a) for b, a in pushed.items() if o.key in (a, b))
                        if pair[0] in by_key and pair[1] in by_key:
                            seen_now.append(o.key)
                            o.seen_at = now
                            if behaviour != "late" and _counts(behaviour, now, settles):
                                o.sighted(f"{index}:{behaviour}", now)  # late: on arrival
                            if pair not in blobbed:  # the blob once per observation
                                blobbed.add(pair)
                                blob = cluster(by_key[pair[1]], by_key[pair[0]])
                                lines.append(
                                    box_line(
                                        f"urn:sim:{name}:blob-{pair[1]}-{pair[0]}",
                                        storey,
                                        blob,
                                        rng,
                                        args,
                                        behaviour,
                                    )
                                )
                            continue
                    if now - last_seen.get(o.key, -1e9) > 3.0:
                        epochs[o.key] = epochs.get(o.key, -1) + 1
                        tracks.pop(o.key, None)
                    last_seen[o.key] = now
                    o.seen_at = now
                    if behaviour != "late" and _counts(behaviour, now, settles):
                        o.sighted(f"{index}:{behaviour}", now)  # late: on arrival
                    if behaviour == "restart":
                        if o.key not in tracks:
                            tracks[o.key], next_track = next_track, next_track + 1
                        iri = f"urn:sim:{name}:s{session}:trk-{tracks[o.key]}"
                    else:
                        iri = f"urn:sim:{name}:trk-{o.key}-{epochs[o.key]}"
                    lines.append(box_line(iri, storey, o, rng, args, behaviour))
                    keys[iri] = o.key
                    seen_now.append(o.key)
            if rng.random() < args.p_false:
                fx, fy = polygon[rng.randrange(len(polygon))]
                fx, fy = x + (fx - x) * 0.5, y + (fy - y) * 0.5
                ghost = Obj(-1, fx, fy, 0.0, 0.5, 0.5, 0.6)
                if (
                    all(world.is_free(*c) for c in ghost.corners())
                    and _inside(ghost.corners(), polygon).all()
                ):
                    false_count += 1
                    stats.false_detections += 1
                    lines.append(
                        f'<urn:sim:{name}:false-{false_count}> twin:ifcClass "IfcFurniture" ; '
                        f'twin:storey "{storey}" ; twin:box "{fx:.3f} {fy:.3f} 0.3 0.5 0.5 0.6 0" .'
                    )
            points = " ".join(f"{px:.3f} {py:.3f}" for px, py in polygon)
            lines.append(
                f'[] a twin:View ; twin:storey "{storey}" ; twin:polygon "{points}" ; '
                f'twin:detects "IfcFurniture" ; twin:senseTime "{_iso(sense)}"^^xsd:dateTime .'
            )
            payload = PREFIX + "\n".join(lines)
            if behaviour == "late":  # sensed now, arrives LATE_S later
                outbox.append((now + LATE_S, payload, seen_now, now, keys))
                if outbox[0][0] > time.time():
                    continue
                _, payload, seen_now, sensed, keys = outbox.pop(0)
                with world.lock:
                    for k in seen_now:
                        o = world.objects[k]
                        if sensed < o.changed_at or not _counts(behaviour, sensed, settles):
                            continue  # it saw the object before its change (or before its clock settled)
                        o.sighted(f"{index}:{behaviour}", time.time())
            stats.sent += 1
            sent = time.time()
            try:
                ack = twin.observe(name, payload)
            except TwinError as err:
                stats.errors += 1
                print(f"{name}: {err}", file=sys.stderr)
                continue
            stats.acked += 1
            if trace is not None:
                trace.write(name, behaviour, sensed, sent, time.time(), payload, keys, ack)
            stats.sightings += len(seen_now)
            if saturating:
                stats.saturated_sightings += len(seen_now)
            acked = time.time()
            changed = not ack.get("unchanged")
            if changed and args.verbose:
                brief = {k: ack.get(k) for k in ("revision", "upserted", "removed", "refined", "merged")}
                brief["seen"] = seen_now
                decided = {}
                for k in seen_now:  # the rule that decided each upserted element (explain)
                    o = world.objects[k]
                    for e in twin.explain(storey, args.skill, o.x, o.y)["occupied_by"]:
                        if e["iri"] in (ack.get("upserted") or []):
                            decided[e["iri"]] = e.get("fusion", {}).get("decided")
                brief["decided"] = decided
                print(f"{name} {sent - world_t0:.1f} {json.dumps(brief)}", flush=True)
            with world.lock:
                for ev in world.events:
                    if ev.kind != "move" or ev.obj not in seen_now or ev.shown is not None:
                        continue
                    if sensed < ev.at:  # a late robot's report of the object before it moved
                        continue
                    if ev.first_sighting is None:
                        ev.first_sighting = sent
                    if changed:
                        ev.shown = acked


VIEWED = "#viewed:"
"""The trace's mark of a view that held a moved or removed object's old place (not yet found gone)."""


@dataclass
class Trace:
    """Every acked observation (``--trace FILE``, JSON lines): the robot, when it was sensed (true time),
    sent and acked, each box with its object's key, the ack (less its maps) and the payload as sent, so
    that one object's every report and what fusion answered can be read back, and the run replayed
    (``fleet_replay.py``)."""

    path: Path
    lock: threading.Lock = field(default_factory=threading.Lock)

    def write(  # noqa: PLR0917
        self,
        robot: str,
        behaviour: str,
        sensed: float,
        sent: float,
        acked: float,
        payload: str,
        keys: dict[str, int],
        ack: dict[str, Any],
    ) -> None:
        boxes = []
        viewed = [k for iri, k in keys.items() if iri.startswith(VIEWED)]
        for line in payload.splitlines():
            if line.startswith("<") and "twin:box" in line:
                iri = line[1 : line.index(">")]
                x, y = line.split('twin:box "', 1)[1].split()[:2]
                boxes.append([keys.get(iri, -1), iri, float(x), float(y)])
        record = {
            "robot": robot,
            "behaviour": behaviour,
            "sensed": round(sensed, 3),
            "sent": round(sent, 3),
            "acked": round(acked, 3),
            "boxes": boxes,
            "viewed": viewed,
            "ack": {k: v for k, v in ack.items() if k != "maps"},
            "payload": payload,
        }
        self.note(record)

    def note(self, record: dict[str, Any]) -> None:
        with self.lock, self.path.open("a") as f:
            f.write(json.dumps(record) + "\n")


def _counts(behaviour: str, sensed: float, settles: float) -> bool:
    """Whether a robot's sighting sensed at ``sensed`` counts as seen (``seen_by``): a robot whose reports
    look 1.5-2 s old (``clock_behind``, ``late``) has them refused as stale until the daemon's estimate
    of its clock settles (``settles``: ``CLOCK_SETTLE_S`` after it starts)."""
    return behaviour not in ("clock_behind", "late") or sensed >= settles


def box_line(  # noqa: PLR0917
    iri: str, storey: str, o: Obj, rng: random.Random, args: argparse.Namespace, behaviour: str
) -> str:
    """A detector's box for ``o``: noise, a flipped heading now and then, the ``bias`` behaviour's offset."""
    bx = o.x + rng.gauss(0, args.sigma_pos) + (BIAS_M if behaviour == "bias" else 0.0)
    by = o.y + rng.gauss(0, args.sigma_pos)
    byaw = o.yaw + rng.gauss(0, math.radians(args.sigma_yaw)) + (math.pi if rng.random() < 0.3 else 0)
    sx, sy, sz = (max(0.05, v + rng.gauss(0, 0.01)) for v in (o.sx, o.sy, o.sz))
    return (
        f'<{iri}> twin:ifcClass "IfcFurniture" ; twin:storey "{storey}" ; '
        f'twin:box "{bx:.4f} {by:.4f} {sz / 2:.4f} {sx:.4f} {sy:.4f} {sz:.4f} {byaw:.4f}" .'
    )


def cluster(a: Obj, b: Obj) -> Obj:
    """The one box a lidar clusterer makes of desk ``b`` pushed against ``a``'s end (same yaw)."""
    return Obj(-1, (a.x + b.x) / 2, (a.y + b.y) / 2, a.yaw, a.sx + b.sx, max(a.sy, b.sy), max(a.sz, b.sz))


# --- the sampler -----------------------------------------------------------------------------------------


def twin_elements(client: Any, storey: str) -> dict[str, Any]:
    from twin.fusion.footprints import pose_of
    from twin.graph.meshcodec import decode_mesh, decode_placement

    rows = client.sparql(
        f"""SELECT ?e ?pl ?ply WHERE {{ ?st twin:storeyKey "{storey}" ; bot:containsElement ?e .
            ?e twin:ifcType "IfcFurniture" ; omg:hasGeometry ?g . ?g twin:placement ?pl ;
            fog:asPly_v1.0-binaryLE ?ply . FILTER NOT EXISTS {{ ?e twin:removed true }} }}"""
    )["results"]["bindings"]
    out = {}
    for r in rows:
        out[r["e"]["value"]] = pose_of((decode_mesh(r["ply"]["value"]), decode_placement(r["pl"]["value"])))
    return out


@dataclass
class GhostWatch:
    """An element where no object is, at one pose: since when the sampler found it so, and the times of
    the views since then that held its footprint as absence asks (``views_holding``)."""

    since: float
    pose: tuple[float, float, float, float, float]  # cx, cy, sx, sy, yaw: a new pose starts afresh
    checked: float  # views up to this time were looked at
    held: list[float] = field(default_factory=list)


def views_holding(pose: Any, views: list[tuple[float, np.ndarray]]) -> list[float]:
    """The times of ``views`` (time, polygon) that should have seen an element at ``pose`` (a
    ``twin.fusion.footprints.Pose``) as the daemon's absence rule asks: its footprint, ``VIEW_INSET_M``
    inside its edges, wholly in the polygon by area (the simulated views carry no origin: no sight lines)."""
    from twin.fusion.absence import VIEW_INSET_M
    from twin.fusion.footprints import corners
    from twin.fusion.visibility import inside_by_area

    inset = corners(pose, inset=VIEW_INSET_M)[None]
    return [t for t, polygon in views if bool(inside_by_area(inset, [polygon])[0])]


def removable_at(held: list[float], misses: int, span_s: float) -> float | None:
    """When views at ``held`` (times, ascending), each a miss, first give absence what it needs to remove
    an element (``misses`` of them spread over ``span_s``), or None: not yet."""
    held = sorted(held)
    for i, t in enumerate(held):
        if i + 1 >= misses and t - held[0] >= span_s:
            return t
    return None


def _rules_misses() -> tuple[int, float]:
    """The daemon's ``[fusion] misses_to_remove`` and ``miss_span_s`` (the defaults: ``fleet.toml`` keeps
    them)."""
    from twin.config.fusion import FusionTable

    table = FusionTable()
    return int(table.misses_to_remove), float(table.miss_span_s)


def _watch(
    world: World, iri: str, pose: Any, views: list[tuple[float, np.ndarray]], now: float
) -> GhostWatch:
    """The ghost ``iri``'s record, brought up to ``views``: started afresh when it is new or its pose
    changed (absence counts misses of the pose it holds), the views since then that held it added."""
    key = (round(pose.cx, 2), round(pose.cy, 2), round(pose.sx, 2), round(pose.sy, 2), round(pose.yaw, 2))
    watch = world.ghosts.get(iri)
    if watch is None or watch.pose != key:
        watch = world.ghosts[iri] = GhostWatch(since=now, pose=key, checked=now)
        return watch
    fresh = [(t, p) for t, p in views if watch.checked < t <= now]
    watch.held.extend(views_holding(pose, fresh))
    watch.checked = now
    return watch


def viewed_ghost(watch: GhostWatch, now: float, misses: int, span_s: float) -> bool:
    """Whether a ghost has had, since it is one, the views absence needs, ``GHOST_VIEWED_S`` ago or more:
    fusion should have removed it (a ghost no view has held whole, as often as the rules ask, is not yet
    decidable: counted in ``ghosts`` only)."""
    at = removable_at(watch.held, misses, span_s)
    return at is not None and now - at >= GHOST_VIEWED_S


def sample(  # noqa: PLR0917
    client: Any,
    world: World,
    storey: str,
    oracle: Any,
    skill: str,
    t0: float,
    before: dict[str, tuple[float, float]],
    verbose: bool = False,
) -> dict[str, Any]:
    from twin.fusion.footprints import corners

    poses = twin_elements(client, storey)
    elements = {iri: (p.cx, p.cy) for iri, p in poses.items()}
    now = time.time()
    with world.lock:
        present = [o for o in world.objects.values() if o.present]
        world.views = [(t, p) for t, p in world.views if now - t < 60.0]
        views = list(world.views)
    per_obj: dict[int, list[str]] = {}  # object -> the elements nearest it (within MATCH_M)
    ghosts, viewed_ghosts, clusters = [], 0, 0
    rules = _rules_misses()
    covered: set[int] = set()
    centres = np.array([(o.x, o.y) for o in present]) if present else np.zeros((0, 2))
    for iri, (ex, ey) in elements.items():
        within = _inside(centres, corners(poses[iri])) if len(centres) else np.zeros(0, bool)
        if within.sum() >= 2:  # one box over desks pushed together (a clusterer's): theirs
            clusters += 1
            covered.update(o.key for o, w in zip(present, within, strict=True) if w)
            continue
        near = [o for o in present if math.dist((o.x, o.y), (ex, ey)) <= MATCH_M]
        if near:
            best = min(near, key=lambda o: math.dist((o.x, o.y), (ex, ey)))
            per_obj.setdefault(best.key, []).append(iri)
        else:
            ghosts.append(iri)
            if viewed_ghost(_watch(world, iri, poses[iri], views, now), now, *rules):
                viewed_ghosts += 1
    duplicate_iris = {}  # object -> the elements beyond its nearest: each as a ghost would be
    viewed_duplicates = 0
    for key, iris in per_obj.items():
        if len(iris) < 2:
            continue
        o = world.objects[key]
        extra = sorted(iris, key=lambda i: math.dist((o.x, o.y), elements[i]))[1:]
        duplicate_iris[key] = extra
        for iri in extra:
            if viewed_ghost(_watch(world, iri, poses[iri], views, now), now, *rules):
                viewed_duplicates += 1
    for iri in set(world.ghosts) - set(ghosts) - {i for e in duplicate_iris.values() for i in e}:
        del world.ghosts[iri]  # removed, or an object of its own stands there now
    duplicates = sum(len(iris) - 1 for iris in per_obj.values())
    missing = sum(
        1
        for o in present
        if o.key not in per_obj
        and o.key not in covered
        and o.seen_at > o.changed_at + 1.0
        and now - o.changed_at > GHOST_VIEWED_S
    )
    false_removals = 0  # elements gone although their object stands there, still, and no element has it
    for iri, place in before.items():  # (a cluster's box over pushed desks has both)
        if iri in elements:
            continue
        for o in present:
            if (
                math.dist((o.x, o.y), place) <= MATCH_M
                and now - o.changed_at > 3.0
                and o.key not in per_obj
                and o.key not in covered
            ):
                false_removals += 1
                break
    before.clear()
    before.update(elements)
    with world.lock:
        for ev in world.events:
            pending = ev.kind in ("move", "remove") and ev.detected is None and ev.at <= now
            if pending and not any(math.dist(ev.place, e) <= MATCH_M for e in elements.values()):
                ev.detected = now
            elif pending and ev.refilled is None:
                back = (o for o in present if o.changed_at > ev.at)
                if any(math.dist(ev.place, (o.x, o.y)) <= MATCH_M for o in back):
                    ev.refilled = now
    grid, _, _ = client.get_map(storey, skill)
    truth = oracle.live_maps.skill_maps[(storey, skill)].data
    cells = int((grid.data != truth).sum()) if grid.data.shape == truth.shape else -1
    with world.lock:
        settled = [
            o
            for o in present
            if o.seen_since_change is not None
            and now - max(o.seen_since_change, t0 + CLOCK_SETTLE_S) >= SETTLE_S
        ]
    status = client.status()
    known = set(status.get("fusion", {}).get("detector_biases", {}))
    free_by_object = {o.key: n for o in settled if (n := false_free_cells(grid, o))}
    unobservable = {k for k in free_by_object if _unobservable(world.objects[k], known, now)}
    why = {}
    if verbose:  # what the twin says of the cells (the deciding rule, a dispute)
        for k in free_by_object:
            o = world.objects[k]
            answer = client.explain(storey, skill, o.x, o.y)
            why[k] = [
                {"iri": e["iri"], **{key: e.get("fusion", {}).get(key) for key in ("decided", "disputed")}}
                for e in [*answer["occupied_by"], *answer["near"][:2]]
            ]
    false_free = sum(n for k, n in free_by_object.items() if k not in unobservable)
    where_free = {
        k: [
            n,
            round(world.objects[k].x, 2),
            round(world.objects[k].y, 2),
            min(
                (
                    [round(ex - world.objects[k].x, 2), round(ey - world.objects[k].y, 2)]
                    for ex, ey in elements.values()
                ),
                key=lambda d: math.hypot(*d),
                default=None,
            ),
            sorted(world.objects[k].seen_by),
            why.get(k),
        ]
        for k, n in free_by_object.items()
    }
    return {
        "t": round(now - t0, 1),
        "wall": round(now, 3),
        "elements": len(elements),
        "objects": len(present),
        "duplicates": duplicates,
        "viewed_duplicates": viewed_duplicates,
        "duplicate_iris": {str(k): v for k, v in sorted(duplicate_iris.items())},
        "clusters": clusters,
        "ghosts": len(ghosts),
        "viewed_ghosts": viewed_ghosts,
        "missing": missing,
        "cells_differ": cells,
        "false_free_cells": false_free,
        "false_free_unobservable": sum(free_by_object[k] for k in unobservable),
        "false_free_objects": where_free,
        "false_removals": false_removals,
        "revision": int(status["revision"]),
        "ghost_iris": sorted(ghosts),
    }


def _unobservable(o: Obj, known_biases: set[str], now: float) -> bool:
    """Whether only ``bias`` robots whose bias the daemon does not know yet saw ``o`` since its last
    change (robots that first saw it less than ``SETTLE_S`` ago not counted: the sightings a short move
    needs, the acks and the maps' coalescing): a detector's offset is not observable from its own
    sightings, so nothing can place it right (such cells are counted apart, ``false_free_unobservable``)."""
    robots = [r.split(":", 1) for r, first in o.seen_by.items() if now - first >= SETTLE_S]
    return bool(robots) and all(b == "bias" and f"robot{i}" not in known_biases for i, b in robots)


def false_free_cells(grid: Any, o: Obj) -> int:
    """The cells more than one cell inside ``o``'s true footprint that the map shows free."""
    from twin.fusion.footprints import box_pose, corners
    from twin.maps.grid import FREE

    f = grid.frame
    inner = corners(box_pose(o.x, o.y, 0.0, o.sx, o.sy, o.sz, yaw=o.yaw), inset=f.resolution_m)
    lo, hi = inner.min(axis=0), inner.max(axis=0)
    c0, c1 = int((lo[0] - f.origin_x) / f.resolution_m), int((hi[0] - f.origin_x) / f.resolution_m) + 1
    r0, r1 = int((lo[1] - f.origin_y) / f.resolution_m), int((hi[1] - f.origin_y) / f.resolution_m) + 1
    c0, r0 = max(c0, 0), max(r0, 0)
    c1, r1 = min(c1, f.width), min(r1, f.height)
    if c1 <= c0 or r1 <= r0:
        return 0
    cols, rows = np.meshgrid(np.arange(c0, c1), np.arange(r0, r1))
    centres = np.stack(
        [
            f.origin_x + (cols.ravel() + 0.5) * f.resolution_m,
            f.origin_y + (rows.ravel() + 0.5) * f.resolution_m,
        ],
        axis=1,
    )
    inside = _inside(centres, inner)
    return int((grid.data[rows.ravel()[inside], cols.ravel()[inside]] == FREE).sum())


# --- the run ---------------------------------------------------------------------------------------------


PULL_AFTER_S = 8.0
"""A chair tucked under a table is pulled out this long after."""
CHAIR = (0.45, 0.45, 0.9)


def tuck_chair(  # noqa: PLR0917
    world: World, rng: random.Random, now: float, oracle: Any, storey: str, elevation: float
) -> tuple[int, int] | None:
    """A new chair tucked under a present table-sized object (a 0.45 m chair inside its footprint,
    taller than it): returns (chair, table), or None when no object is large enough."""
    def spot(t: Obj) -> tuple[float, float]:
        shift = t.sx / 2 - CHAIR[0] / 2 - 0.05
        return t.x + shift * math.cos(t.yaw), t.y + shift * math.sin(t.yaw)

    tables = [o for o in world.objects.values() if o.present and o.sx >= 0.75 and o.sy >= 0.5]
    tables = [  # never a second chair where one is still tucked (one never pulled out: no room beside)
        t
        for t in tables
        if not any(
            o.present and o.key != t.key and math.dist((o.x, o.y), spot(t)) < CHAIR[0]
            for o in world.objects.values()
        )
    ]
    if not tables:
        return None
    t = rng.choice(tables)
    shift = t.sx / 2 - CHAIR[0] / 2 - 0.05
    c, s = math.cos(t.yaw), math.sin(t.yaw)
    k = max(world.objects) + 1
    chair = Obj(k, t.x + shift * c, t.y + shift * s, t.yaw, *CHAIR, changed_at=now)
    world.objects[k] = chair
    world.events.append(Event("tuck", k, now, (chair.x, chair.y), chair.corners()))
    apply_truth(oracle, truth_box(chair, storey, elevation))
    return k, t.key


def pull_out(  # noqa: PLR0917
    world: World, chair_key: int, table_key: int, now: float, oracle: Any, storey: str, elevation: float
) -> None:
    """The chair pulled out from under its table, beside it (if the floor there is free)."""
    chair, table = world.objects[chair_key], world.objects[table_key]
    c, s = math.cos(table.yaw), math.sin(table.yaw)
    sides = [(-s, c), (s, -c), (c, s), (-c, -s)]  # beside the table's long sides first, then its ends
    for (ux, uy), half in zip(sides, (table.sy, table.sy, table.sx, table.sx), strict=True):
        d = half / 2 + CHAIR[1] / 2 + 0.2
        x, y = table.x + d * ux, table.y + d * uy
        probe = Obj(-1, x, y, chair.yaw, *CHAIR)
        crowded = any(
            o.present and o.key not in (chair_key, table_key) and math.dist((o.x, o.y), (x, y)) < 0.7
            for o in world.objects.values()
        )
        if all(world.is_free(*p) for p in probe.corners()) and world.is_free(x, y) and not crowded:
            world.events.append(Event("pull", chair_key, now, (chair.x, chair.y), chair.corners()))
            chair.x, chair.y = x, y
            chair.unseen(now)
            apply_truth(oracle, truth_box(chair, storey, elevation))
            return


APART_AFTER_S = 10.0
"""Desks pushed together are pushed apart this long after."""


def push_desk(  # noqa: PLR0917
    world: World, rng: random.Random, now: float, oracle: Any, storey: str, elevation: float
) -> tuple[int, int] | None:
    """A new desk like a present one, pushed against its end (same yaw and sizes): returns (pushed,
    against), or None when no desk has free floor at an end."""
    desks = [o for o in world.objects.values() if o.present and o.key not in world.together]
    desks = [o for o in desks if o.key not in world.together.values()]
    rng.shuffle(desks)
    for a in desks:
        c, s = math.cos(a.yaw), math.sin(a.yaw)
        for side in (1, -1):
            x, y = a.x + side * a.sx * c, a.y + side * a.sx * s
            b = Obj(max(world.objects) + 1, x, y, a.yaw, a.sx, a.sy, a.sz, changed_at=now)
            crowded = any(
                o.present and o.key != a.key and math.dist((o.x, o.y), (x, y)) < 1.0
                for o in world.objects.values()
            )
            if all(world.is_free(*p) for p in b.corners()) and not crowded:
                world.objects[b.key] = b
                world.together[b.key] = a.key
                a.unseen(now)
                world.events.append(Event("push", b.key, now, (x, y), b.corners()))
                apply_truth(oracle, truth_box(b, storey, elevation))
                return b.key, a.key
    return None


def push_apart(  # noqa: PLR0917
    world: World, pushed: int, against: int, now: float, oracle: Any, storey: str, elevation: float
) -> None:
    """The pushed desk moved 0.8 m away from the one it stood against (taken away if there is no room)."""
    b, a = world.objects[pushed], world.objects[against]
    world.together.pop(pushed, None)
    d = math.dist((a.x, a.y), (b.x, b.y))
    x, y = b.x + 0.8 * (b.x - a.x) / d, b.y + 0.8 * (b.y - a.y) / d
    world.events.append(Event("apart", pushed, now, (b.x, b.y), b.corners()))
    moved = Obj(-1, x, y, b.yaw, b.sx, b.sy, b.sz)
    crowded = any(
        o.present and o.key != pushed and math.dist((o.x, o.y), (x, y)) < 1.0 for o in world.objects.values()
    )
    if all(world.is_free(*p) for p in moved.corners()) and not crowded:
        b.x, b.y = x, y
        apply_truth(oracle, truth_box(b, storey, elevation))
    else:
        b.present = False
        apply_truth(oracle, f"{PREFIX}<urn:truth:{b.key}> twin:removed true .".encode())
    for o in (a, b):
        o.unseen(now)


def oracle_service(store: Path, work: Path) -> Any:
    from dataclasses import replace

    from twin.config import FusionRules, load_config
    from twin.graph.store import EmbeddedStore
    from twin.live import TwinService

    copy = work / "oracle"
    shutil.copytree(store, copy)
    st = EmbeddedStore.open(copy)
    cfg = replace(
        load_config(),
        fusion=FusionRules(enabled=False),
        default_rights=frozenset({"create", "dynamic", "doors", "static"}),
    )
    service = TwinService(st, cfg)
    service.start()
    return service


def truth_box(o: Obj, storey: str, elevation: float) -> bytes:
    del elevation
    return (
        PREFIX + f'<urn:truth:{o.key}> twin:ifcClass "IfcFurniture" ; twin:storey "{storey}" ; '
        f'twin:box "{o.x} {o.y} {o.sz / 2} {o.sx} {o.sy} {o.sz} {o.yaw}" .'
    ).encode()


def apply_truth(oracle: Any, payload: bytes) -> None:
    replies: list[Any] = []
    oracle.submit_observation("oracle", payload, replies.append)
    oracle.process()
    assert replies and replies[0].ok, replies


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    import os

    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def run(args: argparse.Namespace) -> dict[str, Any]:
    from adapters.zenoh.client import TwinClient
    from twin.maps.grid import OCCUPIED

    work = Path(tempfile.mkdtemp(prefix="fleet-"))
    store = live.prepare_store(args.model, work)
    if args.model == "lab":
        storey, skill = "ground-floor", "lab-navigation"
    else:
        storey, skill = live.busiest(store)[0], "navigation"
    args.skill = skill
    oracle = oracle_service(store, work)
    m = oracle.live_maps.skill_maps[(storey, skill)]
    f = m.plan.frame
    data = m.data
    blocked = data == OCCUPIED
    free = data == 0
    for _ in range(math.ceil(0.35 / f.resolution_m)):  # keep off the walls
        grown = free.copy()
        grown[1:, :] &= free[:-1, :]
        grown[:-1, :] &= free[1:, :]
        grown[:, 1:] &= free[:, :-1]
        grown[:, :-1] &= free[:, 1:]
        free = grown
    elevation = oracle.live.site.storeys[storey].elevation_m
    world = World(free, blocked, (f.origin_x, f.origin_y), f.resolution_m, elevation)
    rng = random.Random(args.seed)
    for k in range(args.objects):
        spot = world.place(rng)
        if spot is None:
            break
        o = Obj(k, *spot, rng.uniform(0.5, 0.9), rng.uniform(0.35, 0.6), rng.uniform(0.5, 0.9))
        if o.sy > o.sx:
            o.sx, o.sy = o.sy, o.sx
        world.objects[k] = o
        apply_truth(oracle, truth_box(o, storey, elevation))
    placed = len(world.objects)
    # the script: moves, removals, appearances over the middle of the run
    t_first, t_last = args.duration * 0.2, args.duration * 0.75
    kinds = (
        ["move"] * args.moves
        + ["remove"] * args.removals
        + ["appear"] * args.appears
        + ["tuck"] * args.tucks
        + ["push"] * args.pushes
    )
    rng.shuffle(kinds)
    script = [(t_first + (t_last - t_first) * i / max(1, len(kinds)), k) for i, k in enumerate(kinds)]

    config = work / "fleet.toml"
    config.write_text(f"[fusion]\ntentative_sightings = {args.tentative}\n")
    endpoint = f"tcp/127.0.0.1:{live._free_port()}"
    daemon, line = live.serve(
        "--config", str(config), "--store", str(store), "--listen", endpoint, "--no-record"
    )
    site = line.split("site '", 1)[1].split("'", 1)[0]
    prefix = f"twin/{site}"
    stop = threading.Event()
    samples: list[dict[str, Any]] = []
    stats = [RobotStats() for _ in range(args.robots)]
    try:
        with TwinClient.connect([endpoint], prefix=prefix, timeout_s=30.0) as client:
            rev0 = int(client.status()["revision"])
            t0 = time.time()
            trace = Trace(args.trace) if args.trace else None
            if trace is not None:
                args.trace.write_text(json.dumps({"t0": t0}) + "\n")
            t_end = t0 + args.duration
            sat_end = t_end + args.saturate
            cpu0 = cpu_seconds(daemon.pid)
            threads = [
                threading.Thread(
                    target=robot,
                    args=(i, endpoint, prefix, world, storey, args, t_end, sat_end, stats[i], stop, trace),
                    daemon=True,
                )
                for i in range(args.robots)
            ]
            for t in threads:
                t.start()
            next_sample, step = t0 + 1.0, 0
            pulls: list[tuple[float, int, int]] = []  # (when, chair, table): a tucked chair pulled out
            aparts: list[tuple[float, int, int]] = []  # (when, pushed, against): desks pushed apart
            previous: dict[str, tuple[float, float]] = {}
            cpu_main = None
            traced = 0
            while time.time() < sat_end:
                now = time.time()
                while pulls and now >= pulls[0][0]:
                    _, chair_key, table_key = pulls.pop(0)
                    with world.lock:
                        pull_out(world, chair_key, table_key, now, oracle, storey, elevation)
                while aparts and now >= aparts[0][0]:
                    _, pushed, against = aparts.pop(0)
                    with world.lock:
                        push_apart(world, pushed, against, now, oracle, storey, elevation)
                while step < len(script) and now - t0 >= script[step][0]:
                    _, kind = script[step]
                    step += 1
                    with world.lock:
                        present = [o for o in world.objects.values() if o.present]
                        if kind == "push":
                            together = push_desk(world, rng, now, oracle, storey, elevation)
                            if together is not None:
                                aparts.append((now + APART_AFTER_S, *together))
                            continue
                        if kind == "tuck":
                            tucked = tuck_chair(world, rng, now, oracle, storey, elevation)
                            if tucked is not None:
                                pulls.append((now + PULL_AFTER_S, *tucked))
                            continue
                        if kind == "appear" or not present:
                            spot = world.place(rng)
                            if spot is None:
                                continue
                            k = max(world.objects) + 1
                            o = Obj(k, *spot, 0.8, 0.6, 0.75, changed_at=now)
                            world.objects[k] = o
                            world.events.append(Event("appear", k, now, (o.x, o.y), o.corners()))
                            apply_truth(oracle, truth_box(o, storey, elevation))
                            continue
                        present = [o for o in present if o.key not in world.together]
                        present = [o for o in present if o.key not in world.together.values()]
                        if not present:
                            continue
                        o = rng.choice(present)
                        world.events.append(Event(kind, o.key, now, (o.x, o.y), o.corners()))
                        if kind == "remove":
                            o.present = False
                            apply_truth(oracle, f"{PREFIX}<urn:truth:{o.key}> twin:removed true .".encode())
                        else:
                            spot = world.place(rng, near=(o.x, o.y))
                            if spot is None:
                                world.events.pop()
                                continue
                            o.x, o.y, o.yaw = spot
                            apply_truth(oracle, truth_box(o, storey, elevation))
                        o.unseen(now)
                if trace is not None and len(world.events) > traced:
                    with world.lock:
                        for ev in world.events[traced:]:
                            o = world.objects[ev.obj]
                            trace.note(
                                {
                                    "event": ev.kind,
                                    "obj": ev.obj,
                                    "at": round(ev.at, 3),
                                    "old": [round(v, 3) for v in ev.place],
                                    "x": round(o.x, 3),
                                    "y": round(o.y, 3),
                                    "shape": [round(v, 4) for v in (o.sx, o.sy, o.sz, o.yaw)],
                                    "present": o.present,
                                }
                            )
                        traced = len(world.events)
                if now >= next_sample and now < t_end:
                    samples.append(sample(client, world, storey, oracle, skill, t0, previous, args.verbose))
                    next_sample += 1.0
                    if args.verbose:
                        print(json.dumps(samples[-1]), flush=True)
                if now >= t_end and cpu_main is None:
                    cpu_main = cpu_seconds(daemon.pid) - cpu0
                    acked_main = sum(s.acked for s in stats)
                time.sleep(0.05)
            stop.set()
            for t in threads:
                t.join(timeout=60)
            if cpu_main is None:
                cpu_main, acked_main = cpu_seconds(daemon.pid) - cpu0, sum(s.acked for s in stats)
            time.sleep(1.0)
            final = sample(client, world, storey, oracle, skill, t0, previous)
            end_status = client.status()
            rev1 = int(end_status["revision"])
    finally:
        daemon.terminate()
        daemon.wait(timeout=30)
        oracle.store.close()
        shutil.rmtree(work, ignore_errors=True)
    removals = [e for e in world.events if e.kind in ("move", "remove")]
    viewed = [e for e in removals if e.first_view is not None and not _refilled_in_time(e)]
    if args.verbose:
        for e in viewed:
            if e.detected is None or e.detected - (e.first_view or 0) > 10.0:
                print(
                    f"late removal: {e.kind} of {e.obj} at {e.at - t0:.1f} s, place {e.place}, "
                    f"first view {e.first_view and e.first_view - t0}, "
                    f"detected {e.detected and e.detected - t0}"
                )
    recall_hits = [e for e in viewed if e.detected is not None and e.detected - e.first_view <= 10.0]
    moves = [
        e for e in world.events if e.kind == "move" and e.shown is not None and e.first_sighting is not None
    ]
    move_latency = [e.shown - e.first_sighting for e in moves]
    false_removals = _false_removals(samples)
    true_changes = len(world.events) + placed
    late = [s for s in samples if s["t"] > 10.0]
    result = {
        "model": args.model,
        "robots": args.robots,
        "objects": args.objects,
        "placed": placed,
        "duration_s": args.duration,
        "moves": sum(e.kind == "move" for e in world.events),
        "removals": sum(e.kind == "remove" for e in world.events),
        "appears": sum(e.kind == "appear" for e in world.events),
        "tucks": sum(e.kind == "tuck" for e in world.events),
        "pulls": sum(e.kind == "pull" for e in world.events),
        "pushes": sum(e.kind == "push" for e in world.events),
        "aparts": sum(e.kind == "apart" for e in world.events),
        "max_clusters": max((s["clusters"] for s in samples), default=0),
        "final": final,
        "max_duplicates": max((s["duplicates"] for s in late), default=0),
        "max_viewed_ghosts": max((s["viewed_ghosts"] for s in late), default=0),
        "max_viewed_duplicates": max((s["viewed_duplicates"] for s in late), default=0),
        "samples_with_viewed_ghosts": sum(1 for s in late if s["viewed_ghosts"]),
        "samples_with_viewed_duplicates": sum(1 for s in late if s["viewed_duplicates"]),
        "samples_with_ghosts": sum(1 for s in late if s["ghosts"]),
        "samples_with_duplicates": sum(1 for s in late if s["duplicates"]),
        "mean_cells_differ": float(np.mean([s["cells_differ"] for s in late])) if late else 0.0,
        "max_false_free_cells": max((s["false_free_cells"] for s in samples), default=0),
        "max_false_free_unobservable": max((s["false_free_unobservable"] for s in samples), default=0),
        "samples_with_false_free": sum(1 for s in samples if s["false_free_cells"] > 0),
        "behaviours": ",".join(args.behaviours),
        "removal_recall_10s": len(recall_hits) / len(viewed) if viewed else float("nan"),
        "removal_viewed": len(viewed),
        "removal_false": false_removals,
        "move_shown_p50_s": live._pct(move_latency, 50),
        "move_shown_max_s": max(move_latency) if move_latency else float("nan"),
        "moves_measured": len(move_latency),
        "revisions": rev1 - rev0,
        "true_changes": true_changes,
        "revisions_per_change": (rev1 - rev0) / max(1, true_changes),
        "fusion": end_status.get("fusion", {}),
        "acked_observations": sum(s.acked for s in stats),
        "acked_sightings_per_s": sum(s.sightings - s.saturated_sightings for s in stats) / args.duration,
        "saturated_sightings_per_s": (sum(s.saturated_sightings for s in stats) / args.saturate)
        if args.saturate
        else None,
        "errors": sum(s.errors for s in stats),
        "false_detections": sum(s.false_detections for s in stats),
        "daemon_cpu_ms_per_observation": 1e3 * cpu_main / max(1, acked_main),
        "samples": samples,
    }
    result["removal_precision"] = (
        len(recall_hits) / (len(recall_hits) + false_removals)
        if recall_hits or false_removals
        else float("nan")
    )
    return result


def _refilled_in_time(e: Event) -> bool:
    """Whether an object stood at ``e``'s old place again before the element there was due to go (within
    10 s of the first view of the place): the element is that object's, nothing to remove."""
    return e.refilled is not None and (e.first_view is None or e.refilled - e.first_view <= 10.0)


def _false_removals(samples: list[dict[str, Any]]) -> int:
    """Elements that left the twin although their object stood still where they were, and no other
    element took it over (a removal fusion should not have made)."""
    return sum(s["false_removals"] for s in samples)


def plot(result: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = result["samples"]
    t = [x["t"] for x in s]
    fig, ax = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    ax[0].plot(t, [x["objects"] for x in s], label="true objects")
    ax[0].plot(t, [x["elements"] for x in s], label="twin elements")
    ax[0].plot(t, [x["duplicates"] for x in s], label="duplicates")
    ax[0].plot(t, [x["ghosts"] for x in s], label="ghosts")
    ax[0].plot(t, [x["viewed_ghosts"] for x in s], label="ghosts absence could remove 10 s ago")
    ax[0].legend(loc="upper right", fontsize=8)
    ax[1].plot(t, [x["revision"] for x in s], label="revision")
    ax[1].plot(t, [x["cells_differ"] for x in s], label="navigation cells differing from the truth")
    ax[1].legend(loc="upper left", fontsize=8)
    ax[1].set_xlabel("s")
    fig.suptitle(f"{result['model']}: {result['robots']} robots, {result['objects']} objects")
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    p.add_argument("--model", default="lab")
    p.add_argument("--robots", type=int, default=4)
    p.add_argument("--objects", type=int, default=10)
    p.add_argument("--duration", type=float, default=60.0)
    p.add_argument("--saturate", type=float, default=0.0)
    p.add_argument("--rate", type=float, default=5.0)
    p.add_argument("--range", type=float, default=4.0)
    p.add_argument("--speed", type=float, default=0.6)
    p.add_argument("--sigma-pos", type=float, default=0.03)
    p.add_argument("--sigma-yaw", type=float, default=2.0, help="degrees")
    p.add_argument("--p-miss", type=float, default=0.05)
    p.add_argument("--p-false", type=float, default=0.002, help="a false detection per observation")
    p.add_argument("--tentative", type=int, default=1, help="[fusion] tentative_sightings of the daemon")
    p.add_argument("--moves", type=int, default=2)
    p.add_argument("--removals", type=int, default=1)
    p.add_argument("--appears", type=int, default=0)
    p.add_argument("--tucks", type=int, default=0, help="chairs tucked under tables, pulled out 8 s later")
    p.add_argument(
        "--pushes", type=int, default=0, help="desks pushed against another (one box), apart 10 s later"
    )
    p.add_argument("--seed", type=int, default=1)
    p.add_argument(
        "--behaviours",
        type=lambda v: tuple(v.split(",")),
        default=("normal",),
        help=f"robot behaviours, round-robin: {', '.join(BEHAVIOURS)}; 'mixed': all of them",
    )
    p.add_argument("--json", type=Path)
    p.add_argument("--trace", type=Path, help="every acked report of an object and its ack (JSON lines)")
    p.add_argument("--plot", type=Path)
    p.add_argument("-v", "--verbose", action="store_true")
    return p


def main() -> int:
    args = parser().parse_args()
    if args.behaviours == ("mixed",):
        args.behaviours = BEHAVIOURS
    unknown = [b for b in args.behaviours if b not in BEHAVIOURS]
    if unknown:
        print(f"Unknown behaviours {unknown}; known: {', '.join(BEHAVIOURS)}", file=sys.stderr)
        return 2
    result = run(args)
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
    if args.plot:
        plot(result, args.plot)
    short = {k: v for k, v in result.items() if k != "samples"}
    for k, v in short.items():
        print(f"{k:34} {v:.3f}" if isinstance(v, float) else f"{k:34} {v}")
    bad = result["final"]["duplicates"] or result["final"]["viewed_ghosts"]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
