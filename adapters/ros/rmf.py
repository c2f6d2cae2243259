"""Open-RMF's messages as observations: ``rmf_obstacle_msgs/msg/Obstacles`` (boxes that come and go) and
``rmf_door_msgs/msg/DoorState`` (a door's mode).

**Obstacles.** Each obstacle's ``classification`` is looked up in the source's class table (unknown:
ignored and counted), its ``level_name`` in the level table (RMF level -> storey key, with the level's
transform to the twin's frame where the two differ; unknown: refused), ``bbox`` is its box on that
storey (z above the level's floor). ``action`` works per RMF ``source``: ADD (or modify) upserts the
obstacle ``urn:twin-ros:<twin source>:obstacle:<rmf source>/<id>``; DELETE removes it; DELETEALL
removes every obstacle of that RMF source this daemon added. A non-zero ``lifetime`` makes it expire:
:meth:`ObstacleTracker.expire` removes what has lapsed. The tracker holds an obstacle from its ADD on
(a DELETE right behind it finds it), and lets go of it again when the twin refuses the ADD (told
through :attr:`Translation.settle`): a refused obstacle is not held, deleted or expired. A removal the
twin refuses while it still holds the obstacle (its store full or unreachable) is held again, to be
tried again :data:`REMOVAL_RETRY_S` later (:meth:`ObstacleTracker.removal_refused`).

**Door states.** ``door_name`` is matched to a door of the twin by the source's door table (door name
-> IRI, GlobalId or name of an ``IfcDoor``), else by GlobalId, else by the door's name; OPEN and CLOSED
become ``twin:isOpen true`` / ``false``; MOVING, OFFLINE and UNKNOWN change nothing (counted).

Example::

    tracker = ObstacleTracker(settings)
    t = tracker.translate(payload, now_ns=time.time_ns())
    later = tracker.expire(now_ns=time.time_ns())      # removals of lapsed obstacles
"""

from __future__ import annotations

import contextlib
import itertools
import math
import threading
from collections import Counter
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any
from urllib.parse import unquote

from adapters.ros.cdr import _deserialize
from adapters.ros.detections import box_in_map
from adapters.ros.interfaces import DOOR_STATE, OBSTACLES
from adapters.ros.observation_doc import BoxReport, RosInputError, Translation, observation_turtle, robot_iri
from adapters.ros.tf import matrix
from twin.errors import MapError, ModelError
from twin.graph import vocab
from twin.live.parse import sense_time_ns
from twin.live.validate import MAX_LIFETIME_S

__all__ = [
    "HELD_OBSTACLES",
    "DoorIndex",
    "DoorSettings",
    "Level",
    "ObstacleSettings",
    "ObstacleTracker",
    "held_obstacles",
    "translate_door_state",
]

_NS_PER_S = 1_000_000_000
MAX_OBSTACLES_BYTES = 16 << 20
"""Larger Obstacles messages are refused before they are decoded (voxel data included)."""
MAX_DOOR_STATE_BYTES = 64 << 10
REMOVAL_RETRY_S = 2.0
"""How long after a refused removal of a held obstacle it is tried again."""
ACTION_ADD, ACTION_DELETE, ACTION_DELETEALL = 1, 2, 3
MODE_CLOSED, MODE_MOVING, MODE_OPEN, MODE_OFFLINE, MODE_UNKNOWN = 0, 1, 2, 3, 4
_MODE_NAMES = {MODE_MOVING: "moving", MODE_OFFLINE: "offline", MODE_UNKNOWN: "unknown"}


@dataclass(frozen=True, slots=True)
class Level:
    """An RMF level: the twin's storey key, and ``twin_from_level`` as x, y (m) and yaw (rad)."""

    storey: str
    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0

    def matrix(self) -> Any:
        half = self.yaw / 2
        return matrix((self.x, self.y, 0.0), (0.0, 0.0, math.sin(half), math.cos(half)))


@dataclass(frozen=True, slots=True)
class ObstacleSettings:
    source: str
    classes: Mapping[str, str]
    levels: Mapping[str, Level]
    max_obstacles: int = 256
    max_size_m: float = 20.0
    max_tilt_rad: float = math.radians(15.0)


class ObstacleTracker:
    """The obstacles one twin source has added, per RMF ``source``, with their expiry (None: none).
    One owner (the ingest's worker) translates; the twin's verdict on an ADD comes from the writer's
    thread (:attr:`Translation.settle`), hence the lock."""

    def __init__(self, settings: ObstacleSettings) -> None:
        self.settings = settings
        self._known: dict[str, dict[str, int | None]] = {}
        self._lock = threading.Lock()
        self._set_by: dict[str, int] = {}
        """Obstacle -> the translation that last held it (its ADD may still be refused)."""
        self._count = itertools.count(1)

    def _iri(self, rmf_source: str, obstacle_id: int) -> str:
        return robot_iri(self.settings.source, "obstacle", f"{rmf_source}/{obstacle_id}")

    @property
    def held(self) -> int:
        with self._lock:
            return sum(len(v) for v in self._known.values())

    def translate(
        self, payload: bytes | bytearray | memoryview, *, now_ns: int, fusion_terms: bool = True
    ) -> Translation:
        """One Obstacles message as one observation; RosInputError if malformed or too long."""
        s = self.settings
        if len(payload) > MAX_OBSTACLES_BYTES:
            msg = f"Obstacles of {len(payload)} bytes is larger than the limit {MAX_OBSTACLES_BYTES}."
            raise RosInputError("oversized", msg)
        try:
            message = _deserialize(payload, OBSTACLES)
        except MapError as err:
            raise RosInputError("malformed", str(err)) from err
        if len(message.obstacles) > s.max_obstacles:
            msg = f"Obstacles has {len(message.obstacles)} obstacles, more than the limit {s.max_obstacles}."
            raise RosInputError("oversized", msg)
        ignored: Counter[str] = Counter()
        refused: list[tuple[str, str]] = []
        boxes: dict[str, BoxReport] = {}
        removed: dict[str, None] = {}
        added: dict[str, tuple[str, int | None]] = {}
        for o in message.obstacles:
            rmf_source, action = str(o.source), int(o.action)
            with self._lock:
                known = dict(self._known.get(rmf_source, {}))
            if action == ACTION_DELETEALL:
                removed.update(dict.fromkeys(known))
                for iri in known:
                    boxes.pop(iri, None)
                continue
            iri = self._iri(rmf_source, int(o.id))
            if action == ACTION_DELETE:
                if iri in known or iri in boxes:
                    removed[iri] = None
                    boxes.pop(iri, None)
                else:
                    ignored["unknown_id"] += 1
                continue
            if action != ACTION_ADD:
                refused.append(("action", f"Obstacle {iri}: unknown action {action}."))
                continue
            ifc_class = s.classes.get(str(o.classification))
            if ifc_class is None:
                ignored["unknown_class"] += 1
                continue
            level = s.levels.get(str(o.level_name))
            if level is None:
                known_levels = ", ".join(sorted(s.levels)) or "none"
                refused.append(
                    ("unknown_level", f"Unknown RMF level {o.level_name!r} (configured: {known_levels}).")
                )
                continue
            c, q, size = o.bbox.center.position, o.bbox.center.orientation, o.bbox.size
            try:
                box = box_in_map(
                    level.matrix(),
                    (float(c.x), float(c.y), float(c.z)),
                    (float(q.x), float(q.y), float(q.z), float(q.w)),
                    (float(size.x), float(size.y), float(size.z)),
                    max_tilt_rad=s.max_tilt_rad,
                    max_size_m=s.max_size_m,
                )
            except RosInputError as err:
                refused.append((err.cause, f"Obstacle {iri}: {err}"))
                continue
            lifetime_ns = int(o.lifetime.sec) * _NS_PER_S + int(o.lifetime.nanosec)
            if not 0 <= lifetime_ns <= MAX_LIFETIME_S * _NS_PER_S:
                why = f"lifetime {lifetime_ns / _NS_PER_S:g} s is outside 0 to {MAX_LIFETIME_S:g} s"
                refused.append(("malformed", f"Obstacle {iri}: {why}"))
                continue
            expiry = now_ns + lifetime_ns if lifetime_ns > 0 else None
            boxes[iri] = BoxReport(
                iri, ifc_class, level.storey, box, label=str(o.classification) or None,
                lifetime_s=lifetime_ns / _NS_PER_S,
            )  # fmt: skip
            removed.pop(iri, None)
            added[iri] = (rmf_source, expiry)
        settle = self._hold(added, removed)
        document = observation_turtle(boxes=list(boxes.values()), fusion_terms=fusion_terms)
        return Translation(
            document, tuple(boxes), dict(ignored), tuple(refused), _removals(removed),
            settle=settle if document is not None else None, removes=tuple(removed),
        )  # fmt: skip

    def _hold(
        self, added: dict[str, tuple[str, int | None]], removed: Iterable[str]
    ) -> Callable[[bool], None]:
        """Hold ``added`` and let go of ``removed`` now; the returned function, told that the twin
        refused the ADDs, puts back what was held of them before (nothing, or an earlier ADD's expiry),
        unless a later message has held them again."""
        with self._lock:
            for iri in removed:
                for held in self._known.values():
                    held.pop(iri, None)
                self._set_by.pop(iri, None)
            number = next(self._count)
            before: dict[str, tuple[str, int | None, int] | None] = {}
            for iri, (rmf_source, expiry) in added.items():
                known = self._known.get(rmf_source, {})
                before[iri] = (rmf_source, known[iri], self._set_by.get(iri, 0)) if iri in known else None
                self._known.setdefault(rmf_source, {})[iri] = expiry
                self._set_by[iri] = number

        def settle(accepted: bool) -> None:
            if accepted:
                return
            with self._lock:
                for iri, (rmf_source, _) in added.items():
                    if self._set_by.get(iri) != number:
                        continue  # held again since (or deleted): that message decides
                    held = before[iri]
                    if held is None:
                        self._known.get(rmf_source, {}).pop(iri, None)
                        self._set_by.pop(iri, None)
                    else:
                        self._known.setdefault(held[0], {})[iri] = held[1]
                        self._set_by[iri] = held[2]

        return settle

    @property
    def prefix(self) -> str:
        """The start of the IRI of every obstacle this twin source adds."""
        return robot_iri(self.settings.source, "obstacle", "")

    def restore(self, held: Iterable[tuple[str, int | None]]) -> int:
        """Take back the obstacles a previous run added and the twin still holds, ``(iri, expiry ns or
        None)`` each (from the graph: see :func:`held_obstacles`), so that DELETE, DELETEALL and
        lifetimes hold across a restart. Returns how many were taken."""
        n = 0
        with self._lock:
            for iri, expiry in held:
                if not iri.startswith(self.prefix):
                    continue
                rmf_source, _, _ = unquote(iri[len(self.prefix) :]).rpartition("/")
                self._known.setdefault(rmf_source, {})[iri] = expiry
                n += 1
        return n

    def next_expiry(self) -> int | None:
        """When the next held obstacle lapses (ns), or None."""
        with self._lock:
            times = [t for held in self._known.values() for t in held.values() if t is not None]
        return min(times, default=None)

    def expire(self, *, now_ns: int) -> Translation:
        """The removal of every held obstacle whose lifetime has lapsed by ``now_ns``."""
        with self._lock:
            lapsed = [
                iri
                for held in self._known.values()
                for iri, t in held.items()
                if t is not None and t <= now_ns
            ]
            for held in self._known.values():
                for iri in lapsed:
                    held.pop(iri, None)
            for iri in lapsed:
                self._set_by.pop(iri, None)
        return Translation(None, (), extra=_removals(lapsed), removes=tuple(lapsed))

    def removal_refused(self, iri: str, *, now_ns: int) -> None:
        """The twin refused the removal of ``iri`` and still holds it: hold it again, with its removal
        due :data:`REMOVAL_RETRY_S` from ``now_ns`` (a DELETE, DELETEALL or lapsed lifetime then holds
        once the twin takes writes again)."""
        if not iri.startswith(self.prefix):
            return
        rmf_source, _, _ = unquote(iri[len(self.prefix) :]).rpartition("/")
        with self._lock:
            self._known.setdefault(rmf_source, {})[iri] = now_ns + round(REMOVAL_RETRY_S * _NS_PER_S)
            self._set_by.pop(iri, None)


HELD_OBSTACLES = (
    "SELECT ?e ?at ?life WHERE { ?e twin:observedAt ?at . OPTIONAL { ?e twin:lifetime ?life } "
    'FILTER(STRSTARTS(STR(?e), "urn:twin-ros:")) FILTER NOT EXISTS { ?e twin:removed true } }'
)
"""Every element a ROS source or robot minted that the twin holds, with when it last changed and its
``twin:lifetime``."""


def held_obstacles(rows: Iterable[Mapping[str, str | None]]) -> list[tuple[str, int | None]]:
    """``(iri, expiry ns or None)`` of the rows of :data:`HELD_OBSTACLES`: the expiry is the last change
    plus the lifetime (none: 0 or no lifetime). An obstacle re-sent since its last change lapses at most
    that much earlier than it would have in the previous run; one still reported is added again."""
    out: list[tuple[str, int | None]] = []
    for row in rows:
        iri, at, life = row.get("e"), row.get("at"), row.get("life")
        if not iri or not at:
            continue
        try:
            lifetime_ns = round(float(life) * _NS_PER_S) if life else 0
            expiry = sense_time_ns(at) + lifetime_ns if lifetime_ns > 0 else None
        except ValueError:
            continue
        out.append((iri, expiry))
    return out


def _removals(iris: Iterable[str]) -> tuple[bytes, ...]:
    """One removal document per element (one the twin refuses fails alone), in the order of ``iris``."""
    docs = tuple(observation_turtle(removed=[iri]) for iri in iris)
    return tuple(doc for doc in docs if doc is not None)


@dataclass(frozen=True, slots=True)
class DoorSettings:
    source: str
    doors: Mapping[str, str]
    """RMF ``door_name`` -> the twin door's IRI, GlobalId or name."""


class DoorIndex:
    """The twin's doors by IRI, GlobalId and name (a name shared by several doors matches none)."""

    def __init__(self, doors: Iterable[tuple[str, str]]) -> None:
        self.iris: set[str] = set()
        self.by_guid: dict[str, str] = {}
        names: dict[str, list[str]] = {}
        for iri, name in doors:
            self.iris.add(iri)
            tail = iri.rsplit("_", 1)[-1]
            with contextlib.suppress(ModelError, ValueError):
                self.by_guid[vocab.compress_guid(tail)] = iri
            if name:
                names.setdefault(name, []).append(iri)
        self.by_name = {n: iris[0] for n, iris in names.items() if len(iris) == 1}
        self.ambiguous = {n for n, iris in names.items() if len(iris) > 1}

    def find(self, key: str) -> str | None:
        if key in self.iris:
            return key
        return self.by_guid.get(key) or self.by_name.get(key)


def translate_door_state(
    payload: bytes | bytearray | memoryview,
    settings: DoorSettings,
    index: DoorIndex,
    *,
    fusion_terms: bool = True,
) -> Translation:
    """One DoorState as an observation of the matched door's state (see the module's docstring)."""
    if len(payload) > MAX_DOOR_STATE_BYTES:
        raise RosInputError(
            "oversized", f"A DoorState of {len(payload)} bytes (limit {MAX_DOOR_STATE_BYTES})."
        )
    try:
        message = _deserialize(payload, DOOR_STATE)
    except MapError as err:
        raise RosInputError("malformed", str(err)) from err
    name = str(message.door_name)
    mode = int(message.current_mode.value)
    if mode not in (MODE_OPEN, MODE_CLOSED):
        return Translation(None, (), {f"mode_{_MODE_NAMES.get(mode, 'invalid')}": 1})
    configured = settings.doors.get(name)
    iri = index.find(configured if configured is not None else name)
    if iri is None:
        why = f" (configured as {configured!r})" if configured is not None else ""
        extra = " (several doors have that name: configure it)" if name in index.ambiguous else ""
        msg = f"No door of the twin matches RMF door {name!r}{why}{extra}."
        raise RosInputError("unknown_door", msg)
    stamp = int(message.door_time.sec) * _NS_PER_S + int(message.door_time.nanosec)
    document = observation_turtle(
        doors=[(iri, mode == MODE_OPEN)], sense_ns=stamp or None, fusion_terms=fusion_terms
    )
    return Translation(document, (iri,))
