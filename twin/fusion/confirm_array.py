"""Confirmations at once: an array of boxes that all confirm the held poses, settled in one pass.

A robot's perception reports the same objects many times a second, almost always where the twin holds
them. :func:`confirm_array` settles such an observation with array operations over its boxes and the
held poses (the confirmation gates, the resize evidence and the refinement's hysteresis for all boxes
at once) and one effect for the array, instead of the rules of :func:`twin.live.fuse.fuse` once per
report (for arrays of :data:`MIN_BOXES` reports or more). It decides exactly what the per-report rules
decide, and only when every report is a plain confirmation: a box of a held, candidate element, by its
own IRI or an alias it fits, within the confirmation distance and angle of the held pose, at the held
sizes, whose running mean (past ``refine_after``) stays within ``refine_fraction`` of it, and nothing
else in the report (no class change, labels, zone marks), of an element robots do not dispute
(:mod:`twin.fusion.dispute`: each sighting takes a side); a box seen earlier than what the twin holds
of the element (another robot's later sighting came first) is stale, noted as the per-report rules
note it. Anything else (a move, a new element, a resize, a refinement to commit, two reports of one
element) returns False with nothing done: the per-report rules decide the whole observation.

Example::

    if not confirm_array(ctx, obs.reports, senses):
        for r, s in zip(obs.reports, senses):
            ...  # the per-report rules
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from twin.fusion.associate import alias_fits, through_alias
from twin.fusion.bias import note_sightings, unbiased
from twin.fusion.clocks import last_known, stale_change
from twin.fusion.confirm import box_of, only_sighting_where_it_stands, resizable
from twin.fusion.context import report_pose
from twin.fusion.dispute import older_disagreement, still_covers
from twin.fusion.footprints import SQUARE_TOLERANCE_M, Pose
from twin.fusion.gates import is_candidate
from twin.fusion.memory import FusionMemory
from twin.records import ElementReport, FloatArray

if TYPE_CHECKING:
    from twin.fusion.context import FusionContext
    from twin.live.state import ElementState

HALF_PI = math.pi / 2
MIN_BOXES = 10
"""Fewer reports than this go through the per-report rules: cheaper than setting up the arrays (in
process, one box costs 0.06 ms per observation that way and 0.11 ms this way; they cost the same at
about 10, and 20 cost 0.27 ms here against 0.40 ms)."""


@dataclass(slots=True)
class _Box:
    """One report of the array as the per-report rules would see it, before the gates."""

    report: ElementReport
    """As given (its box shifted by the robot's detector bias, once known)."""
    target: str
    state: ElementState
    storey: str
    raw: Pose
    pose: Pose
    held: Pose
    sense: int
    stale: bool
    """Seen before what the twin holds of it (:func:`~twin.fusion.clocks.stale_change`): only counted."""
    resizable: bool
    """A robot's box: other sizes are resize evidence (:func:`~twin.fusion.confirm.resizable`)."""


def confirm_array(ctx: FusionContext, reports: Sequence[ElementReport], senses: Sequence[int]) -> bool:
    """Settle ``reports`` (seen at ``senses``, corrected) as confirmations if every one is (see the
    module's docstring): the same boxes, detections, sightings, effects and notes as the per-report
    rules. Returns False, with nothing done, when any report needs those rules."""
    if len(reports) < MIN_BOXES or not ctx.rules.enabled:
        return False
    boxes = _boxes(ctx, reports, senses)
    if boxes is None:
        return False
    fresh = [b for b in boxes if not b.stale]
    sighted = _gates(ctx, fresh, _refinements(ctx.memory, fresh)) if fresh else np.zeros((0, 7))
    if sighted is None:
        return False
    _settle(ctx, boxes, fresh, sighted)
    return True


def _boxes(ctx: FusionContext, reports: Sequence[ElementReport], senses: Sequence[int]) -> list[_Box] | None:
    """Every report as a held element's box (no side effect but the robot's bias, computed once), or
    None when one is anything else."""
    aliases, states, storeys, pending = ctx.memory.aliases, ctx.states, ctx.live.site.storeys, ctx.pending
    tracks = ctx.memory.tracks
    out: list[_Box] = []
    targets: set[str] = set()
    for given, sense in zip(reports, senses, strict=True):
        r = given
        if r.box is None or r.unmerge:
            return None
        alias = aliases.get(r.iri)
        target = r.iri if alias is None else alias.target
        state = states.get(target)
        if state is None or target in targets or target in pending or not is_candidate(state):
            return None  # unknown or removed, twice in the array, moved earlier in the batch
        if not only_sighting_where_it_stands(r, state):
            return None  # a change besides the box
        storey_key = r.storey or state.storey
        storey = storeys.get(storey_key or "")
        held = ctx.held_pose(target)
        track = tracks.get(target)
        disputed = track is not None and held is not None and still_covers(track.dispute, held)
        if storey is None or storey_key is None or held is None or disputed:
            return None  # (disputed: robots disagree on where it stands, each sighting takes a side)
        raw = report_pose(r, storey.elevation_m)
        assert raw is not None
        pose = unbiased(ctx, raw)
        if pose is not raw:
            r = replace(r, box=box_of(pose, storey.elevation_m))
        stale = sense < last_known(ctx, target, state)
        if (alias is not None and alias_fits(ctx, r, state, pose) != "fits") or (
            stale and older_disagreement(ctx, r, state, pose, held, sense)
        ):
            return None  # (older: seen before another robot's later sighting, a short move from it)
        targets.add(target)
        out.append(_Box(r, target, state, storey_key, raw, pose, held, sense, stale, resizable(ctx, target)))
    return out


def _refinements(memory: FusionMemory, boxes: list[_Box]) -> FloatArray:
    """``(n, 8)``: each element's confirmations so far (n, then the sums of cx .. yaw)."""
    rows = []
    for b in boxes:
        track = memory.tracks.get(b.target)
        f = track.refinement if track is not None else None
        rows.append(
            (0, 0, 0, 0, 0, 0, 0, 0) if f is None else (f.n, f.cx, f.cy, f.cz, f.sx, f.sy, f.sz, f.yaw)
        )
    return np.array(rows, dtype=np.float64)


def _gates(ctx: FusionContext, boxes: list[_Box], refs: FloatArray) -> FloatArray | None:
    """The sightings aligned with the held poses (``(n, 7)``: cx .. yaw), or None unless every box
    confirms, at the held sizes, without a refinement to commit (:func:`twin.fusion.confirm.confirms`,
    :func:`~twin.fusion.confirm.resize_evidence`, :func:`~twin.fusion.confirm.confirmation`)."""
    rules = ctx.rules
    seen = np.array([_row(b.pose) for b in boxes], dtype=np.float64)
    held = np.array([_row(b.held) for b in boxes], dtype=np.float64)
    of = [rules.of(b.state.ifc_types) for b in boxes]
    dist = np.array([c.confirm_distance_m for c in of], dtype=np.float64)
    angle = np.array([c.confirm_angle_rad for c in of], dtype=np.float64)
    if not _confirms(seen, held, dist, angle).all():
        return None
    a = _aligned(seen, held)
    resize = np.array([b.resizable for b in boxes], dtype=np.bool_)
    near = (np.abs(a[:, 3:6] - held[:, 3:6]) <= dist[:, None]).all(axis=1)
    if not (near | ~resize).all():
        return None  # other sizes: resize evidence
    n = refs[:, 0]
    check = n + 1 >= rules.refine_after
    if check.any():
        mean = _canonical((refs[check, 1:] + a[check]) / (n[check] + 1)[:, None])
        f = rules.refine_fraction
        if not _confirms(mean, held[check], dist[check] * f, angle[check] * f).all():
            return None  # the mean moved: a refinement to commit
    return a


def _row(p: Pose) -> tuple[float, float, float, float, float, float, float]:
    return (p.cx, p.cy, p.cz, p.sx, p.sy, p.sz, p.yaw)


def _period(a: FloatArray, b: FloatArray) -> FloatArray:
    """The yaw symmetry of two poses' footprints: pi/2 when either is square, else pi."""
    square = (a[:, 3] - a[:, 4] < SQUARE_TOLERANCE_M) | (b[:, 3] - b[:, 4] < SQUARE_TOLERANCE_M)
    return np.where(square, HALF_PI, math.pi)


def _confirms(seen: FloatArray, held: FloatArray, dist: FloatArray, angle: FloatArray) -> FloatArray:
    """:func:`twin.fusion.confirm.confirms` (``sizes=False``) of each row."""
    centre = np.hypot(seen[:, 0] - held[:, 0], seen[:, 1] - held[:, 1])
    period = _period(seen, held)
    d = np.mod(seen[:, 6] - held[:, 6], period)
    yaw = np.minimum(d, period - d)
    return np.asarray((centre <= dist) & (np.abs(seen[:, 2] - held[:, 2]) <= dist) & (yaw <= angle))


def _aligned(seen: FloatArray, held: FloatArray) -> FloatArray:
    """:func:`twin.fusion.footprints.aligned` of each row."""
    period = _period(seen, held)
    turn = seen[:, 6] - held[:, 6]
    d = np.mod(turn + period / 2, period) - period / 2
    quarter = np.mod(np.round((turn - d) / HALF_PI), 2) == 1
    out = seen.copy()
    out[quarter, 3] = seen[quarter, 4]
    out[quarter, 4] = seen[quarter, 3]
    out[:, 6] = held[:, 6] + d
    return out


def _canonical(p: FloatArray) -> FloatArray:
    """:func:`twin.fusion.footprints.box_pose` of each row (``sx >= sy``, yaw in [0, pi))."""
    out = p.copy()
    swap = p[:, 4] > p[:, 3]
    out[swap, 3] = p[swap, 4]
    out[swap, 4] = p[swap, 3]
    out[swap, 6] = p[swap, 6] + HALF_PI
    out[:, 6] = np.mod(out[:, 6], math.pi)
    return out


def _settle(ctx: FusionContext, boxes: list[_Box], fresh: list[_Box], sighted: FloatArray) -> None:
    """What the per-report rules do for each box: a stale one noted as they note it, each confirmation
    (``fresh``, aligned as ``sighted``) counted, their memory effects as one."""
    robot = ctx.robot
    rule = f"confirmation by {robot}: within confirm_distance_m and confirm_angle_deg"
    for b in boxes:
        if b.target != b.report.iri:
            through_alias(ctx, b.report)  # resolved, and the alias used
        ctx.boxes.append((b.storey, b.report, b.pose))
        ctx.detected.add(b.target)
        ctx.used.add(b.target)
        if b.stale:
            noted = stale_change(ctx, b.report, b.report.iri, b.state, b.sense)  # a sighting, not the latest
            assert noted
            continue
        ctx.out.seen.append(b.target)
    note_sightings(ctx, [(b.state, b.raw, b.sense) for b in fresh])  # where its detector puts them: its bias
    rows = [(b.target, b.sense, b.resizable, *row) for b, row in zip(fresh, sighted.tolist(), strict=True)]

    def run(m: FusionMemory) -> None:
        for iri, sense, resizes, cx, cy, cz, sx, sy, sz, yaw in rows:
            t = m.track(iri)
            t.sighted(robot, sense)
            if resizes:
                t.sizes.pop(robot, None)  # a sighting at the held sizes clears the robot's evidence
            f = t.refinement
            f.n += 1
            f.cx += cx
            f.cy += cy
            f.cz += cz
            f.sx += sx
            f.sy += sy
            f.sz += sz
            f.yaw += yaw
            t.moving = None
            t.movers.clear()
            t.confirmed[robot] = max(sense, t.confirmed.get(robot, sense))
            t.runs.pop(robot, None)  # this robot sees it where it is held: its own run ends
            t.decided = rule

    ctx.out.effects.append(run)
