"""Steady arrays held back: the daemon passes a robot's re-confirmations to the writer in bunches.

Almost every detection array a robot sends says again what its previous one said: the same tracks, each
box where it was. The writer settles such an array with array operations (confirmations at once), and
what that costs is mostly the caches it finds cold: alone, a confirming array costs the writer about
three times what it costs in a bunch (``benchmarks/confirm_cost.py --flush 32``, with and without
``--single``). :class:`SteadyHold` lets the thread that reads the ingest workers' results
(:class:`~adapters.zenoh.ros_workers.WorkerPool`) hold such *steady* outcomes for up to
``[ros] hold_steady_ms`` and pass them on together; anything else passes at once, with what its robot
held before it (a robot's outcomes keep their order; another robot's held outcomes wait for their time):

- an array is steady when it is a single document of plain boxes (no other change: geometry, doors,
  zones, labels, removals) of the same tracks as the robot's last array that changed something, each
  box within :data:`STEADY_M` and :data:`STEADY_RAD` of that array's box of the same track, of the
  same class and storey;
- after an array that is not (a track appears, is lost or moves), that robot's next
  :data:`SETTLE_ARRAYS` arrays pass at once (the sightings that complete a move);
- refusals, TF waits and anything but an array pass at once.

So a move, a new object or a lost one reaches the twin as soon as it did before; a re-confirmation up to
``hold_steady_ms`` later (its sense time is its own: the twin orders sightings by when they were seen).
The view is not compared: a robot that moves while its tracks stay put sends steady arrays, and the miss
its new view gives an element it covers but does not report (absence) also comes up to
``hold_steady_ms`` later, against the ``miss_span_s`` (1 s) a removal by absence takes anyway.

Example::

    hold = SteadyHold(0.04)
    hold.add(outcomes, time.monotonic())
    if hold.due(time.monotonic()):
        send(hold.take(time.monotonic()))
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from adapters.zenoh.ros_outcomes import Outcome, Translated
from twin.live.validate import Checked
from twin.records import ElementReport, Observation

__all__ = ["SETTLE_ARRAYS", "STEADY_M", "STEADY_RAD", "SteadyHold"]

STEADY_M = 0.12
"""How far a track's box centre (and each of its sizes) may be from the last one passed on for the array
to be steady: far beyond a detector's noise (the boxes of a detector with 2 cm of noise pass it once in
some 8,000 sightings), under the confirmation distance of furniture (0.15 m). A box that crosses it is
passed at once; one that does not still reaches the twin within ``hold_steady_ms``."""
STEADY_RAD = math.radians(6.0)
"""How far its yaw may turn (modulo a half turn) for the array to be steady."""
SETTLE_ARRAYS = 3
"""How many arrays of a robot pass at once after one that changed something (the sightings that complete
a move: ``[fusion] move_sightings`` is 2 by default)."""

_Key = tuple[str | None, str | None, tuple[str, ...]]
"""A report's class, storey and extra classes."""
_Box = tuple[float, float, float, float, float, float, float]


@dataclass(slots=True)
class _Robot:
    """What a robot's arrays said when they last changed (track -> box, class), and how many arrays
    still pass at once."""

    boxes: dict[str, tuple[_Box, _Key]] = field(default_factory=dict)
    settling: int = 0


class SteadyHold:
    """The workers' outcomes, held while each is steady (see the module's docstring) for at most
    ``hold_s`` from the first held; ``hold_s`` 0 holds nothing. An outcome that is not steady makes
    its robot's outcomes due (what it held before, then that one); the other robots' stay held."""

    def __init__(self, hold_s: float) -> None:
        self.hold_s = hold_s
        self.held: list[Outcome] = []
        self._since = math.inf
        self._urgent: set[str] = set()
        """The robots whose held outcomes are due."""
        self._robots: dict[str, _Robot] = {}

    def add(self, outcomes: Sequence[Outcome], now: float) -> None:
        """Hold ``outcomes`` (in order after what is held)."""
        if not outcomes:
            return
        if not self.held:
            self._since = now
        self.held += outcomes
        for o in outcomes:
            if self.hold_s <= 0.0 or not self._steady(o):
                self._urgent.add(o.owner)

    def due(self, now: float) -> bool:
        """Whether some of what is held should go now: a robot's outcome that is not steady, or what
        was held ``hold_s`` ago."""
        return bool(self.held) and (bool(self._urgent) or now - self._since >= self.hold_s)

    def wait_s(self, now: float) -> float | None:
        """How long until what is held is due (None: nothing held)."""
        if not self.held:
            return None
        return 0.0 if self._urgent else max(0.0, self._since + self.hold_s - now)

    def take(self, now: float) -> list[Outcome]:
        """What is due, in order: everything once held ``hold_s``, else the outcomes of the robots with
        an outcome that is not steady (the rest stay held, from when they were)."""
        if now - self._since >= self.hold_s:
            out, self.held = self.held, []
        else:
            urgent = self._urgent
            out = [o for o in self.held if o.owner in urgent]
            self.held = [o for o in self.held if o.owner not in urgent]
        self._urgent = set()
        if not self.held:
            self._since = math.inf
        return out

    def _steady(self, outcome: Outcome) -> bool:
        """Whether ``outcome`` is a steady array (if it is not, it becomes the robot's reference)."""
        if not isinstance(outcome, Translated):
            return False  # a refusal, a wait for TF
        t = outcome
        doc = t.translation.document
        if isinstance(doc, Checked):
            doc = doc.observation
        robot = self._robots.get(t.owner)
        if robot is None:
            robot = self._robots[t.owner] = _Robot()
        if not isinstance(doc, Observation) or t.translation.extra or t.translation.refused:
            robot.boxes, robot.settling = {}, SETTLE_ARRAYS
            return False
        reports = doc.reports
        if not _same(robot.boxes, reports):  # (compared as they are: a dict made only on a change)
            robot.boxes, robot.settling = _boxes(reports) or {}, SETTLE_ARRAYS
            return False
        if robot.settling > 0:  # (the arrays that complete a change pass at once)
            robot.settling -= 1
            return False
        return True


def _plain(r: ElementReport) -> bool:
    """Whether ``r`` is a box and nothing else that changes the twin."""
    return not (
        r.box is None
        or r.geometry is not None
        or r.placement is not None
        or r.removed
        or r.is_open is not None
        or r.keepout is not None
        or r.speed_limit is not None
        or r.labels
        or r.materials
        or r.distinct
        or r.unmerge
        or r.lifetime_s is not None
    )


def _boxes(reports: tuple[ElementReport, ...]) -> dict[str, tuple[_Box, _Key]] | None:
    """Each report's box and class by track, or None unless every report is :func:`_plain`."""
    out: dict[str, tuple[_Box, _Key]] = {}
    for r in reports:
        b = r.box
        if b is None or not _plain(r):
            return None
        out[r.iri] = ((b.cx, b.cy, b.cz, b.sx, b.sy, b.sz, b.yaw), (r.ifc_class, r.storey, r.classes))
    return out


def _same(last: dict[str, tuple[_Box, _Key]], reports: tuple[ElementReport, ...]) -> bool:
    """Whether ``reports`` are plain boxes of the tracks of ``last``, each within the steady bounds of its
    box there, of the same class (the last boxes stay the reference: a slow drift adds up to a change)."""
    if len(last) != len(reports) or not last:
        return False
    hypot, pi = math.hypot, math.pi
    for r in reports:
        was = last.get(r.iri)
        b = r.box
        if was is None or b is None or was[1] != (r.ifc_class, r.storey, r.classes) or not _plain(r):
            return False
        a = was[0]
        if (
            hypot(b.cx - a[0], b.cy - a[1]) > STEADY_M
            or abs(b.cz - a[2]) > STEADY_M
            or abs(b.sx - a[3]) > STEADY_M
            or abs(b.sy - a[4]) > STEADY_M
            or abs(b.sz - a[5]) > STEADY_M
        ):
            return False
        turn = (b.yaw - a[6]) % pi
        if min(turn, pi - turn) > STEADY_RAD:
            return False
    return True
