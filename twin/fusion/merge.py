"""Merge: an element moved onto another of a compatible class is that other element.

The one moved is removed (``twin:mergedInto``, ``twin:removedBecause``) and its IRI and aliases resolve
to the one kept; an element imported from IFC is kept over a robot's. The one kept gains what the one
removed knew and it lacks: labels, materials (each a facing one too, as a robot's reported materials
are) and descriptive types of its kind (:func:`carried`), when the robot may change it.
``twin:distinct`` elements are never merged; an operator's ``twin:unmerge`` makes a merged IRI an
element of its own again.

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
from twin.fusion.gates import compatible, descriptive_types, is_candidate, kinds_agree, sizes_agree
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
    removal, extra = merge(ctx, target, other, sense=sense)
    ctx.reports.append(removal)
    r = replace(r, iri=other, ifc_class=None, classes=())
    if extra is not None:
        r = joined(r, extra)
    ctx.detected.add(other)
    ctx.used.add(other)
    o_held = ctx.held_pose(other)
    if o_held is not None and confirms(ctx.rules.of(ctx.states[other].ifc_types), pose, o_held, sizes=False):
        r = replace(r, box=None, storey=None)
    return r


def merge(
    ctx: FusionContext, gone: str, kept: str, *, sense: int
) -> tuple[ElementReport, ElementReport | None]:
    """``gone`` is ``kept``: its IRI and aliases resolve to ``kept``; returns its removal to plan, and
    what ``kept`` gains from it (:func:`carried`) to plan with ``kept``'s report (:func:`fold`)."""
    out = ctx.out
    extra, carry = carried(ctx, gone, kept)
    out.merged[gone] = kept
    ctx.decide(kept, f"merge: <{gone}> merged into it{carry}")
    out.reasons[gone] = f"merged into <{kept}>: seen by {ctx.robot} at {when(sense)} where <{kept}> stands"
    out.notes.append(f"<{gone}> merged into <{kept}>{carry}")
    out.sense[gone] = sense
    out.aliases[gone] = kept
    out.effects.append(set_alias(gone, kept, sense))
    for alias in ctx.memory.aliases_of(gone):
        out.aliases[alias] = kept
        out.effects.append(set_alias(alias, kept, sense))
    out.resolved[gone] = kept
    ctx.pending.pop(gone, None)
    out.effects.append(forget(gone))
    return ElementReport(gone, removed=True), extra


def carried(ctx: FusionContext, gone: str, kept: str) -> tuple[ElementReport | None, str]:
    """What ``kept`` gains from ``gone`` merged into it: ``gone``'s labels, its facing materials and its
    descriptive types (``a furn:Table``; only when the two kinds agree) that ``kept`` lacks, as a report
    of ``kept`` (None: nothing to carry); and a note of it for the event log ("" when nothing). Nothing
    is carried when the robot may not change ``kept`` (the merge stands; the note says so)."""
    was, state = ctx.states.get(gone), _state(ctx, kept)
    if was is None or state is None:
        return None, ""
    schema = ctx.live.site.schema
    labels = tuple(sorted(was.labels - state.labels))
    materials = tuple(  # as plan._descriptive writes a reported one: a material and a facing one
        sorted(
            m
            for m in was.facing_materials & was.materials
            if m not in state.materials or m not in state.facing_materials
        )
    )
    classes: tuple[str, ...] = ()
    if kinds_agree(schema, tuple(was.classes), was.ifc_class, state):
        classes = tuple(sorted(descriptive_types(schema, was.classes, was.ifc_class) - state.classes))
    if not (labels or materials or classes):
        return None, ""
    right = state.change_right
    held = kept in ctx.states and not state.removed  # else created by this observation: no change right
    if held and right not in ctx.rights:
        skipped = f"its labels, materials and types not carried over: {ctx.robot} lacks the {right!r} right"
        return None, f" ({skipped})"
    what = ", ".join(
        f"{len(v)} {name}{'' if len(v) == 1 else 's'}"
        for v, name in ((labels, "label"), (materials, "material"), (classes, "type"))
        if v
    )
    extra = ElementReport(kept, labels=labels, materials=materials, classes=classes)
    return extra, f" (carried over: {what})"


def _state(ctx: FusionContext, iri: str) -> ElementState | None:
    """``iri``'s state as the batch left it, or as this observation creates or moves it."""
    pending = ctx.pending.get(iri)
    return ctx.states.get(iri) or (pending[2] if pending is not None else None)


def joined(r: ElementReport, extra: ElementReport) -> ElementReport:
    """``r`` with ``extra``'s labels, materials and types too (``r``'s first)."""
    return replace(
        r,
        labels=tuple(dict.fromkeys((*r.labels, *extra.labels))),
        materials=tuple(dict.fromkeys((*r.materials, *extra.materials))),
        classes=tuple(dict.fromkeys((*r.classes, *extra.classes))),
    )


def fold(ctx: FusionContext, extra: ElementReport | None, *, sense: int) -> None:
    """Plan ``extra`` with the report this observation already plans for its element (one report per
    element: the plan checks each against the twin as it was), or on its own."""
    if extra is None:
        return
    for i in range(len(ctx.reports) - 1, -1, -1):
        if ctx.reports[i].iri == extra.iri:
            if not ctx.reports[i].removed:
                ctx.reports[i] = joined(ctx.reports[i], extra)
            return
    ctx.reports.append(extra)
    ctx.out.sense[extra.iri] = sense


def unmerge(ctx: FusionContext, r: ElementReport, sense: int) -> None:
    """An operator's ``twin:unmerge``: the IRI is its own element again (planned as given)."""
    was = ctx.memory.aliases.get(r.iri)
    ctx.reports.append(r)
    ctx.out.sense[r.iri] = sense
    ctx.out.effects.append(drop_alias(r.iri))
    ctx.out.unaliased.append(r.iri)
    ctx.out.notes.append(f"<{r.iri}> is its own element again (unmerged from <{was.target if was else '?'}>)")
