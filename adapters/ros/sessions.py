"""Tracker sessions: a robot's detection ids mean one object only while its tracker runs.

Trackers number their tracks from 1 again when they restart, so ``id`` 3 before and after a restart of
the robot's perception are two different objects. The IRIs the adapter mints carry the session:
``urn:twin-ros:<robot>:det:s<session>:<id>``, where ``<session>`` is the stamp (whole seconds) of the
session's first array. A new session starts when the detector restarted, which the adapter sees as:

- **ids going back**: an id below half of the highest one seen in this session that is not a live
  track (never seen, or not seen for :data:`TRACK_MAX_AGE_NS`): a tracker issues new ids in increasing
  order (a few out of order near the top are not a restart) and drops tracks it lost for a while;
- **a stamp gap**: an array stamped more than ``session_gap_s`` after the previous one, or before it
  (a detector that runs publishes every frame, empty or not).

A restart of the daemon does not start a new session: at start-up it resumes each robot's latest
session from the IRIs the twin holds (aliases and elements, tombstones included), with the ids seen in
it. Starting a session too often costs little (the new IRIs are associated afresh); missing a restart
would let a reused id move an element, so both rules err on the side of a new session.

Example::

    sessions = resume_sessions(store.select, ["robot1"])
    label = sessions["robot1"].observe(stamp_ns, ["3", "7"], gap_ns=10**10)   # "s1700000000"
"""

from __future__ import annotations

import functools
import logging
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from urllib.parse import quote, unquote

from twin.graph.rdf import Row

log = logging.getLogger(__name__)
_NS_PER_S = 1_000_000_000
TRACK_MAX_AGE_NS = 2 * _NS_PER_S
"""A tracker id not seen for this long is no live track: seen again low in the numbering, its tracker
restarted."""
_IRI = re.compile(r"urn:twin-ros:([^:]+):det:s(\d+):(.+)")


@dataclass(slots=True)
class TrackerSession:
    """One robot's current tracker session: its label, the ids seen in it, the last array's stamp."""

    started_s: int | None = None
    ids: dict[str, int | None] = field(default_factory=dict)
    """The live tracks: id -> the stamp it was last seen (None: resumed at start-up, live until the
    first array)."""
    highest: int = -1
    last_stamp_ns: int | None = None
    restarts: int = 0
    """Sessions started after the first (detector restarts seen)."""

    def __reduce__(self) -> tuple[type[TrackerSession], tuple[object, ...]]:
        """A call with its fields (handed over with every array an ingest worker translates)."""
        return (TrackerSession, (self.started_s, self.ids, self.highest, self.last_stamp_ns, self.restarts))

    @property
    def label(self) -> str:
        return f"s{self.started_s or 0}"

    def observe(self, stamp_ns: int, ids: Sequence[str], *, gap_ns: int) -> str:
        """The session of an array stamped ``stamp_ns`` with tracker ``ids`` (a new one when the
        detector restarted); returns its label for the IRIs."""
        numbers = [int(i) for i in ids if i.isdigit()]
        seen = {i: stamp_ns if t is None else t for i, t in self.ids.items()}
        live: dict[str, int | None] = {i: t for i, t in seen.items() if stamp_ns - t <= TRACK_MAX_AGE_NS}
        restarted = self.started_s is None
        if not restarted and self.last_stamp_ns is not None:
            restarted = stamp_ns - self.last_stamp_ns > gap_ns or stamp_ns < self.last_stamp_ns
        if not restarted and self.highest >= 2:
            restarted = any(n < self.highest / 2 and str(n) not in live for n in numbers)
        if restarted:
            if self.started_s is not None:
                self.restarts += 1
                log.info(
                    "New tracker session s%d: the detector restarted (ids went back, or a stamp gap)",
                    max(stamp_ns // _NS_PER_S, (self.started_s or 0) + 1),
                )
            self.started_s = max(stamp_ns // _NS_PER_S, (self.started_s or 0) + 1)
            live = {}
            self.highest = -1
        self.ids = live | dict.fromkeys(ids, stamp_ns)
        self.highest = max([self.highest, *numbers])
        self.last_stamp_ns = stamp_ns
        return self.label


@functools.lru_cache(maxsize=8192)  # a robot's tracks are named again at every array
def session_iri(robot: str, label: str, track_id: str) -> str:
    """The IRI of track ``track_id`` of ``robot``'s session ``label``."""
    return f"urn:twin-ros:{quote(robot, safe='')}:det:{label}:{quote(track_id, safe='')}"


def resume_sessions(
    select: Callable[[str], Sequence[Row]], robots: Iterable[str]
) -> dict[str, TrackerSession]:
    """Each robot's latest session as the twin's IRIs (aliases, elements, tombstones) hold it, so that a
    restart of the daemon continues it: no stamp gap is counted across the restart."""
    rows = select(
        "SELECT DISTINCT ?e WHERE { { ?e twin:aliasOf ?t } UNION { ?e a bot:Element } "
        'FILTER(STRSTARTS(STR(?e), "urn:twin-ros:")) }'
    )
    return sessions_from_iris((r["e"] or "" for r in rows), robots)


def sessions_from_iris(iris: Iterable[str], robots: Iterable[str]) -> dict[str, TrackerSession]:
    """Each of ``robots``' latest session among ``iris`` (a fresh one for a robot with none)."""
    found: dict[str, dict[int, set[str]]] = {}
    for iri in iris:
        m = _IRI.fullmatch(iri)
        if m is not None:
            found.setdefault(unquote(m.group(1)), {}).setdefault(int(m.group(2)), set()).add(
                unquote(m.group(3))
            )
    out = {}
    for robot in robots:
        sessions: Mapping[int, set[str]] = found.get(robot, {})
        if not sessions:
            out[robot] = TrackerSession()
            continue
        started = max(sessions)
        ids = sessions[started]
        numbers = [int(i) for i in ids if i.isdigit()]
        out[robot] = TrackerSession(started, dict.fromkeys(ids), max(numbers, default=-1))
    return out
