"""Absence: what a view should have seen and did not.

An observation's view (``a twin:View``) names a storey, the floor its sensor saw and the classes its
detector reports. Every candidate element of those classes inside the view that the observation does
not describe gets a **miss**; ``misses_to_remove`` misses spread over ``miss_span_s`` of sense time,
from any robots and with no sighting in between, remove it, with the reason.

Whether a view should have seen an element is :func:`twin.fusion.visibility.view_sees`: its inset
footprint inside the view's polygons by area and, with the view's ``twin:origin``, visible from there
past the elements the twin holds and the boxes the observation reports.

Example::

    absence(ctx, view=obs.view, sense=sense_ns)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from twin.fusion.clocks import when
from twin.fusion.effects import forget, miss
from twin.fusion.footprints import Pose, heights_overlap
from twin.fusion.gates import compatible, is_candidate, kinds_agree, lies_within
from twin.fusion.memory import Miss
from twin.fusion.merge import fold, merge, one_object
from twin.fusion.visibility import view_sees
from twin.records import ElementReport, ObservedView

if TYPE_CHECKING:
    from twin.fusion.context import FusionContext
    from twin.live.state import ElementState

VIEW_INSET_M = 0.1
"""An element is in a view when its footprint, this much smaller on each side, is: a view's edge stops
at the walls, so an object against a wall is never wholly inside one."""


def covered(ctx: FusionContext, storey: str, pose: Pose, state: ElementState) -> bool:
    """Whether a box of this observation, of the element's class and kind, covers its footprint."""
    schema = ctx.live.site.schema
    margin = ctx.rules.of(state.ifc_types).confirm_distance_m
    return any(
        s == storey
        and compatible(schema, r.ifc_class or state.ifc_class, state)
        and kinds_agree(schema, r.classes, r.ifc_class, state)
        and heights_overlap(box, pose)
        and lies_within(pose, box, margin_m=margin)
        for s, r, box in ctx.boxes
    )


def covered_by_another(
    ctx: FusionContext, storey: str, iri: str, pose: Pose, state: ElementState
) -> str | None:
    """The element a box of this observation that covers ``iri``'s footprint is a sighting of, when the
    two are one object (:func:`twin.fusion.merge.one_object`): then ``iri`` is a second element of what
    the robot saw as one, not a neighbour under a box over both. An element imported from IFC is never
    merged into a robot's here, nor an element marked distinct."""
    memory, out = ctx.memory, ctx.out
    base = ctx.base_iri
    if iri in memory.distinct or (base and iri.startswith(base)):
        return None
    schema = ctx.live.site.schema
    margin = ctx.rules.of(state.ifc_types).confirm_distance_m
    for s, r, box in ctx.boxes:
        kept = out.resolved.get(r.iri, r.iri)
        kept = out.merged.get(kept, kept)
        if s != storey or kept == iri or kept not in ctx.detected or kept in memory.distinct:
            continue
        if not (
            compatible(schema, r.ifc_class or state.ifc_class, state)
            and kinds_agree(schema, r.classes, r.ifc_class, state)
            and heights_overlap(box, pose)
            and lies_within(pose, box, margin_m=margin)
        ):
            continue
        pending = ctx.pending.get(kept)
        other = ctx.states.get(kept) or (pending[2] if pending is not None else None)
        held = ctx.held_pose(kept)
        if (
            other is not None
            and held is not None
            and is_candidate(other)
            and one_object(ctx, other, held, state, pose)
        ):
            return kept
    return None


def absence(ctx: FusionContext, *, view: ObservedView, sense: int) -> None:
    """Count a miss for every element the view should have seen and the observation does not describe;
    plan the removal of those with enough misses."""
    out, memory = ctx.out, ctx.memory
    schema = ctx.live.site.schema
    storey = view.storey
    ring = np.concatenate(view.polygons)
    lo, hi = np.minimum.reduce(ring), np.maximum.reduce(ring)  # (ring.min(axis=0), without the wrapper)
    if view.origin is not None:  # what may stand between the sensor and the floor it saw
        lo, hi = np.minimum(lo, view.origin[:2]), np.maximum(hi, view.origin[:2])
    held = ctx.candidates_near(storey, lo, hi)  # view_sees looks at no other (the same in its order)
    looked: list[tuple[str, Pose, ElementState]] = []
    for iri, pose in held.items():
        if iri in ctx.detected or iri in out.merged:
            continue
        state = ctx.states.get(iri)
        if state is None or not is_candidate(state):
            continue
        if not any(compatible(schema, d, state) for d in view.detects):  # kinds agree, as in association
            continue
        looked.append((iri, pose, state))
    if not looked:
        return
    visible = view_sees(
        view,
        [pose for _, pose, _ in looked],
        iris=[iri for iri, _, _ in looked],
        held=held,
        sightings=[box for _, _, box in ctx.boxes],
        elevation_m=ctx.live.site.storeys[storey].elevation_m,
        inset_m=VIEW_INSET_M,
    )
    for (iri, pose, state), seen in zip(looked, visible, strict=True):
        if not seen:
            continue
        if covered(ctx, storey, pose, state):
            kept = covered_by_another(ctx, storey, iri, pose, state)
            if kept is not None:  # the box is another element of the same object: one element of it
                removal, extra = merge(ctx, iri, kept, sense=sense)
                ctx.reports.append(removal)
                fold(ctx, extra, sense=sense)  # what it knew and the one kept lacks
            continue  # else a box over it and its neighbours (two desks pushed together seen as one)
        track = memory.tracks.get(iri)
        if sense <= max(state.sensed_ns, track.seen_ns if track is not None else 0):
            continue  # seen (or changed) at or after this view
        rules = ctx.rules.of(state.ifc_types)
        misses = [*(track.misses if track is not None else []), Miss(ctx.robot, sense)]
        span = max(m.sense_ns for m in misses) - min(m.sense_ns for m in misses)
        if len(misses) >= rules.misses_to_remove and span >= rules.miss_span_ns:
            robots = ", ".join(sorted({m.robot for m in misses}))
            out.reasons[iri] = (
                f"absent: not seen in {len(misses)} views by {robots} "
                f"between {when(min(m.sense_ns for m in misses))} and {when(sense)}"
            )
            out.notes.append(f"<{iri}> removed: {out.reasons[iri]}")
            out.sense[iri] = sense
            ctx.reports.append(ElementReport(iri, removed=True))
            out.effects.append(forget(iri))
        else:
            out.effects.append(miss(iri, ctx.robot, sense))
            ctx.decide(iri, f"absence: miss {len(misses)} of misses_to_remove, by {ctx.robot}'s view")
