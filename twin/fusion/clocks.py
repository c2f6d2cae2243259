"""Sense time: when a report was seen, and whether it is news.

A report's sense time is its own ``twin:senseTime``, else its view's, else its arrival. A change seen
before what the twin already holds of the element (its last applied change, or any later sighting) is
**stale**: not applied, listed in the ack's ``"stale"``.

Example::

    sense = default_sense(obs, arrival_ns)
    refuse_future(obs, sense, now_ns=now, rules=rules)
"""

from __future__ import annotations

import datetime
from typing import TYPE_CHECKING

from twin.config import FusionRules
from twin.errors import ObservationError
from twin.fusion.effects import sighting
from twin.fusion.memory import FusionMemory
from twin.records import ElementReport, Observation

if TYPE_CHECKING:
    from twin.fusion.context import FusionContext
    from twin.live.state import ElementState


def when(ns: int) -> str:
    """A sense time as ISO 8601, to the millisecond (for messages and notes)."""
    return datetime.datetime.fromtimestamp(ns / 1e9, tz=datetime.UTC).isoformat(timespec="milliseconds")


def default_sense(obs: Observation, arrival_ns: int) -> int:
    """The sense time of the reports that carry none: the view's, else the arrival."""
    view = obs.view
    return view.sense_ns if view is not None and view.sense_ns is not None else arrival_ns


def refuse_future(obs: Observation, default: int, *, now_ns: int, rules: FusionRules) -> None:
    """ObservationError naming a sense time more than ``max_clock_skew_s`` ahead of the daemon's clock."""
    for sense in [r.sense_ns for r in obs.reports if r.sense_ns is not None] + [default]:
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
    last = last_known(ctx, state.iri, state)
    if sense >= last or not changes_something(r):
        return False
    ctx.out.stale.append(reported)
    ctx.out.notes.append(
        f"stale: <{state.iri}> seen by {ctx.robot} at {when(sense)}, the twin holds {when(last)}"
    )
    ctx.out.effects.append(sighting(state.iri, ctx.robot, sense, latest=False))
    return True


def changes_something(r: ElementReport) -> bool:
    """Whether the report changes geometry, removes, opens or closes, or marks a zone."""
    return (
        r.changes_geometry
        or r.removed
        or r.is_open is not None
        or r.keepout is not None
        or r.speed_limit is not None
    )
