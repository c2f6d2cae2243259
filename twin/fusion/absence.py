"""Absence: what a view should have seen and did not.

An observation's view (``a twin:View``) names a storey, the floor its sensor saw and the classes its
detector reports. Every candidate element of those classes inside the view that the observation does
not describe gets a **miss**; ``misses_to_remove`` misses spread over ``miss_span_s`` of sense time,
from any robots and with no sighting in between, remove it, with the reason.

Example::

    absence(ctx, storey="ground-floor", polygons=view.polygons, detects=view.detects, sense=sense_ns)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from twin.fusion.clocks import when
from twin.fusion.effects import forget, miss
from twin.fusion.footprints import Pose, corners, heights_overlap, inside
from twin.fusion.gates import compatible, is_candidate, kinds_agree, lies_within
from twin.fusion.memory import Miss
from twin.records import ElementReport

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


def absence(
    ctx: FusionContext, *, storey: str, polygons: tuple[object, ...], detects: tuple[str, ...], sense: int
) -> None:
    """Count a miss for every element the view should have seen and the observation does not describe;
    plan the removal of those with enough misses."""
    out, memory = ctx.out, ctx.memory
    schema = ctx.live.site.schema
    for iri, pose in ctx.candidates(storey).items():
        if iri in ctx.detected or iri in out.merged:
            continue
        state = ctx.states.get(iri)
        if state is None or not is_candidate(state):
            continue
        if not any(compatible(schema, d, state) for d in detects):  # kinds agree, as in association
            continue
        if not inside(corners(pose, inset=VIEW_INSET_M), polygons):  # type: ignore[arg-type]
            continue
        if covered(ctx, storey, pose, state):
            continue  # a box over it and its neighbours (two desks pushed together seen as one)
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
