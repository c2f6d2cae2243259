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

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from twin.config import FusionRules
from twin.config.fusion import FusionClassRules
from twin.fusion.clocks import changes_something
from twin.fusion.effects import confirmed_by, hold_move, moved, refine, reset_refinement, size_evidence
from twin.fusion.footprints import Pose, aligned, box_pose, centre_distance, yaw_difference
from twin.fusion.memory import Refinement, SizeEvidence, Track
from twin.records import ElementReport, ObservedBox

if TYPE_CHECKING:
    from twin.fusion.context import FusionContext
    from twin.live.state import ElementState, StoreyFrame

Sizes = tuple[float, float, float]
"""An element's sizes (sx >= sy, sz), metres."""

RESIZE_AGREEMENT_NS = 10 * 10**9
"""Two robots agree on new sizes when their sightings are at most this far apart (sense time)."""


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
    ctx: FusionContext,
    class_rules: FusionClassRules,
    seen: Pose,
    held: Pose,
    *,
    track: Track | None,
    sense: int,
) -> bool:
    """A move shorter than ``certain_move_m`` that fewer than ``move_sightings`` sightings of this robot
    agree on (each within the confirmation distance and angle of their mean), and that no other robot
    stands behind (its own ``move_sightings`` sightings agree with it)."""
    rules = ctx.rules
    if rules.move_sightings <= 1 or far(rules, seen, held):
        return False
    if own_run(class_rules, seen, held, track, ctx.robot) + 1 >= rules.move_sightings:
        return False
    return not standing(ctx, class_rules, seen, held, track=track, sense=sense)


def own_run(class_rules: FusionClassRules, seen: Pose, held: Pose, track: Track | None, robot: str) -> int:
    """How many of ``robot``'s latest sightings of a move ``seen`` agrees with (0: it starts a new one)."""
    run = track.runs.get(robot) if track is not None else None
    if run is None or run[0].n == 0:
        return 0
    return run[0].n if confirms(class_rules, aligned(seen, held), run[0].mean(), sizes=False) else 0


def standing(
    ctx: FusionContext,
    class_rules: FusionClassRules,
    seen: Pose,
    held: Pose,
    *,
    track: Track | None,
    sense: int,
) -> list[str]:
    """The other robots that stand behind the move ``seen`` shows: ``move_sightings`` of their own latest
    sightings agree with it, the last within ``disagreement_window_s``."""
    if track is None:
        return []
    rules = ctx.rules
    return [
        r
        for r, (ref, last) in track.runs.items()
        if r != ctx.robot
        and ref.n >= rules.move_sightings
        and sense - last <= rules.disagreement_window_ns
        and confirms(class_rules, aligned(seen, held), ref.mean(), sizes=False)
    ]


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


def only_a_box(r: ElementReport) -> bool:
    """Whether ``r`` says nothing but where the element stands (and its class): no geometry, placement,
    removal, door, zone, label, material, class or unmerge."""
    return (
        r.geometry is None
        and r.placement is None
        and not r.removed
        and r.is_open is None
        and r.keepout is None
        and r.speed_limit is None
        and not r.labels
        and not r.materials
        and not r.classes
        and not r.unmerge
    )


def only_sighting_where_it_stands(r: ElementReport, state: ElementState) -> bool:
    """:func:`only_sighting` of ``r`` without its box and storey (without making that report)."""
    c = r.ifc_class
    return only_a_box(r) and (c is None or c in state.ifc_types or c.lower() == state.ifc_class.lower())


def confirmation(
    ctx: FusionContext,
    r: ElementReport,
    state: ElementState,
    *,
    seen: Pose,
    held: Pose,
    storey: StoreyFrame,
    sense: int,
    sizes: Sizes | None = None,
) -> ElementReport | None:
    """A sighting that confirms the held pose: averaged in memory, or the mean committed once it is past
    the hysteresis (at the held sizes, or ``sizes`` once a resize is believed). Returns what is left to
    plan (None: nothing, the element was only seen)."""
    rules, target = ctx.rules, state.iri
    class_rules = rules.of(state.ifc_types)
    track = ctx.memory.tracks.get(target)
    refinement = track.refinement if track is not None else None
    sighted = aligned(seen, held)
    mean = None
    if refinement is not None and refinement.n + 1 >= rules.refine_after:
        mean = mean_with(refinement, sighted)
    if mean is not None and (
        not confirms(class_rules, mean, held, sizes=False, fraction=rules.refine_fraction)
        or centre_distance(mean, held) > rules.refine_distance_m  # a map cell off: free floor inside it
    ):
        r, at = placed(ctx, r, state, at=mean, held=held, storey=storey, sizes=sizes)
        n = refinement.n + 1 if refinement else 1
        ctx.out.refined.append(target)
        ctx.decide(target, f"refined: the mean of {n} confirmations")
        ctx.out.notes.append(f"<{target}>: pose refined from {n} sightings")
        ctx.out.effects.append(reset_refinement(target))
        ctx.pend(target, storey.key, at, r=r)
        return r
    ctx.out.effects.append(refine(target, sighted, robot=ctx.robot, sense=sense))
    ctx.decide(target, f"confirmation by {ctx.robot}: within confirm_distance_m and confirm_angle_deg")
    if sizes is not None:
        return resized(ctx, r, state, held=held, storey=storey, sizes=sizes)
    if only_sighting_where_it_stands(r, state):
        ctx.out.seen.append(state.iri)
        return None
    return replace(r, box=None, storey=None)  # where it stood: on its storey too


def hold(
    ctx: FusionContext,
    r: ElementReport,
    state: ElementState,
    *,
    seen: Pose,
    held: Pose,
    storey: StoreyFrame,
    sense: int,
    sizes: Sizes | None = None,
    why: str = "",
) -> ElementReport | None:
    """A short move not yet believed (``why``): held in memory with the sightings that agree with it (or
    as a new start), listed in the ack's ``"pending"``. Returns what is left to plan (None: nothing; a
    believed resize where it stands)."""
    target = state.iri
    ctx.out.pending.append(target)
    ctx.decide(target, f"move by {ctx.robot} held: {why}")
    track = ctx.memory.tracks.get(target)
    class_rules = ctx.rules.of(state.ifc_types)
    agree = agreeing(class_rules, seen, held, track, sizes=False) > 0
    mine = own_run(class_rules, seen, held, track, ctx.robot) > 0
    ctx.out.effects.append(
        hold_move(
            target, aligned(seen, held), restart=not agree, robot=ctx.robot, restart_run=not mine, sense=sense
        )
    )
    if sizes is not None:
        return resized(ctx, r, state, held=held, storey=storey, sizes=sizes)
    return _unless_only_seen(ctx, replace(r, box=None, storey=None), state)


def disputed(ctx: FusionContext, state: ElementState, seen: Pose, held: Pose, sense: int) -> str:
    """Whether a short move must wait ("" if not): robots whose latest sighting confirmed the held pose
    within ``disagreement_window_s`` are at least as many as the robots behind the move (this one and
    those whose own sightings agree on it): two detectors biased against each other do not flap a still
    object, and the majority decides ("held"; "tie": as many on each side, nothing says which is right:
    :mod:`twin.fusion.dispute`). Robots that confirmed it earlier than the window (their latest sighting)
    make a "tie" too when they are as many: a robot's box then covers both poses until they see it
    again (two robots passing a desk minutes apart do not move it back and forth). A move beyond
    ``certain_move_m`` never waits."""
    if far(ctx.rules, seen, held):
        return ""
    track = ctx.memory.tracks.get(state.iri)
    if track is None:
        return ""
    window = ctx.rules.disagreement_window_ns
    against = {r for r, t in track.confirmed.items() if r != ctx.robot and sense - t <= window}
    earlier = {r for r in track.confirmed if r != ctx.robot}  # their latest sighting, at any time
    if not earlier:
        return ""
    behind = {ctx.robot, *standing(ctx, ctx.rules.of(state.ifc_types), seen, held, track=track, sense=sense)}
    if not against:  # as many robots saw it where it is held, earlier: it covers both until one returns
        return "" if len(behind - earlier) > len(earlier) else "tie"
    movers = len(behind - against)
    return "" if movers > len(against) else "tie" if movers == len(against) else "held"


def move(
    ctx: FusionContext,
    r: ElementReport,
    state: ElementState,
    *,
    seen: Pose,
    held: Pose,
    storey: StoreyFrame,
    sense: int,
    sizes: Sizes | None = None,
) -> tuple[ElementReport, Pose]:
    """A move: to the sighting, or (a short one) to the mean of the sightings that agreed on it; the
    element keeps its sizes (or takes ``sizes``, a believed resize) and, unless a robot's box, its mesh.
    Returns the report to plan and the pose it gives the element."""
    target = state.iri
    track = ctx.memory.tracks.get(target)
    ctx.out.effects.append(reset_refinement(target))
    ctx.out.effects.append(moved(target))
    ctx.out.effects.append(confirmed_by(target, {ctx.robot: sense}))  # the mover sees it there
    ctx.decide(target, f"move by {ctx.robot}")
    class_rules = ctx.rules.of(state.ifc_types)
    if (
        track is not None
        and not far(ctx.rules, seen, held)
        and agreeing(class_rules, seen, held, track, sizes=False)
    ):
        assert track.moving is not None
        seen = mean_with(track.moving, aligned(seen, held))  # the sightings that agreed
    elif track is not None and not far(ctx.rules, seen, held):
        behind = set(standing(ctx, class_rules, seen, held, track=track, sense=sense))
        if own_run(class_rules, seen, held, track, ctx.robot):
            behind.add(ctx.robot)
        agreed = Refinement()
        for robot in sorted(behind):
            agreed = _summed(agreed, track.runs[robot][0])
        if agreed.n:
            seen = mean_with(agreed, aligned(seen, held))  # the sightings that agreed
    return placed(ctx, r, state, at=seen, held=held, storey=storey, sizes=sizes)


def _summed(a: Refinement, b: Refinement) -> Refinement:
    return Refinement(
        a.n + b.n, a.cx + b.cx, a.cy + b.cy, a.cz + b.cz, a.sx + b.sx, a.sy + b.sy, a.sz + b.sz, a.yaw + b.yaw
    )


def resizable(ctx: FusionContext, iri: str) -> bool:
    """Whether robots' boxes may change the element's sizes: a box a robot made (an element imported
    from IFC keeps its mesh, and so does one a robot sent as a mesh)."""
    imported = bool(ctx.base_iri) and iri.startswith(ctx.base_iri)
    return not imported and ctx.is_box_element(iri)


def placed(
    ctx: FusionContext,
    r: ElementReport,
    state: ElementState,
    *,
    at: Pose,
    held: Pose,
    storey: StoreyFrame,
    sizes: Sizes | None,
) -> tuple[ElementReport, Pose]:
    """``r`` rewritten to put the element at ``at``'s centre (x, y) and yaw, on the floor it stood on,
    at its held sizes (or ``sizes``): a box for a robot's box, a new placement (the same mesh) for any
    other element. Returns it and the element's pose after it."""
    a = aligned(at, held)
    if resizable(ctx, state.iri):
        sx, sy, sz = sizes or (held.sx, held.sy, held.sz)
        pose = box_pose(a.cx, a.cy, held.zmin + sz / 2, sx, sy, sz, yaw=a.yaw)
        return replace(r, box=box_of(pose, storey.elevation_m), storey=r.storey or storey.key), pose
    shape = ctx.shape_of(state.iri)
    assert shape is not None  # a held pose is a shape's
    turn = a.yaw - held.yaw
    c, s = math.cos(turn), math.sin(turn)
    delta = np.eye(4)
    delta[:2, :2] = [[c, -s], [s, c]]
    delta[:2, 3] = (a.cx - (c * held.cx - s * held.cy), a.cy - (s * held.cx + c * held.cy))
    placement = delta @ shape[1]
    placement = np.round(placement, 9)
    placement[:3, 3] = np.round(placement[:3, 3], 6)
    pose = box_pose(a.cx, a.cy, held.cz, held.sx, held.sy, held.sz, yaw=a.yaw)
    return replace(r, box=None, geometry=None, placement=placement), pose


def resized(
    ctx: FusionContext,
    r: ElementReport,
    state: ElementState,
    *,
    held: Pose,
    storey: StoreyFrame,
    sizes: Sizes,
) -> ElementReport:
    """A resize believed (two robots, or one robot over time, agree): the element where it stands, at
    ``sizes``."""
    r, pose = placed(ctx, r, state, at=held, held=held, storey=storey, sizes=sizes)
    ctx.decide(state.iri, "resized: two robots, or one over resize_sightings, agree on its sizes")
    ctx.out.notes.append(f"<{state.iri}>: resized to {sizes[0]:.2f} x {sizes[1]:.2f} x {sizes[2]:.2f} m")
    ctx.pend(state.iri, storey.key, pose, r=r)
    return r


def resize_evidence(
    ctx: FusionContext, state: ElementState, seen: Pose, held: Pose, sense: int
) -> Sizes | None:
    """The sizes a robot's box element takes now, if this sighting makes the evidence strong: two robots
    agree on other sizes (within the confirmation distance), or one robot over ``resize_sightings``
    sightings spanning ``resize_span_s``. Else None (the evidence is kept, or cleared by a sighting at
    the held sizes)."""
    if not resizable(ctx, state.iri):
        return None
    rules, robot, iri = ctx.rules, ctx.robot, state.iri
    d = rules.of(state.ifc_types).confirm_distance_m
    a = aligned(seen, held)
    size = (a.sx, a.sy, a.sz)
    track = ctx.memory.tracks.get(iri)
    evidence = track.sizes if track is not None else {}

    def near(other: Sizes) -> bool:
        return abs(size[0] - other[0]) <= d and abs(size[1] - other[1]) <= d and abs(size[2] - other[2]) <= d

    if near((held.sx, held.sy, held.sz)):
        if robot in evidence:
            ctx.out.effects.append(size_evidence(iri, robot, None))
        return None
    mine = evidence.get(robot)
    ev = (mine if mine is not None and near(mine.mean()) else SizeEvidence()).added(*size, sense)
    others = [
        e
        for who, e in evidence.items()
        if who != robot and near(e.mean()) and abs(sense - e.last_ns) <= RESIZE_AGREEMENT_NS
    ]
    if others or (ev.n >= rules.resize_sightings and ev.last_ns - ev.first_ns >= rules.resize_span_ns):
        n = ev.n + sum(e.n for e in others)
        mean = tuple((getattr(ev, k) + sum(getattr(e, k) for e in others)) / n for k in ("sx", "sy", "sz"))
        ctx.out.effects.append(size_evidence(iri, None, None))
        return (mean[0], mean[1], mean[2])
    ctx.out.effects.append(size_evidence(iri, robot, ev))
    ctx.out.pending.append(iri)
    return None


def _unless_only_seen(ctx: FusionContext, r: ElementReport, state: ElementState) -> ElementReport | None:
    if only_sighting(r, state):
        ctx.out.seen.append(state.iri)
        return None
    return r
