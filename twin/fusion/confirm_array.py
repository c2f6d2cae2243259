"""Confirmations at once: an array of boxes that all confirm the held poses, settled in one pass.

A robot's perception reports the same objects many times a second, almost always where the twin holds
them. :func:`confirm_array` settles such an observation with array operations over its boxes and the
held poses (the confirmation gates, the resize evidence and the refinement's hysteresis for all boxes
at once) and one effect for the array, instead of the rules of :func:`twin.live.fuse.fuse` once per
report (for arrays of :data:`MIN_BOXES` reports or more). It decides exactly what the per-report rules
decide, and only when every report is a plain confirmation: a box of a held, candidate element, by its
own IRI or an alias it fits, within the confirmation distance and angle of the held pose, at the held
sizes, whose running mean (past ``refine_after``) stays within ``refine_fraction`` of it and within
``refine_distance_m`` of its centre, and nothing
else in the report (no class change, labels, zone marks), of an element robots do not dispute
(:mod:`twin.fusion.dispute`: each sighting takes a side); a box seen earlier than what the twin holds
of the element (another robot's later sighting came first) is stale, noted as the per-report rules
note it. Anything else (a move, a new element, a resize, a refinement to commit, two reports of one
element) returns False with nothing done: the per-report rules decide the whole observation.

Per report it makes one pass of lookups (what the report names, what the twin holds of that); what the
gates need of each held element is remembered while the objects it was made from stay the same, and a
robot's next array naming the same elements uses the same stacked arrays (``FusionMemory.confirm_cache``).
An element moved earlier in the batch (another robot's array) is held where that move put it, as the
per-report rules hold it: the arrays that follow a move in its batch are settled here too.

Example::

    if not confirm_array(ctx, obs.reports, senses):
        for r, s in zip(obs.reports, senses):
            ...  # the per-report rules
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from operator import is_
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from twin.config import FusionRules
from twin.fusion.bias import sightings_noted, unbiased, update_pairs
from twin.fusion.clocks import note_stale
from twin.fusion.confirm import box_of, only_a_box, resizable
from twin.fusion.dispute import older_disagreement, still_covers
from twin.fusion.effects import Effect
from twin.fusion.footprints import SQUARE_TOLERANCE_M, Pose
from twin.fusion.gates import compatible, is_candidate, kinds_agree
from twin.fusion.memory import FusionMemory, RobotMean
from twin.records import ElementReport, FloatArray, Shape

if TYPE_CHECKING:
    from twin.fusion.context import FusionContext
    from twin.live.state import ElementState

Index = npt.NDArray[np.intp]
BoolArray = npt.NDArray[np.bool_]
HALF_PI = math.pi / 2
MIN_BOXES = 10
"""Fewer reports than this go through the per-report rules: cheaper than setting up the arrays (in
process, one box costs 0.06 ms per observation that way and 0.11 ms this way; they cost the same at
about 10, and 20 cost 0.27 ms here against 0.40 ms)."""


@dataclass(slots=True)
class _Held:
    """What the gates need of one held element, kept (in ``FusionMemory.confirm_cache``) while the
    objects it was made from stay the same: its state, its shape, its dispute's poses, the report's
    class and the rules."""

    state: ElementState
    mesh: object
    placement: object
    """The shape's objects (the held pose is theirs)."""
    held: Pose
    cover: object
    """The dispute's poses (None: no dispute)."""
    ifc_class: str | None
    rules: FusionRules
    ok: bool
    """A candidate, not disputed, of the report's class (the class part of
    :func:`~twin.fusion.confirm.only_sighting_where_it_stands`): a box of it may confirm it."""
    class_ok: bool
    """The report's class and kind agree with the element's (the alias check's first gates)."""
    resizable: bool
    """A robot's box: other sizes are resize evidence (:func:`~twin.fusion.confirm.resizable`)."""
    row: tuple[float, float, float, float, float, float, float]
    gates: tuple[float, float, float, float]
    """The class's confirm distance and angle, size ratio and minimum area ratio."""


def _held(ctx: FusionContext, r: ElementReport, state: ElementState, shape: Shape, cover: object) -> _Held:
    """:class:`_Held` of ``r``'s element, which has ``shape``."""
    held = ctx.memory.pose(state.iri, shape)
    schema = ctx.live.site.schema
    track = ctx.memory.tracks.get(state.iri)
    disputed = track is not None and still_covers(track.dispute, held)
    c = ctx.rules.of(state.ifc_types)
    class_ok = (r.ifc_class is None or compatible(schema, r.ifc_class, state)) and kinds_agree(
        schema, (), r.ifc_class, state
    )
    return _Held(
        state,
        shape[0],
        shape[1],
        held,
        cover,
        r.ifc_class,
        ctx.rules,
        is_candidate(state)
        and not disputed
        and (
            r.ifc_class is None
            or r.ifc_class in state.ifc_types
            or r.ifc_class.lower() == state.ifc_class.lower()
        ),
        class_ok,
        resizable(ctx, state.iri),
        _row(held),
        (c.confirm_distance_m, c.confirm_angle_rad, c.size_ratio, c.min_area_ratio),
    )


@dataclass(slots=True)
class _Array:
    """The array's boxes as the per-report rules would see them, before the gates (row i: report i)."""

    reports: list[ElementReport]
    """As given (each box shifted by the robot's detector bias, once known)."""
    targets: list[str]
    layout: _Layout
    storeys: list[str]
    senses: list[int]
    stale: list[bool]
    """Seen before what the twin holds of it (:func:`~twin.fusion.clocks.stale_change`): only counted."""
    raw: FloatArray
    """``(n, 7)``: the boxes' world poses (canonical), cx .. yaw."""
    pose: FloatArray
    """``raw`` less the robot's detector bias."""
    refs: FloatArray
    """``(n, 8)``: each element's confirmations so far (n, then the sums of cx .. yaw)."""


def confirm_array(ctx: FusionContext, reports: Sequence[ElementReport], senses: Sequence[int]) -> bool:
    """Settle ``reports`` (seen at ``senses``, corrected) as confirmations if every one is (see the
    module's docstring): the same boxes, detections, sightings, effects and notes as the per-report
    rules. Returns False, with nothing done, when any report needs those rules."""
    if len(reports) < MIN_BOXES or not ctx.rules.enabled:
        return False
    boxes = _boxes(ctx, reports, senses)
    if boxes is None:
        return False
    stale = boxes.stale
    fresh = np.arange(len(stale)) if True not in stale else np.flatnonzero(~np.array(stale, dtype=np.bool_))
    sighted = _gates(ctx, boxes, fresh) if len(fresh) else np.zeros((0, 7))
    if sighted is None:
        return False
    _settle(ctx, boxes, fresh, sighted)
    return True


def _boxes(  # noqa: PLR0911 (each return: a report the per-report rules decide)
    ctx: FusionContext, reports: Sequence[ElementReport], senses: Sequence[int]
) -> _Array | None:
    """Every report as a held element's box (no side effect but the robot's bias, computed once), or
    None when one is anything else. One pass of lookups per report (what it names, what the twin holds
    of that: :class:`_Held`, remembered while it stays the same), the geometry as arrays."""
    memory = ctx.memory
    aliases, states, tracks = memory.aliases, ctx.states, memory.tracks
    cache = _cache(memory, len(ctx.live.states))
    held_of = cache.held
    shapes, shape_of = ctx.shapes, ctx.live.maps.shape_of
    storeys = ctx.live.site.storeys
    rules = ctx.rules
    elevations: dict[str, float] = {}
    targets: list[str] = []
    helds: list[_Held] = []
    keys: list[str] = []
    stale: list[bool] = []
    rows: list[tuple[float, ...]] = []
    """Per report: its box (cx .. yaw, z above the storey's floor) and its element's confirmations so far
    (n, then the sums of cx .. yaw), made into one array at once."""
    aliased: list[int] = []
    for i, (r, sense) in enumerate(zip(reports, senses, strict=True)):
        b = r.box
        if b is None or r.unmerge:
            return None
        alias = aliases.get(r.iri)
        if alias is None:
            target = r.iri
        else:
            target = alias.target
            aliased.append(i)
        state = states.get(target)
        if state is None:
            return None  # unknown (twice in the array: below)
        track = tracks.get(target)
        dispute = track.dispute if track is not None else None
        cover = dispute.poses if dispute is not None else None
        # ctx.held_pose: an element moved earlier in the batch has its new shape in ctx.shapes, whose
        # pose is the one ctx.pending holds (twin.live.observe.fused_pending: memory.pose of that shape)
        shape = shapes[target] if target in shapes else shape_of(target)
        if shape is None:
            return None  # no held pose: nothing to confirm
        h = held_of.get(target)
        if (
            h is None
            or h.mesh is not shape[0]
            or h.placement is not shape[1]
            or h.state is not state
            or h.cover is not cover
            or h.ifc_class != r.ifc_class
            or h.rules is not rules
        ):
            h = held_of[target] = _held(ctx, r, state, shape, cover)
        if not h.ok or not only_a_box(r):
            return None  # not a candidate, disputed (each sighting takes a side), a change besides the box
        key = r.storey or state.storey
        if key is None:
            return None
        elevation = elevations.get(key)
        if elevation is None:
            storey = storeys.get(key)
            if storey is None:
                return None
            elevation = elevations[key] = storey.elevation_m
        targets.append(target)
        helds.append(h)
        keys.append(key)
        stale.append(sense < state.sensed_ns or (track is not None and sense < track.seen_ns))
        f = track.refinement if track is not None else None
        z = elevation + b.cz
        rows.append(
            (b.cx, b.cy, z, b.sx, b.sy, b.sz, b.yaw, *_NO_REFINEMENT)
            if f is None
            else (b.cx, b.cy, z, b.sx, b.sy, b.sz, b.yaw, f.n, f.cx, f.cy, f.cz, f.sx, f.sy, f.sz, f.yaw)
        )
    if len(set(targets)) < len(targets):
        return None  # an element twice in the array
    both = np.array(rows, dtype=np.float64)
    raw = _canonical(both[:, :7])  # box_pose of each
    pose = raw
    given = list(reports)
    if unbiased(ctx, _ANY_POSE) is not _ANY_POSE:  # the robot's detector bias, once known
        bias = ctx.bias
        assert bias is not None
        pose = raw.copy()
        pose[:, 0] -= bias[0]
        pose[:, 1] -= bias[1]
        for i, row in enumerate(pose.tolist()):
            given[i] = replace(given[i], box=box_of(Pose(*row), elevations[keys[i]]))
    layout = _layout(cache, ctx.robot, helds, aliased)
    if True in stale:
        old = [j for j, s in enumerate(stale) if s]
        confirming = _confirms(pose[old], layout.held[old], layout.dist[old], layout.angle[old]).tolist()
        for i, confirms_held in zip(old, confirming, strict=True):
            if confirms_held:
                continue  # it confirms the held pose: not a disagreement (older_disagreement's confirms)
            sighted = Pose(*pose[i].tolist())
            if older_disagreement(ctx, given[i], helds[i].state, sighted, helds[i].held, senses[i]):
                return None  # (older: seen before another robot's later sighting, a short move from it)
    if aliased and not _aliases_fit(
        pose if len(aliased) == len(rows) else pose[aliased],
        layout,
        rules.alias_jump_m,
        gated=True not in stale,  # (every box fresh: the confirmation gates check each one next)
    ):
        return None
    return _Array(
        given, targets, layout, keys, list(senses), stale, raw, pose, both[:, 7:]
    )


_NO_REFINEMENT = (0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
_ANY_POSE = Pose(0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0)
"""A pose to ask :func:`~twin.fusion.bias.unbiased` whether the robot has a bias."""


@dataclass(slots=True)
class _Layout:
    """An array's held elements stacked as arrays (row i: report i), kept per robot and used again
    while its next array names the same elements through the same IRIs, held as they were (a
    tracker's objects, array after array)."""

    helds: list[_Held]
    aliased: list[int]
    """The rows whose report came through an alias."""
    held: FloatArray
    """``(n, 7)``: the held poses, cx .. yaw."""
    square: BoolArray
    """The held footprints that are square (:attr:`~twin.fusion.footprints.Pose.square`)."""
    dist: FloatArray
    angle: FloatArray
    ratio: FloatArray
    min_area: FloatArray
    resizable: BoolArray
    class_ok: bool
    """Every aliased row's class and kind agree with its element's."""
    twice: FloatArray
    """``(2n, 7)``: :attr:`held` twice (the sightings' rows, then their means')."""
    square_twice: BoolArray
    limits: FloatArray
    """``(3, 2n)``: for the sightings, the class's confirm distance (centre, height) and angle; for
    their means, ``refine_fraction`` of those (the centre also within ``refine_distance_m``)."""
    alias: _AliasGates
    sizes: FloatArray
    """``(n, 3)``: how far each size may be from the held one without being resize evidence: the
    confirm distance, infinite where the element is not :attr:`resizable`."""


HEIGHT_MARGIN_M = 1e-6
"""How much more than the confirm distance an aliased element's half height must be for its box's
height gate to imply that the heights overlap (far more than the floats' rounding)."""


@dataclass(slots=True)
class _AliasGates:
    """The aliased rows' side of :func:`_aliases_fit`, computed once per layout."""

    held: FloatArray
    """``(k, 7)``: the aliased rows' held poses."""
    area: FloatArray
    positive: bool
    """Every held area is positive (the area ratio needs no guard)."""
    tolerance: FloatArray
    """``(k, 3)``: the size gate, ``size_ratio`` of the held sizes."""
    min_area: FloatArray
    gated: bool
    """The confirmation gates imply the alias's centre and height gates (each row's confirm distance
    within ``alias_jump_m`` and :data:`HEIGHT_MARGIN_M` less than its half height): a box the
    confirmation gates check needs only the alias's size gates here."""


def _alias_gates(held: FloatArray, gates: FloatArray, aliased: list[int], jump_m: float) -> _AliasGates:
    """:class:`_AliasGates` of the ``aliased`` rows of ``held`` and ``gates`` (:attr:`_Held.gates`)."""
    if len(aliased) < len(held):
        held, gates = held[aliased], gates[aliased]
    dist, ratio, min_area = gates[:, 0], gates[:, 2], gates[:, 3]
    area = held[:, 3] * held[:, 4]
    return _AliasGates(
        held,
        area,
        bool((area > 0.0).all()),
        ratio[:, None] * held[:, 3:6],
        min_area,
        bool((dist <= jump_m).all() and (dist + HEIGHT_MARGIN_M <= held[:, 5] / 2).all()),
    )


@dataclass(slots=True)
class _Cache:
    """What confirmations at once keep between arrays (``FusionMemory.confirm_cache``)."""

    held: dict[str, _Held] = field(default_factory=dict)
    """Element -> :class:`_Held`."""
    layouts: dict[str, _Layout] = field(default_factory=dict)
    """Robot -> its last array's :class:`_Layout`."""


CACHE_SLACK = 1024
"""The cache is emptied once it holds this many more elements (or robots' layouts) than the twin holds
elements (removed elements' entries are never used again; it fills again as arrays come)."""


def _cache(memory: FusionMemory, elements: int) -> _Cache:
    """The memory's cache, emptied when it holds more than ``elements`` + :data:`CACHE_SLACK` entries."""
    cache = memory.confirm_cache
    if not isinstance(cache, _Cache):
        cache = memory.confirm_cache = _Cache()
    elif len(cache.held) > elements + CACHE_SLACK or len(cache.layouts) > CACHE_SLACK:
        cache.held.clear()
        cache.layouts.clear()
    return cache


def forget(memory: FusionMemory, iris: Sequence[str]) -> None:
    """Drop what confirmations at once keep of ``iris`` (elements the twin no longer holds)."""
    cache = memory.confirm_cache
    if isinstance(cache, _Cache):
        for iri in iris:
            cache.held.pop(iri, None)


def _layout(cache: _Cache, robot: str, helds: list[_Held], aliased: list[int]) -> _Layout:
    """``helds`` stacked: the robot's last layout when it is the same."""
    last = cache.layouts.get(robot)
    if (
        last is not None
        and last.aliased == aliased
        and len(last.helds) == len(helds)
        and all(map(is_, last.helds, helds))
    ):
        return last
    held = np.array([h.row for h in helds], dtype=np.float64)
    gates = np.array([h.gates for h in helds], dtype=np.float64)
    dist, angle = gates[:, 0].copy(), gates[:, 1].copy()
    rules = helds[0].rules
    f = rules.refine_fraction
    limits = np.array(
        [
            np.concatenate((dist, np.minimum(dist * f, rules.refine_distance_m))),
            np.concatenate((dist, dist * f)),
            np.concatenate((angle, angle * f)),
        ]
    )
    square = held[:, 3] - held[:, 4] < SQUARE_TOLERANCE_M
    resizes = np.array([h.resizable for h in helds], dtype=np.bool_)
    made = _Layout(
        helds,
        aliased,
        held,
        square,
        dist,
        angle,
        gates[:, 2].copy(),
        gates[:, 3].copy(),
        resizes,
        all(helds[i].class_ok for i in aliased),
        np.concatenate((held, held)),
        np.concatenate((square, square)),
        limits,
        _alias_gates(held, gates, aliased, rules.alias_jump_m),
        np.where(resizes[:, None], dist[:, None], np.inf).repeat(3, axis=1),
    )
    cache.layouts[robot] = made
    return made


def _aliases_fit(pose: FloatArray, layout: _Layout, jump_m: float, *, gated: bool = False) -> bool:
    """:func:`twin.fusion.associate.alias_fits` is ``"fits"`` for every aliased row (``pose``; ``"within"``
    and ``"fails"`` both need the per-report rules): class and kind agree, the centre no farther than
    ``jump_m``, the heights overlap, the sizes agree. With ``gated`` (the confirmation gates check
    every row next: every box fresh), only the size gates when the confirmation gates imply the
    others (:attr:`_AliasGates.gated`): a row they would fail, those fail."""
    if not layout.class_ok:
        return False
    g = layout.alias
    if gated and g.gated and g.positive:
        a, b = pose[:, 3] * pose[:, 4], g.area
        return _every(np.minimum(a, b) / np.maximum(a, b) >= g.min_area) and _every(
            np.abs(pose[:, 3:6] - g.held[:, 3:6]) <= g.tolerance
        )
    rows = layout.aliased
    if len(rows) == len(layout.helds):  # every report through an alias (a robot that made none of them)
        held, ratio, min_area = layout.held, layout.ratio, layout.min_area
    else:
        held, ratio, min_area = layout.held[rows], layout.ratio[rows], layout.min_area[rows]
    half, held_half = pose[:, 5] / 2, held[:, 5] / 2
    fits = (  # the centre near, the heights overlapping (each condition of every row, then one reduction)
        (np.hypot(pose[:, 0] - held[:, 0], pose[:, 1] - held[:, 1]) <= jump_m)
        & (pose[:, 2] - half <= held[:, 2] + held_half)
        & (held[:, 2] - held_half <= pose[:, 2] + half)
    )
    a, b = pose[:, 3] * pose[:, 4], held[:, 3] * held[:, 4]
    small, large = np.minimum(a, b), np.maximum(a, b)
    fits &= (large <= 0.0) | (
        np.divide(small, large, out=np.zeros_like(small), where=large > 0.0) >= min_area
    )
    return bool(fits.all() and (np.abs(pose[:, 3:6] - held[:, 3:6]) <= ratio[:, None] * held[:, 3:6]).all())


def _gates(ctx: FusionContext, boxes: _Array, fresh: Index) -> FloatArray | None:
    """The sightings aligned with the held poses (``(n, 7)``: cx .. yaw, one row per ``fresh`` box), or
    None unless every box confirms, at the held sizes, without a refinement to commit
    (:func:`twin.fusion.confirm.confirms`, :func:`~twin.fusion.confirm.resize_evidence`,
    :func:`~twin.fusion.confirm.confirmation`)."""
    rules, layout = ctx.rules, boxes.layout
    if len(fresh) == len(boxes.targets) and _every(boxes.refs[:, 0] + 1 >= rules.refine_after):
        return _gates_at_once(boxes.pose, boxes.refs, layout)
    if len(fresh) == len(boxes.targets):
        seen, refs, held = boxes.pose, boxes.refs, layout.held
        held_square, dist, angle, resize = layout.square, layout.dist, layout.angle, layout.resizable
    else:
        seen, refs, held = boxes.pose[fresh], boxes.refs[fresh], layout.held[fresh]
        held_square, dist, angle = layout.square[fresh], layout.dist[fresh], layout.angle[fresh]
        resize = layout.resizable[fresh]
    period = np.where((seen[:, 3] - seen[:, 4] < SQUARE_TOLERANCE_M) | held_square, HALF_PI, math.pi)
    turn = seen[:, 6] - held[:, 6]
    d = np.mod(turn, period)
    if not (
        (np.hypot(seen[:, 0] - held[:, 0], seen[:, 1] - held[:, 1]) <= dist)
        & (np.abs(seen[:, 2] - held[:, 2]) <= dist)
        & (np.minimum(d, period - d) <= angle)
    ).all():
        return None
    a = _aligned(seen, held, period, turn)
    if not ((np.abs(a[:, 3:6] - held[:, 3:6]) <= dist[:, None]).all(axis=1) | ~resize).all():
        return None  # other sizes: resize evidence
    n = refs[:, 0]
    check = n + 1 >= rules.refine_after
    f = rules.refine_fraction
    if check.all():  # (after the first few arrays)
        if not _keeps(_canonical((refs[:, 1:] + a) / (n + 1)[:, None]), held, dist * f, angle * f, rules):
            return None  # the mean moved: a refinement to commit
    elif check.any():
        mean = _canonical((refs[check, 1:] + a[check]) / (n[check] + 1)[:, None])
        if not _keeps(mean, held[check], dist[check] * f, angle[check] * f, rules):
            return None
    return a


def _gates_at_once(seen: FloatArray, refs: FloatArray, layout: _Layout) -> FloatArray | None:
    """:func:`_gates` when every box is fresh and every element's mean is checked (the common case): the
    sightings and their means (with this sighting) against the held poses in one pass."""
    held = layout.held
    period = np.where((seen[:, 3] - seen[:, 4] < SQUARE_TOLERANCE_M) | layout.square, HALF_PI, math.pi)
    a = _aligned(seen, held, period, seen[:, 6] - held[:, 6])
    if not _every(np.abs(a[:, 3:6] - held[:, 3:6]) <= layout.sizes):
        return None  # other sizes: resize evidence
    rows = np.concatenate((seen, _canonical((refs[:, 1:] + a) / (refs[:, :1] + 1))))
    twice = layout.twice
    period = np.where((rows[:, 3] - rows[:, 4] < SQUARE_TOLERANCE_M) | layout.square_twice, HALF_PI, math.pi)
    delta = rows - twice  # (each column as the gates below take it, in one operation)
    d = np.mod(delta[:, 6], period)
    centre, height, angle = layout.limits
    ok = (
        (np.hypot(delta[:, 0], delta[:, 1]) <= centre)
        & (np.abs(delta[:, 2]) <= height)
        & (np.minimum(d, period - d) <= angle)
    )
    return a if _every(ok) else None  # (a mean out of bounds: a refinement to commit)


def _keeps(
    mean: FloatArray, held: FloatArray, dist: FloatArray, angle: FloatArray, rules: FusionRules
) -> bool:
    """Whether every refinement's ``mean`` stays within its hysteresis (``dist`` and ``angle``, already
    ``refine_fraction`` of the class's) and within ``refine_distance_m`` of the held pose (a map cell
    off: :func:`twin.fusion.confirm.confirmation` commits it)."""
    if not _confirms(mean, held, dist, angle).all():
        return False
    return bool((np.hypot(mean[:, 0] - held[:, 0], mean[:, 1] - held[:, 1]) <= rules.refine_distance_m).all())


def _every(mask: BoolArray) -> bool:
    """``mask.all()`` (any shape) without the method's Python-level wrapper: a third of its cost on the
    20-40 rows of an array, where a dozen such tests are made per array."""
    return int(np.count_nonzero(mask)) == mask.size


def _some(mask: BoolArray) -> bool:
    """``mask.any()``, as :func:`_every`."""
    return int(np.count_nonzero(mask)) > 0


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


def _aligned(seen: FloatArray, held: FloatArray, period: FloatArray, turn: FloatArray) -> FloatArray:
    """:func:`twin.fusion.footprints.aligned` of each row (``period``: :func:`_period`, ``turn``: the
    yaw of ``seen`` less ``held``'s)."""
    half = period / 2
    d = np.mod(turn + half, period) - half
    quarter = np.mod(np.rint((turn - d) / HALF_PI), 2) == 1  # (np.round to 0 decimals is rint)
    out = seen.copy()
    if _some(quarter):
        out[quarter, 3] = seen[quarter, 4]
        out[quarter, 4] = seen[quarter, 3]
    out[:, 6] = held[:, 6] + d
    return out


def _canonical(p: FloatArray) -> FloatArray:
    """:func:`twin.fusion.footprints.box_pose` of each row (``sx >= sy``, yaw in [0, pi))."""
    out = p.copy()
    swap = p[:, 4] > p[:, 3]
    if _some(swap):
        out[swap, 3] = p[swap, 4]
        out[swap, 4] = p[swap, 3]
        out[swap, 6] = p[swap, 6] + HALF_PI
    out[:, 6] = np.mod(out[:, 6], math.pi)
    return out


def _settle(ctx: FusionContext, boxes: _Array, fresh: Index, sighted: FloatArray) -> None:
    """What the per-report rules do for each box: a stale one noted as they note it, each confirmation
    (``fresh``, aligned as ``sighted``) counted, their memory effects as one."""
    robot, out = ctx.robot, ctx.out
    reports, targets, senses, helds = boxes.reports, boxes.targets, boxes.senses, boxes.layout.helds
    rule = f"confirmation by {robot}: within confirm_distance_m and confirm_angle_deg"
    used: list[str] = []
    resolved = out.resolved
    for i in boxes.layout.aliased:
        iri, target = reports[i].iri, targets[i]
        if target != iri:
            resolved[iri] = target  # resolved, and the alias used
            used.append(iri)
    ctx.boxes_later = _later(ctx.boxes_later, boxes)
    if len(fresh) < len(targets):  # stale_change of each (a sighting, not the latest), one effect
        old = [(targets[i], senses[i]) for i, stale in enumerate(boxes.stale) if stale]
        for i, stale in enumerate(boxes.stale):
            if stale:
                note_stale(ctx, reports[i].iri, helds[i].state, senses[i])
        out.effects.append(_stale_sightings(old, robot))
    if used:  # (the per-report rules add one such effect per report: on the aliases, not the tracks)
        out.effects.append(_use_aliases(used, ctx.arrival_ns))
    ctx.detected.update(targets)
    ctx.used.update(targets)
    if len(fresh) == len(targets):
        seen, at, resizes = targets, senses, [h.resizable for h in helds]
        raw = boxes.raw[:, :2].tolist()
    else:
        picked = fresh.tolist()
        seen, at = [targets[i] for i in picked], [senses[i] for i in picked]
        resizes, raw = [helds[i].resizable for i in picked], boxes.raw[fresh, :2].tolist()
    out.seen.extend(seen)
    means, diffs = sightings_noted(  # where its detector puts them: its bias (note_sightings_at)
        ctx, [(iri, x, y, sense) for iri, (x, y), sense in zip(seen, raw, at, strict=True)]
    )
    rows = [
        (iri, sense, r, mean, *row)
        for iri, sense, r, mean, row in zip(seen, at, resizes, means, sighted.tolist(), strict=True)
    ]

    def run(m: FusionMemory) -> None:  # (the bias notes' effect and the confirmations', as one)
        journaled, tracks = m.journal is not None, m.tracks
        for iri, sense, resizes, (_, old, n, mx, my, last), cx, cy, cz, sx, sy, sz, yaw in rows:
            t = m.track(iri) if journaled else tracks.get(iri) or m.track(iri)
            mean = t.means.get(robot)  # bias.set_mean
            if mean is not None and mean is old:
                mean.n, mean.x, mean.y, mean.last_ns = n, mx, my, last
            else:
                t.means[robot] = RobotMean(n, mx, my, last)
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
            if t.movers:
                t.movers.clear()
            confirmed = t.confirmed.get(robot)
            if confirmed is None or sense > confirmed:
                t.confirmed[robot] = sense
            if t.runs:
                t.runs.pop(robot, None)  # this robot sees it where it is held: its own run ends
            t.decided = rule
        update_pairs(m, robot, diffs)

    out.effects.append(run)


def _later(
    before: Callable[[], list[tuple[str, ElementReport, Pose]]] | None, boxes: _Array
) -> Callable[[], list[tuple[str, ElementReport, Pose]]]:
    """The boxes of the array (storey, report, pose) for ``ctx.boxes``, made when they are read."""

    def made() -> list[tuple[str, ElementReport, Pose]]:
        mine = [
            (key, r, Pose(*row))
            for key, r, row in zip(boxes.storeys, boxes.reports, boxes.pose.tolist(), strict=True)
        ]
        return mine if before is None else [*before(), *mine]

    return made


def _stale_sightings(seen: list[tuple[str, int]], robot: str) -> Effect:
    """:func:`twin.fusion.effects.sighting` (``latest=False``) of each (element, sense time), as one
    effect."""

    def run(m: FusionMemory) -> None:
        for iri, sense in seen:
            t = m.track(iri)
            latest = t.seen_ns
            t.sighted(robot, sense)
            t.seen_ns = latest

    return run


def _use_aliases(used: list[str], now: int) -> Effect:
    """:func:`twin.fusion.effects.use_alias` of each alias in ``used``, as one effect."""

    def run(m: FusionMemory) -> None:
        journaled = m.journal is not None
        for alias in used:
            if journaled:
                m.changing("aliases", alias)
            a = m.aliases.get(alias)
            if a is not None:
                a.used_ns = max(a.used_ns, now)

    return run
