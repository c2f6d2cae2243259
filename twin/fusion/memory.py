"""What the writer remembers of robots' sightings: per element, who saw it and when, what views missed
it, the confirmations, moves and resizes not yet committed, its previous poses; per robot, its clock
offset; and the robot IRIs that resolved to elements (aliases).

In memory only, except aliases (``twin:aliasOf``, written by the writer) and each element's last
applied sense time (``twin:senseTime``, on the element): it changes many times a second and the graph
does not grow with how often an element is seen. One writer mutates it. :meth:`FusionMemory.to_json`
and :meth:`FusionMemory.from_json` are its one serialiser (everything but the pose index and the pose
cache, which start-up code rebuilds from the shapes: :func:`twin.fusion.poses.build_poses`).

Example::

    memory = FusionMemory()
    track = memory.track(iri)
    track.sighted("robot1", sense_ns)
    again = FusionMemory.from_json(json.loads(json.dumps(memory.to_json())))
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

from twin.fusion.footprints import BoxSizes, Pose, box_pose, box_sizes, placed_pose

TENTATIVE_TTL_NS = 60 * 10**9
"""A tentative robot IRI not seen often enough within this long is forgotten."""


@dataclass(slots=True)
class RobotSightings:
    """One robot's sightings of one element: how many, the first and the last (sense time, ns)."""

    count: int
    first_ns: int
    last_ns: int


@dataclass(slots=True)
class Refinement:
    """The sum of the confirmations since the last committed pose, each first aligned with the held
    pose (:func:`~twin.fusion.footprints.aligned`: a flipped heading or a quarter turn of a square
    footprint averages as the same yaw)."""

    n: int = 0
    cx: float = 0.0
    cy: float = 0.0
    cz: float = 0.0
    sx: float = 0.0
    sy: float = 0.0
    sz: float = 0.0
    yaw: float = 0.0

    def add(self, p: Pose) -> None:
        """Add a sighting already aligned with the held pose."""
        self.n += 1
        self.cx += p.cx
        self.cy += p.cy
        self.cz += p.cz
        self.sx += p.sx
        self.sy += p.sy
        self.sz += p.sz
        self.yaw += p.yaw

    def copy(self) -> Refinement:
        return Refinement(self.n, self.cx, self.cy, self.cz, self.sx, self.sy, self.sz, self.yaw)

    def mean(self) -> Pose:
        n = self.n
        return box_pose(
            self.cx / n, self.cy / n, self.cz / n, self.sx / n, self.sy / n, self.sz / n, yaw=self.yaw / n
        )


@dataclass(slots=True)
class SizeEvidence:
    """One robot's sightings of an element at sizes other than the held ones, that agree with each
    other: how many, their summed sizes (aligned with the held pose), the first and last sense time."""

    n: int = 0
    sx: float = 0.0
    sy: float = 0.0
    sz: float = 0.0
    first_ns: int = 0
    last_ns: int = 0

    def added(self, sx: float, sy: float, sz: float, sense_ns: int) -> SizeEvidence:
        """A copy with one more sighting."""
        first = sense_ns if self.n == 0 else min(self.first_ns, sense_ns)
        return SizeEvidence(
            self.n + 1, self.sx + sx, self.sy + sy, self.sz + sz, first, max(self.last_ns, sense_ns)
        )

    def mean(self) -> tuple[float, float, float]:
        return (self.sx / self.n, self.sy / self.n, self.sz / self.n)


@dataclass(slots=True)
class RobotMean:
    """A moving mean of positions (x, y), how many went into it and the last one's sense time."""

    n: int = 0
    x: float = 0.0
    y: float = 0.0
    last_ns: int = 0

    def added(self, x: float, y: float, sense_ns: int, *, weight: float) -> RobotMean:
        a = 1.0 if self.n == 0 else max(weight, 1.0 / (self.n + 1))
        return RobotMean(
            self.n + 1, self.x + a * (x - self.x), self.y + a * (y - self.y), max(self.last_ns, sense_ns)
        )


class PairTable(dict[tuple[str, str], RobotMean]):
    """(robot, other robot) -> their mean difference (:attr:`FusionMemory.pairs`), a dict that also
    knows each robot's partners: a robot's detector bias reads its own pairs, not every pair of the
    fleet (600 with 25 robots, on every array). Robot -> other robot -> the same mean as the table's."""

    __slots__ = ("_partners",)

    def __init__(self, items: Any = (), /) -> None:
        super().__init__()
        self._partners: dict[str, dict[str, RobotMean]] = {}
        self.update(items)

    def __reduce__(self) -> tuple[type[PairTable], tuple[dict[tuple[str, str], RobotMean]]]:
        return (PairTable, (dict(self),))

    def __setitem__(self, key: tuple[str, str], value: RobotMean) -> None:
        partners = self._partners.get(key[0])
        if partners is None:
            partners = self._partners[key[0]] = {}
        partners[key[1]] = value
        super().__setitem__(key, value)

    def __delitem__(self, key: tuple[str, str]) -> None:
        super().__delitem__(key)
        self._forget(key)

    def _forget(self, key: tuple[str, str]) -> None:
        partners = self._partners.get(key[0])
        if partners is not None:
            partners.pop(key[1], None)

    def update(self, items: Any = (), /, **kw: Any) -> None:
        assert not kw, "pairs are keyed by tuples"
        if not isinstance(items, dict):
            items = dict(items)
        partners = self._partners
        for key, value in items.items():
            partners.setdefault(key[0], {})[key[1]] = value
        dict.update(self, items)

    def pop(self, key: tuple[str, str], *default: Any) -> Any:
        if key in self:
            self._forget(key)
        return super().pop(key, *default)

    def popitem(self) -> tuple[tuple[str, str], RobotMean]:
        key, value = super().popitem()
        self._forget(key)
        return key, value

    def setdefault(self, key: tuple[str, str], default: RobotMean) -> RobotMean:
        if key not in self:
            self[key] = default
        return self[key]

    def clear(self) -> None:
        super().clear()
        self._partners.clear()

    def partners(self, robot: str) -> list[tuple[str, RobotMean]]:
        """``robot``'s pairs: (other robot, the mean difference), in the order they were made."""
        others = self._partners.get(robot)
        return list(others.items()) if others else []

    def of(self, robot: str) -> dict[str, RobotMean] | None:
        """``robot``'s pairs as other robot -> the mean difference (only to read, or to change a mean
        in place: the table holds the same objects)."""
        return self._partners.get(robot)


@dataclass(slots=True)
class Dispute:
    """Robots that disagree on where an element stands: the element covers both poses
    (:mod:`twin.fusion.dispute`) until most of the robots that saw it since agree on one."""

    poses: tuple[Pose, Pose]
    """The held pose before the dispute (side 0) and the pose the robots behind the move saw (side 1)."""
    sides: dict[str, tuple[int, int]] = field(default_factory=dict)
    """Robot -> (the side it takes, the sense time of its latest sighting that confirmed it)."""
    leaning: dict[str, int] = field(default_factory=dict)
    """Robot -> how many of its latest sightings in a row confirmed the other side (it changes sides
    at ``move_sightings``: one sighting nearer the other pose is a detector's outlier)."""


@dataclass(slots=True)
class Miss:
    robot: str
    sense_ns: int


@dataclass(slots=True)
class Track:
    """What the writer knows of one element's sightings."""

    seen_ns: int = 0
    """The latest sense time of anything known about it: its last applied change, or any sighting."""
    robots: dict[str, RobotSightings] = field(default_factory=dict)
    misses: list[Miss] = field(default_factory=list)
    """Views that should have seen it and did not, since its last sighting."""
    refinement: Refinement = field(default_factory=Refinement)
    moving: Refinement | None = None
    """Sightings of a short move not yet believed (``[fusion] move_sightings``), aligned and summed."""
    movers: set[str] = field(default_factory=set)
    """The robots whose sightings are in ``moving``."""
    runs: dict[str, tuple[Refinement, int]] = field(default_factory=dict)
    """Per robot, its latest consecutive sightings that agree on a move not yet applied (summed,
    aligned with the held pose) and the last one's sense time: a robot stands behind a move once
    ``move_sightings`` of its own agree; another robot's confirmation does not erase it."""
    confirmed: dict[str, int] = field(default_factory=dict)
    """Robot -> the sense time of its latest sighting, while that sighting confirmed the held pose
    (a robot that then reports a move leaves): who disagrees with a short move."""
    sizes: dict[str, SizeEvidence] = field(default_factory=dict)
    """Per robot, its agreeing sightings at other sizes than the held ones (a resize not yet believed)."""
    decided: str = ""
    """The rule that decided the latest report of it (for ``twin explain``)."""
    means: dict[str, RobotMean] = field(default_factory=dict)
    """Per robot, where its detector puts the element (a moving mean of its raw sightings since the
    element's last move): the robots' detector biases are estimated from them."""
    dispute: Dispute | None = None
    """Robots disagree on where it stands (a short move the others' confirmations hold): it covers both."""

    def sighted(self, robot: str, sense_ns: int) -> None:
        """A sighting by ``robot`` seen at ``sense_ns``: counted, and misses before it are forgotten."""
        s = self.robots.get(robot)
        if s is None:
            self.robots[robot] = RobotSightings(1, sense_ns, sense_ns)
        else:
            s.count += 1
            if sense_ns < s.first_ns:  # noqa: PLR1730 (min and max are calls: 20 boxes an array)
                s.first_ns = sense_ns
            if sense_ns > s.last_ns:  # noqa: PLR1730
                s.last_ns = sense_ns
        if sense_ns > self.seen_ns:  # noqa: PLR1730
            self.seen_ns = sense_ns
        if self.misses:
            self.misses = [m for m in self.misses if m.sense_ns > sense_ns]

    def as_json(self) -> dict[str, object]:
        return {
            "sightings": {
                r: {"count": s.count, "first_ns": s.first_ns, "last_ns": s.last_ns}
                for r, s in sorted(self.robots.items())
            },
            "misses": [{"robot": m.robot, "sense_ns": m.sense_ns} for m in self.misses],
            "seen_ns": self.seen_ns,
            **({"decided": self.decided} if self.decided else {}),
            **(
                {
                    "pending_move": {
                        "sightings": self.moving.n,
                        "robots": sorted(self.movers),
                        "to": [round(v, 3) for v in (self.moving.mean().cx, self.moving.mean().cy)],
                    }
                }
                if self.moving is not None and self.moving.n
                else {}
            ),
            **(
                {
                    "disputed": {
                        "poses": [[round(p.cx, 3), round(p.cy, 3)] for p in self.dispute.poses],
                        "robots": {r: side for r, (side, _) in sorted(self.dispute.sides.items())},
                    }
                }
                if self.dispute is not None
                else {}
            ),
            **(
                {
                    "pending_resize": {
                        r: {"sightings": e.n, "sizes": [round(v, 3) for v in e.mean()]}
                        for r, e in sorted(self.sizes.items())
                    }
                }
                if self.sizes
                else {}
            ),
        }


@dataclass(slots=True)
class ClockEstimate:
    """One robot's clock offset: the running minimum of arrival - sense time (ns) over a window of
    arrival time (a monotonic queue: deltas increasing, the minimum first)."""

    samples: deque[tuple[int, int]] = field(default_factory=deque)
    """(arrival, arrival - sense) of the samples that can still be the window's minimum."""
    first_ns: int = 0
    """Arrival of the first sample since the window last ran empty (the estimate settles after it)."""
    warned: bool = False

    def add(self, arrival_ns: int, delta_ns: int, *, window_ns: int) -> None:
        while self.samples and self.samples[0][0] < arrival_ns - window_ns:
            self.samples.popleft()
        if not self.samples:
            self.first_ns = arrival_ns
        while self.samples and self.samples[-1][1] >= delta_ns:
            self.samples.pop()
        self.samples.append((arrival_ns, delta_ns))

    @property
    def offset_ns(self) -> int:
        """How far the robot's clock is behind the daemon's (negative: ahead), latency included."""
        return self.samples[0][1] if self.samples else 0


@dataclass(frozen=True, slots=True)
class Tentative:
    """A robot IRI of a new object held until seen often enough: how many sightings so far and when the
    first arrived; held from a robot that streams views (:mod:`twin.fusion.tentative`), also the robot,
    the storey and the pose it was seen at (its next view that should have seen it without it drops it)."""

    seen: int
    since_ns: int
    robot: str = ""
    storey: str = ""
    pose: Pose | None = None


@dataclass(frozen=True, slots=True)
class PastPose:
    """Where an element stood until a change seen at ``until_ns`` moved or removed it."""

    storey: str
    pose: Pose
    until_ns: int


ABSENT = object()
"""A journaled entry that did not exist (:meth:`FusionMemory.changing`)."""

HISTORY_PER_ELEMENT = 8
"""Past poses kept per element (its last moves, or its removal)."""


@dataclass(slots=True)
class Alias:
    """A robot IRI that resolved to ``target``; forgotten when unused for ``alias_ttl_s``."""

    target: str
    used_ns: int


@dataclass(slots=True)
class FusionMemory:
    """Every element's :class:`Track`, the aliases, the poses of dynamic elements per storey, and the
    robot IRIs held tentative until seen often enough."""

    tracks: dict[str, Track] = field(default_factory=dict)
    aliases: dict[str, Alias] = field(default_factory=dict)
    poses: dict[str, dict[str, Pose]] | None = None
    """Storey -> element -> pose of every dynamic element with geometry (None: not built yet)."""
    pose_arrays: dict[str, Any] = field(default_factory=dict)
    """Storey -> the index's poses as arrays (:class:`twin.fusion.poses.StoreyArrays`), built on use and
    dropped when the storey's poses change."""
    tentative: dict[str, Tentative] = field(default_factory=dict)
    """Robot IRIs of new elements not seen often enough yet (``tentative_sightings``,
    ``stream_sightings``); forgotten after :data:`TENTATIVE_TTL_NS` (a false detection seen once)."""
    views: dict[str, int] = field(default_factory=dict)
    """Per robot, when its latest view was seen (sense time, corrected; ns): a robot whose views come
    often streams (:mod:`twin.fusion.tentative`)."""
    distinct: set[str] = field(default_factory=set)
    """Elements robots said are distinct objects (never merged into another)."""
    history: dict[str, deque[PastPose]] = field(default_factory=dict)
    """Per element, its previous poses and the sense times of the changes that ended them (the last
    :data:`HISTORY_PER_ELEMENT`; a removed element's last pose too): late news is checked against them."""
    clocks: dict[str, ClockEstimate] = field(default_factory=dict)
    """Per robot, its clock offset estimate (:mod:`twin.fusion.clocks`)."""
    pairs: PairTable = field(default_factory=PairTable)
    """(robot, other robot) -> the mean difference (x, y) between where they put the elements both see
    (:mod:`twin.fusion.bias`)."""
    shape_poses: dict[str, tuple[object, object, Pose, BoxSizes | None]] = field(default_factory=dict)
    """Element -> (mesh, placement, pose, the mesh's box sizes if a box): the pose of the shape it has,
    computed once per shape; the box test once per mesh (a move keeps the mesh)."""
    confirm_cache: Any = None
    """What confirmations at once (:mod:`twin.fusion.confirm_array`) keep between arrays: each element's
    gates while the objects they were made from stay the same (checked at every use)."""
    journal: dict[tuple[str, Any], Any] | None = None
    """While an observation waits for the store (:meth:`begin` .. :meth:`keep` or :meth:`undo`): each
    entry the effects changed since (part, key) -> its value before (:data:`ABSENT`: it had none)."""

    def pose(self, iri: str, shape: tuple[Any, Any]) -> Pose:
        """The pose of ``iri``'s current ``shape`` (cached while the shape's objects stay the same)."""
        cached = self.shape_poses.get(iri)
        if cached is not None and cached[0] is shape[0]:
            if cached[1] is shape[1]:
                return cached[2]
            box = cached[3]  # moved: the same mesh, tested once (None: not a box)
        else:
            box = box_sizes(shape[0].vertices)
        pose = placed_pose(shape, box)
        self.shape_poses[iri] = (shape[0], shape[1], pose, box)
        return pose

    def track(self, iri: str) -> Track:
        """``iri``'s track, made if it has none (to change it: journaled)."""
        if self.journal is not None:
            self.changing("tracks", iri)
        t = self.tracks.get(iri)
        if t is None:
            t = self.tracks[iri] = Track()
        return t

    def existing(self, iri: str) -> Track | None:
        """``iri``'s track if it has one (to change it: journaled)."""
        if self.journal is not None:
            self.changing("tracks", iri)
        return self.tracks.get(iri)

    def changing(self, part: str, key: Any) -> None:
        """``part`` (``"tracks"``, ``"aliases"``, ``"tentative"``, ``"views"``, ``"pairs"`` or
        ``"distinct"``) is about to change at ``key``: while journaling, its value before is kept."""
        journal = self.journal
        if journal is None or (part, key) in journal:
            return
        if part == "distinct":
            journal[part, key] = key in self.distinct
            return
        value = getattr(self, part).get(key, ABSENT)
        if part == "tracks" and value is not ABSENT:
            value = _track(_track_json(value))  # a copy, by the one serialiser
        elif part == "aliases" and value is not ABSENT:
            value = Alias(value.target, value.used_ns)
        journal[part, key] = value  # tentative, views, pairs: values replaced, never changed in place

    def begin(self) -> None:
        """Journal the changes from here on (an observation's effects before the store accepts it)."""
        if self.journal is None:
            self.journal = {}

    def keep(self) -> None:
        """The store accepted the journaled changes: keep them."""
        self.journal = None

    def undo(self) -> None:
        """The store refused: every entry changed since :meth:`begin` as it was then."""
        journal, self.journal = self.journal or {}, None
        for (part, key), value in journal.items():
            if part == "distinct":
                (self.distinct.add if value else self.distinct.discard)(key)
            elif value is ABSENT:
                getattr(self, part).pop(key, None)
            else:
                getattr(self, part)[key] = value

    def remember(self, iri: str, past: PastPose) -> None:
        """``iri`` stood at ``past.pose`` until ``past.until_ns``."""
        kept = self.history.get(iri)
        if kept is None:
            kept = self.history[iri] = deque(maxlen=HISTORY_PER_ELEMENT)
        kept.append(past)

    def to_json(self) -> dict[str, Any]:
        """Everything fusion remembers (tracks, aliases, tentative IRIs, distinct elements, previous
        poses, clock offsets) as JSON-able values; not the pose index nor the pose cache (start-up code
        rebuilds them from the shapes)."""
        return memory_to_json(self)

    @classmethod
    def from_json(cls, value: dict[str, Any]) -> FusionMemory:
        """The memory :meth:`to_json` gave (its pose index not built: ``poses`` is None)."""
        return memory_from_json(value)

    def aliases_of(self, target: str) -> list[str]:
        return sorted(a for a, v in self.aliases.items() if v.target == target)


def expire_aliases(memory: FusionMemory, now_ns: int, ttl_ns: int) -> list[str]:
    """Forget the aliases unused for ``ttl_ns`` (returned, for the writer to delete from the graph) and
    the tentative IRIs older than :data:`TENTATIVE_TTL_NS`."""
    old = [a for a, v in memory.aliases.items() if now_ns - v.used_ns > ttl_ns]
    for a in old:
        del memory.aliases[a]
    for iri in [i for i, t in memory.tentative.items() if now_ns - t.since_ns > TENTATIVE_TTL_NS]:
        del memory.tentative[iri]
    return sorted(old)


# --- the one serialiser ------------------------------------------------------------------------------------

MEMORY_FORMAT = 2
"""The version of :meth:`FusionMemory.to_json`'s layout."""


def _pose_json(p: Pose) -> list[float]:
    return [p.cx, p.cy, p.cz, p.sx, p.sy, p.sz, p.yaw]


def _pose(v: Any) -> Pose:
    return Pose(*(float(x) for x in v))


def _refinement_json(r: Refinement) -> list[float]:
    return [r.n, r.cx, r.cy, r.cz, r.sx, r.sy, r.sz, r.yaw]


def _refinement(v: Any) -> Refinement:
    return Refinement(int(v[0]), *(float(x) for x in v[1:]))


def _track_json(t: Track) -> dict[str, Any]:
    return {
        "seen_ns": t.seen_ns,
        "robots": {r: [s.count, s.first_ns, s.last_ns] for r, s in t.robots.items()},
        "misses": [[m.robot, m.sense_ns] for m in t.misses],
        "refinement": _refinement_json(t.refinement),
        "moving": None if t.moving is None else _refinement_json(t.moving),
        "movers": sorted(t.movers),
        "confirmed": dict(t.confirmed),
        "sizes": {r: [e.n, e.sx, e.sy, e.sz, e.first_ns, e.last_ns] for r, e in t.sizes.items()},
        "decided": t.decided,
        "means": {r: [m.n, m.x, m.y, m.last_ns] for r, m in t.means.items()},
        "runs": {r: [_refinement_json(ref), ns] for r, (ref, ns) in t.runs.items()},
        "dispute": None
        if t.dispute is None
        else {
            "poses": [_pose_json(p) for p in t.dispute.poses],
            "sides": {r: list(v) for r, v in t.dispute.sides.items()},
            "leaning": dict(t.dispute.leaning),
        },
    }


def _track(v: dict[str, Any]) -> Track:
    return Track(
        seen_ns=int(v["seen_ns"]),
        robots={r: RobotSightings(int(c), int(f), int(la)) for r, (c, f, la) in v["robots"].items()},
        misses=[Miss(str(r), int(ns)) for r, ns in v["misses"]],
        refinement=_refinement(v["refinement"]),
        moving=None if v["moving"] is None else _refinement(v["moving"]),
        movers=set(v["movers"]),
        confirmed={r: int(ns) for r, ns in v["confirmed"].items()},
        sizes={
            r: SizeEvidence(int(n), float(sx), float(sy), float(sz), int(f), int(la))
            for r, (n, sx, sy, sz, f, la) in v["sizes"].items()
        },
        decided=str(v["decided"]),
        means={r: RobotMean(int(n), float(x), float(y), int(ns)) for r, (n, x, y, ns) in v["means"].items()},
        runs={r: (_refinement(ref), int(ns)) for r, (ref, ns) in v["runs"].items()},
        dispute=_dispute(v.get("dispute")),
    )


def _dispute(v: Any) -> Dispute | None:
    if v is None:
        return None
    a, b = v["poses"]
    return Dispute(
        (_pose(a), _pose(b)),
        {r: (int(side), int(ns)) for r, (side, ns) in v["sides"].items()},
        {r: int(n) for r, n in v.get("leaning", {}).items()},
    )


def memory_to_json(m: FusionMemory) -> dict[str, Any]:
    """Everything fusion remembers as JSON-able values (see :meth:`FusionMemory.to_json`)."""
    return {
        "format": MEMORY_FORMAT,
        "tracks": {iri: _track_json(t) for iri, t in m.tracks.items()},
        "aliases": {a: [v.target, v.used_ns] for a, v in m.aliases.items()},
        "tentative": {
            iri: [t.seen, t.since_ns, t.robot, t.storey, None if t.pose is None else _pose_json(t.pose)]
            for iri, t in m.tentative.items()
        },
        "views": dict(m.views),
        "distinct": sorted(m.distinct),
        "history": {
            iri: [[p.storey, _pose_json(p.pose), p.until_ns] for p in past] for iri, past in m.history.items()
        },
        "clocks": {
            robot: {"samples": [list(s) for s in e.samples], "first_ns": e.first_ns, "warned": e.warned}
            for robot, e in m.clocks.items()
        },
        "pairs": [[a, b, d.n, d.x, d.y, d.last_ns] for (a, b), d in m.pairs.items()],
    }


def memory_from_json(v: dict[str, Any]) -> FusionMemory:
    """The memory :func:`memory_to_json` wrote; ValueError naming a layout it does not know."""
    if v.get("format") != MEMORY_FORMAT:
        msg = f"Fusion memory of format {v.get('format')!r}: this daemon reads format {MEMORY_FORMAT}."
        raise ValueError(msg)
    m = FusionMemory(
        tracks={iri: _track(t) for iri, t in v["tracks"].items()},
        aliases={a: Alias(str(t), int(ns)) for a, (t, ns) in v["aliases"].items()},
        tentative={
            iri: Tentative(int(n), int(since), str(robot), str(storey), None if pose is None else _pose(pose))
            for iri, (n, since, robot, storey, pose) in v["tentative"].items()
        },
        views={robot: int(ns) for robot, ns in v["views"].items()},
        distinct=set(v["distinct"]),
        clocks={
            robot: ClockEstimate(
                deque((int(a), int(d)) for a, d in e["samples"]), int(e["first_ns"]), bool(e["warned"])
            )
            for robot, e in v["clocks"].items()
        },
        pairs=PairTable(
            ((str(a), str(b)), RobotMean(int(n), float(x), float(y), int(ns)))
            for a, b, n, x, y, ns in v["pairs"]
        ),
    )
    for iri, past in v["history"].items():
        for storey, pose, until in past:
            m.remember(iri, PastPose(str(storey), _pose(pose), int(until)))
    return m
