"""Confirmation or move: what a sighting of a held element says about where it stands.

A box within the class's confirmation distance and angle of the held pose confirms it: nothing is
written; the confirmations are averaged in memory and their mean is committed only past a hysteresis
(``refine_after``, ``refine_fraction``). A sighting farther than ``certain_move_m`` moves the element at
once; a shorter move is held until ``move_sightings`` sightings agree on it (a detector's outlier is
no move), and is applied at their mean.

Example::

    if confirms(class_rules, seen, held, sizes=True):
        r = confirmation(ctx, r, state, seen=seen, held=held, storey=storey)
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from twin.config import FusionRules
from twin.config.fusion import FusionClassRules
from twin.fusion.clocks import changes_something
from twin.fusion.effects import hold_move, refine, reset_refinement
from twin.fusion.footprints import Pose, aligned, centre_distance, yaw_difference
from twin.fusion.memory import Refinement, Track
from twin.records import ElementReport, ObservedBox

if TYPE_CHECKING:
    from twin.fusion.context import FusionContext
    from twin.live.state import ElementState, StoreyFrame


def confirms(rules: FusionClassRules, seen: Pose, held: Pose, *, sizes: bool, fraction: float = 1.0) -> bool:
    """``seen`` is within (``fraction`` of) the confirmation distance and angle of ``held`` (and, with
    ``sizes``, its sizes within the distance of the held ones)."""
    d = rules.confirm_distance_m * fraction
    if centre_distance(seen, held) > d or abs(seen.cz - held.cz) > d:
        return False
    if yaw_difference(seen, held) > rules.confirm_angle_rad * fraction:
        return False
    return not sizes or (
        abs(seen.sx - held.sx) <= d and abs(seen.sy - held.sy) <= d and abs(seen.sz - held.sz) <= d
    )


def far(rules: FusionRules, seen: Pose, held: Pose) -> bool:
    """A sighting farther than ``certain_move_m``: a move, at once."""
    return centre_distance(seen, held) > rules.certain_move_m


def unsure_move(
    rules: FusionRules,
    class_rules: FusionClassRules,
    seen: Pose,
    held: Pose,
    track: Track | None,
    *,
    sizes: bool,
) -> bool:
    """A move shorter than ``certain_move_m`` that fewer than ``move_sightings`` sightings agree on
    (each within the confirmation distance and angle of their mean)."""
    if rules.move_sightings <= 1 or far(rules, seen, held):
        return False
    return agreeing(class_rules, seen, held, track, sizes=sizes) + 1 < rules.move_sightings


def agreeing(
    class_rules: FusionClassRules, seen: Pose, held: Pose, track: Track | None, *, sizes: bool
) -> int:
    """How many held sightings of a move ``seen`` agrees with (0: it starts a new one)."""
    moving = track.moving if track is not None else None
    if moving is None or moving.n == 0:
        return 0
    return moving.n if confirms(class_rules, aligned(seen, held), moving.mean(), sizes=sizes) else 0


def mean_with(refinement: Refinement, pose: Pose) -> Pose:
    """The mean of ``refinement``'s sightings and ``pose`` (the held sums are left as they are)."""
    copy = refinement.copy()
    copy.add(pose)
    return copy.mean()


def box_of(p: Pose, elevation: float) -> ObservedBox:
    """A world pose as a report's box (``cz`` above the storey's ``elevation``)."""
    return ObservedBox(p.cx, p.cy, p.cz - elevation, p.sx, p.sy, p.sz, p.yaw)


def only_sighting(r: ElementReport, state: ElementState) -> bool:
    """Nothing in ``r`` but what the element already is (its class), once its box confirmed it."""
    return (
        not changes_something(r)
        and not r.labels
        and not r.materials
        and not r.classes
        and r.storey is None
        and not r.unmerge
        and (
            r.ifc_class is None
            or r.ifc_class in state.ifc_types
            or r.ifc_class.lower() == state.ifc_class.lower()
        )
    )


def confirmation(
    ctx: FusionContext, r: ElementReport, state: ElementState, *, seen: Pose, held: Pose, storey: StoreyFrame
) -> ElementReport | None:
    """A sighting that confirms the held pose: averaged in memory, or the mean committed once it is past
    the hysteresis. Returns what is left to plan (None: nothing, the element was only seen)."""
    rules, target = ctx.rules, state.iri
    class_rules = rules.of(state.ifc_types)
    sizes = ctx.is_box_element(target)
    track = ctx.memory.tracks.get(target)
    refinement = track.refinement if track is not None else None
    sighted = aligned(seen, held)
    mean = None
    if refinement is not None and refinement.n + 1 >= rules.refine_after:
        mean = mean_with(refinement, sighted)
    if mean is not None and not confirms(
        class_rules, mean, held, sizes=sizes, fraction=rules.refine_fraction
    ):
        r = replace(r, box=box_of(mean, storey.elevation_m))
        ctx.out.refined.append(target)
        ctx.out.notes.append(
            f"<{target}>: pose refined from {refinement.n + 1 if refinement else 1} sightings"
        )
        ctx.out.effects.append(reset_refinement(target))
        ctx.pend(target, storey.key, mean, r=r)
        return r
    r = replace(r, box=None, storey=None)  # where it stood: on its storey too
    ctx.out.effects.append(refine(target, sighted))
    return _unless_only_seen(ctx, r, state)


def hold(
    ctx: FusionContext, r: ElementReport, state: ElementState, seen: Pose, held: Pose
) -> ElementReport | None:
    """A short move not yet believed: held in memory with the sightings that agree with it (or as a new
    start). Returns what is left to plan (None: nothing)."""
    target = state.iri
    track = ctx.memory.tracks.get(target)
    sizes = ctx.is_box_element(target)
    agree = agreeing(ctx.rules.of(state.ifc_types), seen, held, track, sizes=sizes) > 0
    ctx.out.effects.append(hold_move(target, aligned(seen, held), restart=not agree))
    return _unless_only_seen(ctx, replace(r, box=None, storey=None), state)


def move(
    ctx: FusionContext, r: ElementReport, state: ElementState, *, seen: Pose, held: Pose, storey: StoreyFrame
) -> tuple[ElementReport, Pose]:
    """A move: at the sighting, or (a short one) at the mean of the sightings that agreed on it."""
    target = state.iri
    track = ctx.memory.tracks.get(target)
    ctx.out.effects.append(reset_refinement(target))
    if track is not None and track.moving is not None and not far(ctx.rules, seen, held):
        seen = mean_with(track.moving, aligned(seen, held))  # the sightings that agreed
        r = replace(r, box=box_of(seen, storey.elevation_m))
    return r, seen


def _unless_only_seen(ctx: FusionContext, r: ElementReport, state: ElementState) -> ElementReport | None:
    if only_sighting(r, state):
        ctx.out.seen.append(state.iri)
        return None
    return r
