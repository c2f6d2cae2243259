"""Sense time: when a report was seen, on the daemon's clock, and whether it is news.

A report's sense time is its own ``twin:senseTime``, else its view's, else its arrival. Robots' clocks
are off: each robot's **clock offset** is estimated as the least arrival - sense time over the last
``clock_window_s`` (every observation counts, accepted or not), and once its reports span
``clock_settle_s`` its sense times are corrected by it, so that sense times from different robots
compare. A sense time (corrected) later than its arrival is taken as its arrival. Until the offset is
known, a sense time more than ``max_clock_skew_s`` ahead of the daemon's clock is refused; the log warns
once per robot whose offset exceeds ``max_clock_offset_s``.

A change seen before what the twin already holds of the element (its last applied change, or any later
sighting) is **stale**: not applied, listed in the ack's ``"stale"``.

Example::

    clock = robot_clock(memory, "robot1", obs, arrival_ns=now, rules=rules)
    refuse_future(obs, clock, now_ns=now, rules=rules)
    sense = clock.sense(obs.view.sense_ns)     # on the daemon's clock
"""

from __future__ import annotations

import datetime
import functools
import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING

from twin.config import FusionRules
from twin.errors import ObservationError
from twin.fusion.effects import sighting
from twin.fusion.memory import ClockEstimate, FusionMemory
from twin.records import ElementReport, Observation

if TYPE_CHECKING:
    from twin.fusion.context import FusionContext
    from twin.live.state import ElementState


@functools.lru_cache(maxsize=1024)  # an array's boxes share their sense time, and the held ones repeat
def when(ns: int) -> str:
    """A sense time as ISO 8601, to the millisecond (for messages and notes)."""
    return datetime.datetime.fromtimestamp(ns / 1e9, tz=datetime.UTC).isoformat(timespec="milliseconds")


log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class RobotClock:
    """One observation's robot clock: its arrival and the robot's offset (0 until known)."""

    arrival_ns: int
    offset_ns: int
    settled: bool

    def sense(self, raw_ns: int | None) -> int:
        """A sense time the robot gave, on the daemon's clock (never later than the arrival); None: the
        arrival."""
        if raw_ns is None:
            return self.arrival_ns
        return min(raw_ns + self.offset_ns, self.arrival_ns)


def robot_clock(
    memory: FusionMemory, robot: str, obs: Observation, *, arrival_ns: int, rules: FusionRules
) -> RobotClock:
    """Count this observation's sense times in ``robot``'s clock offset estimate (at once: a transport
    fact, kept whether or not the observation is accepted) and return the robot's clock."""
    raw = [r.sense_ns for r in obs.reports if r.sense_ns is not None]
    if obs.view is not None and obs.view.sense_ns is not None:
        raw.append(obs.view.sense_ns)
    estimate = memory.clocks.get(robot)
    if not raw:
        if estimate is None:
            return RobotClock(arrival_ns, 0, settled=False)
        return RobotClock(arrival_ns, estimate.offset_ns, settled=_settled(estimate, arrival_ns, rules))
    if estimate is None:
        estimate = memory.clocks[robot] = ClockEstimate()
    estimate.add(arrival_ns, arrival_ns - max(raw), window_ns=rules.clock_window_ns)
    settled = _settled(estimate, arrival_ns, rules)
    if settled and not estimate.warned and abs(estimate.offset_ns) > rules.max_clock_offset_ns:
        estimate.warned = True
        log.warning(
            "Robot %r's clock is off by about %+.3f s (behind > 0, ahead < 0; latency included): its sense "
            "times are corrected by it (more than [fusion] max_clock_offset_s = %g s; check its time sync).",
            robot,
            estimate.offset_ns / 1e9,
            rules.max_clock_offset_ns / 1e9,
        )
    return RobotClock(arrival_ns, estimate.offset_ns if settled else 0, settled=settled)


def _settled(estimate: ClockEstimate, arrival_ns: int, rules: FusionRules) -> bool:
    return arrival_ns - estimate.first_ns >= rules.clock_settle_ns


def clock_offsets(memory: FusionMemory) -> dict[str, float]:
    """Each robot's clock offset estimate, seconds (behind > 0, ahead < 0; latency included)."""
    return {robot: round(e.offset_ns / 1e9, 3) for robot, e in sorted(list(memory.clocks.items()))}


def refuse_future(obs: Observation, clock: RobotClock, *, now_ns: int, rules: FusionRules) -> None:
    """ObservationError naming a sense time more than ``max_clock_skew_s`` ahead of the daemon's clock,
    while the robot's clock offset is not known yet (once it is, sense times are corrected)."""
    if clock.settled:
        return
    raw = [r.sense_ns for r in obs.reports if r.sense_ns is not None]
    if obs.view is not None and obs.view.sense_ns is not None:
        raw.append(obs.view.sense_ns)
    for sense in raw:
        if sense > now_ns + rules.max_skew_ns:
            raise ObservationError(
                f"Observation sense time {when(sense)} is in the future: the daemon's clock says "
                f"{when(now_ns)} (allowed skew {rules.max_skew_ns / 1e9:g} s)."
            )


def seen_ns(memory: FusionMemory, iri: str) -> int:
    """The latest sense time of a sighting of ``iri`` (0: none)."""
    t = memory.tracks.get(iri)
    return 0 if t is None else t.seen_ns


def last_known(ctx: FusionContext, iri: str, state: ElementState) -> int:
    """The latest sense time the twin holds of ``iri``: its last applied change or any sighting."""
    return max(state.sensed_ns, seen_ns(ctx.memory, iri))


def stale_tombstone(ctx: FusionContext, r: ElementReport, state: ElementState | None, sense: int) -> bool:
    """A sighting of a removed element seen before its removal (or a later sighting): noted stale."""
    if state is None or not state.removed or sense >= last_known(ctx, state.iri, state):
        return False
    ctx.out.stale.append(r.iri)
    ctx.out.notes.append(f"stale: <{r.iri}> seen at {when(sense)}, removed at {when(state.sensed_ns)}")
    return True


def stale_change(
    ctx: FusionContext, r: ElementReport, reported: str, state: ElementState, sense: int
) -> bool:
    """A change of a held element seen before what the twin holds of it: counted as a sighting (never
    the latest), noted stale, not planned."""
    if sense >= last_known(ctx, state.iri, state) or not changes_something(r):
        return False
    note_stale(ctx, reported, state, sense)
    ctx.out.effects.append(sighting(state.iri, ctx.robot, sense, latest=False))
    return True


def note_stale(ctx: FusionContext, reported: str, state: ElementState, sense: int) -> None:
    """``reported`` listed in the ack's ``"stale"``, with a note of what the twin holds."""
    ctx.out.stale.append(reported)
    ctx.out.notes.append(
        f"stale: <{state.iri}> seen by {ctx.robot} at {when(sense)}, the twin holds "
        f"{when(last_known(ctx, state.iri, state))}"
    )


def changes_something(r: ElementReport) -> bool:
    """Whether the report changes geometry, removes, opens or closes, or marks a zone."""
    return (
        r.changes_geometry
        or r.removed
        or r.is_open is not None
        or r.keepout is not None
        or r.speed_limit is not None
    )
