"""Late news: a first sighting that arrives after the element it saw has moved or gone.

The twin keeps each element's previous poses and the sense times of the changes that ended them
(:attr:`~twin.fusion.memory.FusionMemory.history`, a few per element, a removed element's last pose
too). A robot IRI nothing current matches, seen before such a change and matching the element's pose of
that time (the gates of association), is that element seen late: it becomes an alias of it and is acked
stale; nothing is created (no ghost at the old place).

Example::

    element = late_news(ctx, r, pose, "ground-floor", sense_ns)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from twin.fusion.clocks import when
from twin.fusion.effects import set_alias, sighting
from twin.fusion.footprints import Pose, centre_distance
from twin.fusion.gates import compatible, kinds_agree, matches, sizes_agree
from twin.records import ElementReport

if TYPE_CHECKING:
    from twin.fusion.context import FusionContext
    from twin.live.state import ElementState


def late_news(ctx: FusionContext, r: ElementReport, pose: Pose, storey: str, sense: int) -> str | None:
    """The element ``r`` saw where it stood before a later change (moved or removed), if any: the best
    match among the past poses that held after ``sense``."""
    schema = ctx.live.site.schema
    best, best_score = None, 0.0
    for iri, past in ctx.memory.history.items():
        state = ctx.states.get(iri)
        if state is None or state.is_static or iri in ctx.used:
            continue
        if not compatible(schema, r.ifc_class or "", state) or not kinds_agree(
            schema, r.classes, r.ifc_class, state
        ):
            continue
        rules = ctx.rules.of(state.ifc_types)
        for p in past:
            if p.storey != storey or p.until_ns <= ctx.earliest(sense):
                continue
            score = matches(rules, pose, p.pose)
            if score > best_score and sizes_agree(rules, pose, p.pose):
                best, best_score = iri, score
    return best


def seen_late(ctx: FusionContext, r: ElementReport, element: str, sense: int) -> None:
    """``r`` is ``element`` seen before its last change: an alias of it, acked stale, nothing planned."""
    out = ctx.out
    out.stale.append(r.iri)
    out.resolved[r.iri] = element
    out.aliases[r.iri] = element
    out.effects.append(set_alias(r.iri, element, ctx.arrival_ns))
    out.effects.append(sighting(element, ctx.robot, sense, latest=False))
    ctx.used.add(element)
    ctx.decide(element, f"late news: {r.iri} by {ctx.robot}, seen where it stood before its last change")
    out.notes.append(
        f"stale: <{r.iri}> seen by {ctx.robot} at {when(sense)} is <{element}> where it stood before its "
        "last change (late news)"
    )


def echo(ctx: FusionContext, state: ElementState, pose: Pose, sense: int) -> bool:
    """Whether a report of an element puts it back where it stood before a change that came after the
    report may have been seen (:meth:`~twin.fusion.context.FusionContext.earliest`): late news of its
    old place (a report delayed on the way, or a robot whose lateness looks like a clock behind), not a
    move back."""
    past = ctx.memory.history.get(state.iri)
    if not past:
        return False
    held = ctx.held_pose(state.iri)
    rules = ctx.rules.of(state.ifc_types)
    earliest = ctx.earliest(sense)
    for p in past:
        if p.until_ns <= earliest or matches(rules, pose, p.pose) <= 0.0:
            continue
        if held is None or centre_distance(pose, p.pose) < centre_distance(pose, held):
            return True
    return False


def seen_echo(ctx: FusionContext, r: ElementReport, state: ElementState, sense: int) -> None:
    """``r`` is late news of where ``state`` stood before its last change: stale, nothing planned."""
    ctx.out.stale.append(r.iri)
    ctx.out.effects.append(sighting(state.iri, ctx.robot, sense, latest=False))
    ctx.decide(state.iri, f"late news: {ctx.robot} saw it where it stood before its last change")
    ctx.out.notes.append(
        f"stale: <{r.iri}> by {ctx.robot} puts <{state.iri}> back where it stood before its last change"
    )
