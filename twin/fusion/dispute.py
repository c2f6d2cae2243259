"""Robots that disagree: while nothing says which pose is right, the element covers both.

A short move that robots stand behind (``move_sightings`` agreeing sightings) while as many others
confirmed the held pose within ``disagreement_window_s`` is disputed (:func:`twin.fusion.confirm.disputed`).
Two robots whose detectors differ by 20 cm, one of them the only other witness, cannot be told apart
until a third robot or the detector bias (:mod:`twin.fusion.bias`) settles it; whichever pose the twin
held, the navigation map would show free floor where the object may stand. So a robot's box element
**covers both poses** (:func:`widen`: one box around both footprints, in the held pose's frame) and each
later sighting takes a side (:func:`covered`; a robot changes sides once ``move_sightings`` of its
sightings in a row confirm the other pose: one noisy sighting nearer the other pose is no change of
mind); once the robots that take one side outnumber those on the other (a third robot, or a biased
robot corrected), the element is put at that side's pose, at its own sizes. A sighting far from both
(beyond ``certain_move_m``) is a move. An element imported from IFC, or a robot's mesh, keeps its
shape: its move is held as before.

Example::

    if disputed(ctx, state, seen, held, sense) == "tie" and resizable(ctx, state.iri):
        r = widen(ctx, r, state, seen=seen, held=held, storey=storey, sense=sense)
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from twin.fusion.clocks import last_known
from twin.fusion.confirm import (
    confirms,
    far,
    mean_with,
    move,
    only_sighting,
    only_sighting_where_it_stands,
    own_run,
    placed,
    standing,
)
from twin.fusion.effects import (
    confirmed_by,
    disputed_poses,
    leans,
    moved,
    reset_refinement,
    size_evidence,
    took_side,
)
from twin.fusion.footprints import Pose, aligned, box_pose, centre_distance, corners
from twin.fusion.memory import Dispute, Refinement
from twin.fusion.merge import merge_or_move
from twin.records import ElementReport

if TYPE_CHECKING:
    from twin.fusion.context import FusionContext
    from twin.live.state import ElementState, StoreyFrame


def covering(a: Pose, b: Pose) -> Pose:
    """The upright box around both footprints and heights, its sides along ``a``'s."""
    c, s = math.cos(a.yaw), math.sin(a.yaw)
    pts = np.vstack([corners(a), corners(b)]) - (a.cx, a.cy)
    u, v = pts @ (c, s), pts @ (-s, c)
    cu, cv = (u.min() + u.max()) / 2, (v.min() + v.max()) / 2
    zmin, zmax = min(a.zmin, b.zmin), max(a.zmax, b.zmax)
    return box_pose(
        a.cx + cu * c - cv * s,
        a.cy + cu * s + cv * c,
        (zmin + zmax) / 2,
        float(u.max() - u.min()),
        float(v.max() - v.min()),
        zmax - zmin,
        yaw=a.yaw,
    )


def still_covers(dispute: Dispute | None, held: Pose) -> bool:
    """Whether the element still stands as the cover of ``dispute``'s poses (a mesh or an operator's box
    written since ends the dispute)."""
    if dispute is None:
        return False
    cover = covering(*dispute.poses)
    return (
        centre_distance(cover, held) < 0.01
        and abs(cover.sx - held.sx) < 0.01
        and abs(cover.sy - held.sy) < 0.01
    )


def older_disagreement(  # noqa: PLR0917 (the report as the rules see it)
    ctx: FusionContext, r: ElementReport, state: ElementState, seen: Pose, held: Pose, sense: int
) -> bool:
    """Whether ``r``, which puts the element a short move (not beyond ``certain_move_m``) from the held
    pose and nothing else, was seen after the element's last applied change but before another robot's
    later sighting of it: robots that disagree on where a still object stands, not old news. Such a
    report takes part in the dispute (held, or the element covers both poses) and is never applied as
    a move; otherwise it would be stale, and a robot whose reports arrive late (its sense times
    corrected to about their arrival, a few tenths of a second earlier than a streaming robot's latest
    sighting) would never be heard against a biased robot that watches the object."""
    if not ctx.rules.enabled or sense < state.sensed_ns or sense >= last_known(ctx, state.iri, state):
        return False
    if not only_sighting_where_it_stands(r, state):
        return False  # a removal, a door, a zone, a mesh: stale as any change
    class_rules = ctx.rules.of(state.ifc_types)
    if far(ctx.rules, seen, held) or confirms(class_rules, seen, held, sizes=False):
        return False
    track = ctx.memory.tracks.get(state.iri)
    return track is None or not still_covers(track.dispute, held)


def _behind(
    ctx: FusionContext, state: ElementState, seen: Pose, held: Pose, sense: int
) -> tuple[set[str], Pose]:
    """The robots behind the move ``seen`` shows and the mean of their agreeing sightings with it."""
    track = ctx.memory.tracks.get(state.iri)
    class_rules = ctx.rules.of(state.ifc_types)
    behind = {ctx.robot, *standing(ctx, class_rules, seen, held, track=track, sense=sense)}
    agreed = Refinement()
    if track is not None:
        mine = own_run(class_rules, seen, held, track, ctx.robot) > 0
        for robot in sorted(behind):
            run = track.runs.get(robot)
            if run is not None and (robot != ctx.robot or mine):
                ref = run[0]
                agreed = Refinement(
                    agreed.n + ref.n,
                    agreed.cx + ref.cx,
                    agreed.cy + ref.cy,
                    agreed.cz + ref.cz,
                    agreed.sx + ref.sx,
                    agreed.sy + ref.sy,
                    agreed.sz + ref.sz,
                    agreed.yaw + ref.yaw,
                )
    return behind, mean_with(agreed, aligned(seen, held))


def widen(
    ctx: FusionContext,
    r: ElementReport,
    state: ElementState,
    *,
    seen: Pose,
    held: Pose,
    storey: StoreyFrame,
    sense: int,
) -> ElementReport:
    """A disputed short move of a robot's box element: the element covers the held pose and the one the
    robots behind the move saw (listed in the ack's ``"pending"``)."""
    target = state.iri
    track = ctx.memory.tracks.get(target)
    behind, other = _behind(ctx, state, seen, held, sense)
    other = replace(other, sx=held.sx, sy=held.sy, sz=held.sz)  # the sizes are not disputed
    cover = covering(held, other)
    sides = {  # the robots whose latest sighting confirmed the held pose, at any time
        robot: (0, t)
        for robot, t in (track.confirmed.items() if track is not None else ())
        if robot not in behind
    }
    sides.update({robot: (1, sense) for robot in behind})
    r, pose = placed(ctx, r, state, at=cover, held=held, storey=storey, sizes=(cover.sx, cover.sy, cover.sz))
    ctx.out.pending.append(target)
    ctx.out.effects.append(reset_refinement(target))
    ctx.out.effects.append(size_evidence(target, None, None))
    ctx.out.effects.append(disputed_poses(target, Dispute((held, other), sides)))
    ctx.decide(
        target, f"disputed: {', '.join(sorted(behind))} against {', '.join(sorted(sides.keys() - behind))}"
    )
    ctx.out.notes.append(f"<{target}>: robots disagree on where it stands; it covers both poses")
    ctx.pend(target, storey.key, pose, r=r)
    return r


def covered(
    ctx: FusionContext,
    r: ElementReport,
    state: ElementState,
    *,
    seen: Pose,
    held: Pose,
    storey: StoreyFrame,
    sense: int,
) -> ElementReport | None:
    """A sighting of an element that covers two disputed poses (``held``: the cover): it takes a side;
    once one side's robots outnumber the other's, the element is put at that side's pose (a sighting
    far from both is a move). Returns what is left to plan (None: nothing)."""
    target = state.iri
    track = ctx.memory.tracks.get(target)
    assert track is not None and track.dispute is not None
    dispute = track.dispute
    class_rules = ctx.rules.of(state.ifc_types)
    near = [
        (centre_distance(seen, p), i)
        for i, p in enumerate(dispute.poses)
        if confirms(class_rules, seen, p, sizes=False)
    ]
    side = min(near)[1] if near else None
    if side is None:
        if any(far(ctx.rules, seen, p) for p in dispute.poses):  # neither: the object moved
            a = dispute.poses[0]
            r, pose = move(
                ctx, r, state, seen=seen, held=held, storey=storey, sense=sense, sizes=(a.sx, a.sy, a.sz)
            )
            return merge_or_move(ctx, r, state, pose, storey.key, sense=sense)
        ctx.out.pending.append(target)
        ctx.decide(target, f"disputed: {ctx.robot}'s sighting confirms neither pose")
        return _unless_only_seen(ctx, r, state)
    taken = dispute.sides.get(ctx.robot)
    if taken is not None and taken[0] != side:
        run = dispute.leaning.get(ctx.robot, 0) + 1
        if run < ctx.rules.move_sightings:  # one sighting nearer the other pose: a detector's outlier
            ctx.out.effects.append(leans(target, ctx.robot, run))
            ctx.out.pending.append(target)
            why = f"{ctx.robot} stays on side {taken[0]}; {run} of its sightings in a row confirm {side}"
            ctx.decide(target, f"disputed: {why}")
            return _unless_only_seen(ctx, r, state)
    sides = {**dispute.sides, ctx.robot: (side, sense)}
    counts = [sum(1 for s, _ in sides.values() if s == i) for i in (0, 1)]
    if counts[side] <= counts[1 - side]:
        ctx.out.effects.append(took_side(target, ctx.robot, side, sense))
        ctx.out.pending.append(target)
        ctx.decide(target, f"disputed: {ctx.robot} confirms side {side}; {counts[0]} against {counts[1]}")
        return _unless_only_seen(ctx, r, state)
    at = dispute.poses[side]
    a = dispute.poses[0]
    r, pose = placed(ctx, r, state, at=at, held=held, storey=storey, sizes=(a.sx, a.sy, a.sz))
    ctx.out.effects.append(reset_refinement(target))
    if side == 1:
        ctx.out.effects.append(moved(target))
    ctx.out.effects.append(confirmed_by(target, {r: ns for r, (s, ns) in sides.items() if s == side}))
    ctx.decide(target, f"dispute settled: {counts[side]} robots against {counts[1 - side]}")
    ctx.out.notes.append(
        f"<{target}>: the robots agree where it stands ({counts[side]} against {counts[1 - side]})"
    )
    ctx.pend(target, storey.key, pose, r=r)
    return r


def _unless_only_seen(ctx: FusionContext, r: ElementReport, state: ElementState) -> ElementReport | None:
    r = replace(r, box=None, storey=None)
    if only_sighting(r, state):
        ctx.out.seen.append(state.iri)
        return None
    return r
