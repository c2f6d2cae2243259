"""Merge: an element moved onto another of a compatible class is that other element.

The one moved is removed (``twin:mergedInto``, ``twin:removedBecause``) and its IRI and aliases resolve
to the one kept; an element imported from IFC is kept over a robot's. ``twin:distinct`` elements are
never merged; an operator's ``twin:unmerge`` makes a merged IRI an element of its own again.

Example::

    r = merge_or_move(ctx, r, state, pose, "ground-floor", sense=sense_ns)
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

from twin.fusion.clocks import when
from twin.fusion.confirm import confirms
from twin.fusion.effects import drop_alias, forget, set_alias
from twin.fusion.footprints import Pose, heights_overlap, iou
from twin.fusion.gates import compatible, is_candidate, kinds_agree, sizes_agree
from twin.records import ElementReport

if TYPE_CHECKING:
    from twin.fusion.context import FusionContext
    from twin.live.state import ElementState


def one_object(ctx: FusionContext, state: ElementState, pose: Pose, other: ElementState, held: Pose) -> bool:
    """Whether the element ``state`` at ``pose`` and ``other`` at ``held`` are one object: a compatible
    class (either way), kind and size, heights that overlap and footprints that overlap by ``merge_iou``
    (both candidates: dynamic, not zones)."""
    schema = ctx.live.site.schema
    if not (compatible(schema, state.ifc_class, other) or compatible(schema, other.ifc_class, state)):
        return False
    if not kinds_agree(schema, tuple(state.classes), state.ifc_class, other):
        return False  # a chair moved under a table stays a chair
    if not sizes_agree(ctx.rules.of(other.ifc_types), pose, held):
        return False  # a box over two desks is neither
    return heights_overlap(pose, held) and iou(pose, held) >= ctx.rules.merge_iou


def merge_target(ctx: FusionContext, iri: str, state: ElementState, pose: Pose, storey: str) -> str | None:
    """Another element this one overlaps so much after its move that they are one object."""
    if iri in ctx.memory.distinct:
        return None
    cx, cy, own = pose.cx, pose.cy, math.hypot(pose.sx, pose.sy) / 2
    for other, held in ctx.candidates(storey).items():
        # footprints that cannot meet (centres farther apart than their half-diagonals) first: the
        # IoU below would be 0, and the gates before it cost far more than this
        if (
            abs(held.cx - cx) > own + (held.sx + held.sy) / 2
            or abs(held.cy - cy) > own + (held.sx + held.sy) / 2
        ):
            continue
        if other == iri or other in ctx.used or other in ctx.memory.distinct:
            continue
        o_state = ctx.states.get(other)
        if o_state is not None and is_candidate(o_state) and one_object(ctx, state, pose, o_state, held):
            return other
    return None


def merge_or_move(
    ctx: FusionContext, r: ElementReport, state: ElementState, pose: Pose, storey: str, *, sense: int
) -> ElementReport:
    """``r`` moves its element to ``pose``; onto another element, the two merge (the moved one's removal
    is planned, and ``r`` becomes a sighting of the one kept). Returns the report to plan."""
    target = state.iri
    other = merge_target(ctx, target, state, pose, storey)
    if other is None or (target.startswith(ctx.base_iri) and not other.startswith(ctx.base_iri)):
        ctx.pend(target, storey, pose, r=r)
        return r
    ctx.reports.append(merge(ctx, target, other, sense=sense))
    r = replace(r, iri=other, ifc_class=None, classes=())
    ctx.detected.add(other)
    ctx.used.add(other)
    o_held = ctx.held_pose(other)
    if o_held is not None and confirms(ctx.rules.of(ctx.states[other].ifc_types), pose, o_held, sizes=False):
        r = replace(r, box=None, storey=None)
    return r


def merge(ctx: FusionContext, gone: str, kept: str, *, sense: int) -> ElementReport:
    """``gone`` is ``kept``: its IRI and aliases resolve to ``kept``; returns its removal to plan."""
    out = ctx.out
    out.merged[gone] = kept
    ctx.decide(kept, f"merge: <{gone}> merged into it")
    out.reasons[gone] = f"merged into <{kept}>: seen by {ctx.robot} at {when(sense)} where <{kept}> stands"
    out.notes.append(f"<{gone}> merged into <{kept}>")
    out.sense[gone] = sense
    out.aliases[gone] = kept
    out.effects.append(set_alias(gone, kept, sense))
    for alias in ctx.memory.aliases_of(gone):
        out.aliases[alias] = kept
        out.effects.append(set_alias(alias, kept, sense))
    out.resolved[gone] = kept
    ctx.pending.pop(gone, None)
    out.effects.append(forget(gone))
    return ElementReport(gone, removed=True)


def unmerge(ctx: FusionContext, r: ElementReport, sense: int) -> None:
    """An operator's ``twin:unmerge``: the IRI is its own element again (planned as given)."""
    was = ctx.memory.aliases.get(r.iri)
    ctx.reports.append(r)
    ctx.out.sense[r.iri] = sense
    ctx.out.effects.append(drop_alias(r.iri))
    ctx.out.unaliased.append(r.iri)
    ctx.out.notes.append(f"<{r.iri}> is its own element again (unmerged from <{was.target if was else '?'}>)")
