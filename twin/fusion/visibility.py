"""What a sensor could see: which elements a view (``a twin:View``) should have seen, so that not
seeing them is a miss.

A view is the floor a robot's sensor saw on a storey: the union of its polygons (concave ones too)
less its holes (``twin:hole``: floor inside the polygons that it did not see, such as a person's
shadow). An element is **in** the view when its inset footprint lies inside that region *by area*:
every part of it, not just its corners (a bench whose middle stands in a shadow carved out of the
polygon is not in the view). Where no boundary of the region crosses a footprint, the test is exact
(the footprint is wholly in or wholly out, its corners and centre decide); where one does, the
footprint is sampled every :data:`AREA_SAMPLE_M` (the union of several polygons that share an edge).

With the sensor's **origin** (``twin:origin``, map frame), an element in the view is also **visible**
only when nothing the twin holds stands between: sight lines from the origin to a grid of points over
its inset footprint, at its mid-height, must each pass clear of every other element's upright box
(its footprint from its zmin to its zmax) until they reach the element's own footprint (so what
overlaps an element hides it only from the side it stands on: a robot's offset sighting of a ghost
does not keep the ghost). An element taller than the sensor's height hides all that
stands behind it; a lower one hides what the sight lines reach below its top (the rear rows of a
stack of boxes, a bench behind a cabinet). The boxes that robots report in the same observation
stand in the way too (a detection of something the twin does not hold yet, a person).

Everything is vectorised over the candidates: ``(n, 4, 2)`` footprint corners at once.

Example::

    feet = np.stack([corners(p, inset=0.1) for p in poses])          # (n, 4, 2)
    solids = Solids.of(other_poses)
    seen = visible_in_view(feet, view.polygons, holes=view.holes, origin=(x, y, z_world),
                           mid_z=np.array([p.cz for p in poses]), occluders=solids, own=own)
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from twin.fusion.footprints import Pose, corners, points_in_polygon
from twin.records import FloatArray, ObservedView

__all__ = [
    "AREA_SAMPLE_M",
    "SIGHT_LINES",
    "Solids",
    "in_region",
    "inside_by_area",
    "line_of_sight",
    "view_sees",
    "visible_in_view",
]

BoolArray = npt.NDArray[np.bool_]
IndexArray = npt.NDArray[np.int64]

AREA_SAMPLE_M = 0.05
"""Where a boundary of the view crosses a footprint (several polygons meeting under it), the footprint
is sampled this densely (at most :data:`MAX_AREA_SAMPLES` a side)."""
MAX_AREA_SAMPLES = 64
SIGHT_LINES = 4
"""Sight lines per side of a footprint: ``SIGHT_LINES**2`` points at the cell centres of a grid over it."""
GRAZE_M = 1e-6
"""A sight line or an edge that only touches a box or footprint (within this) does not cross it."""
_CHUNK = 1 << 20
"""Point x edge pairs tested at once (memory bound)."""


@dataclass(frozen=True, slots=True)
class Solids:
    """Upright boxes that block sight lines: ``corners (m, 4, 2)`` footprints in the map frame, and
    ``zmin``, ``zmax`` ``(m,)`` world heights."""

    corners: FloatArray
    zmin: FloatArray
    zmax: FloatArray

    def __post_init__(self) -> None:
        m = len(self.corners)
        if self.corners.shape != (m, 4, 2) or self.zmin.shape != (m,) or self.zmax.shape != (m,):
            msg = (
                f"Solids need corners (m, 4, 2) and heights (m,), got {self.corners.shape}, "
                f"{self.zmin.shape}, {self.zmax.shape}."
            )
            raise ValueError(msg)

    @classmethod
    def of(cls, poses: Sequence[Pose]) -> Solids:
        """The boxes of ``poses`` (their whole footprints)."""
        if not poses:
            return cls(np.zeros((0, 4, 2)), np.zeros(0), np.zeros(0))
        return cls(
            np.stack([corners(p) for p in poses]),
            np.array([p.zmin for p in poses], dtype=np.float64),
            np.array([p.zmax for p in poses], dtype=np.float64),
        )

    def __len__(self) -> int:
        return len(self.corners)


def _rings(rings: Sequence[FloatArray]) -> list[FloatArray]:
    out = []
    for ring in rings:
        r = np.asarray(ring, dtype=np.float64)
        if r.ndim != 2 or r.shape[1] != 2 or len(r) < 3:
            msg = f"A view's ring must be (k >= 3, 2) x y points, got shape {r.shape}."
            raise ValueError(msg)
        out.append(r)
    return out


def in_region(
    points: FloatArray, polygons: Sequence[FloatArray], holes: Sequence[FloatArray] = ()
) -> BoolArray:
    """``(k,) bool``: which points lie in the union of ``polygons`` and in none of ``holes`` (each ring
    by the even-odd rule)."""
    k = len(points)
    out = np.zeros(k, dtype=bool)
    if k == 0:
        return out
    step = max(1, _CHUNK // max(1, max((len(r) for r in [*polygons, *holes]), default=1)))
    for lo in range(0, k, step):
        part = points[lo : lo + step]
        got = np.zeros(len(part), dtype=bool)
        for ring in polygons:
            left = ~got
            if left.any():
                got[left] = points_in_polygon(part[left], ring)
        for ring in holes:
            if got.any():
                got[got] = ~points_in_polygon(part[got], ring)
        out[lo : lo + step] = got
    return out


def _ccw(quads: FloatArray) -> FloatArray:
    """The quads with their corners counter-clockwise."""
    x, y = quads[..., 0], quads[..., 1]
    area2 = (x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y).sum(axis=1)
    return np.where((area2 < 0)[:, None, None], quads[:, ::-1], quads)


def _clip_interval(
    p0: FloatArray, d: FloatArray, quads: FloatArray, lo: FloatArray, hi: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Cyrus-Beck: the parameters ``t`` in ``(lo, hi)`` where ``p0 + t d`` lies in the open interior
    of each convex counter-clockwise quad (``p0``, ``d`` ``(k, 2)``, ``quads`` ``(k, 4, 2)``); empty
    when the returned ``lo >= hi``. A quad of no area has no interior (empty)."""
    a = quads
    e = np.roll(a, -1, axis=1) - a  # (k, 4, 2) edges
    length = np.hypot(e[..., 0], e[..., 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        nx = np.where(length > 0, -e[..., 1] / length, 0.0)  # inward (left) unit normals
        ny = np.where(length > 0, e[..., 0] / length, 0.0)
    num = nx * (p0[:, None, 0] - a[..., 0]) + ny * (p0[:, None, 1] - a[..., 1]) - GRAZE_M  # (k, 4)
    den = nx * d[:, None, 0] + ny * d[:, None, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -num / den
    lo = np.maximum(lo, np.where(den > 0, t, -np.inf).max(axis=1))
    hi = np.minimum(hi, np.where(den < 0, t, np.inf).min(axis=1))
    parallel_out = ((den == 0) & (num <= 0)).any(axis=1)
    hi = np.where(parallel_out, -np.inf, hi)
    return lo, hi


def _bounds(quads: FloatArray) -> FloatArray:
    """``(n, 4)``: xmin, ymin, xmax, ymax."""
    return np.concatenate([quads.min(axis=1), quads.max(axis=1)], axis=1)


def _boundary_crosses(quads: FloatArray, rings: Sequence[FloatArray]) -> BoolArray:
    """``(n,) bool``: whether an edge of any ring passes through the open interior of each quad."""
    n = len(quads)
    if n == 0 or not rings:
        return np.zeros(n, dtype=bool)
    a = np.concatenate(list(rings))
    b = np.concatenate([np.roll(r, -1, axis=0) for r in rings])
    qb = _bounds(quads)
    sb = np.concatenate([np.minimum(a, b), np.maximum(a, b)], axis=1)
    out = np.zeros(n, dtype=bool)
    step = max(1, _CHUNK // max(1, len(a)))
    for lo in range(0, n, step):
        q = qb[lo : lo + step]
        near = (
            (sb[None, :, 0] < q[:, None, 2])
            & (sb[None, :, 2] > q[:, None, 0])
            & (sb[None, :, 1] < q[:, None, 3])
            & (sb[None, :, 3] > q[:, None, 1])
        )
        qi, ei = np.nonzero(near)
        if len(qi) == 0:
            continue
        qi = qi + lo
        t_lo, t_hi = _clip_interval(a[ei], b[ei] - a[ei], quads[qi], np.zeros(len(qi)), np.ones(len(qi)))
        hit = t_lo < t_hi
        out[qi[hit]] = True
    return out


def _grid(quads: FloatArray, k: int) -> FloatArray:
    """``(n, k*k, 2)``: the cell centres of a ``k`` x ``k`` grid over each quad (bilinear in its corners)."""
    u = (np.arange(k) + 0.5) / k
    uu, vv = np.meshgrid(u, u, indexing="ij")
    uu, vv = uu.ravel()[None, :, None], vv.ravel()[None, :, None]
    c0, c1, c2, c3 = (quads[:, i][:, None, :] for i in range(4))
    return np.asarray((1 - uu) * (1 - vv) * c0 + uu * (1 - vv) * c1 + uu * vv * c2 + (1 - uu) * vv * c3)


def inside_by_area(
    footprints: FloatArray, polygons: Sequence[FloatArray], holes: Sequence[FloatArray] = ()
) -> BoolArray:
    """``(n,) bool``: which footprints ``(n, 4, 2)`` (convex quads) lie wholly inside the union of
    ``polygons`` less ``holes`` (see the module's docstring)."""
    quads = np.asarray(footprints, dtype=np.float64)
    n = len(quads)
    if quads.shape != (n, 4, 2):
        msg = f"Footprints must be (n, 4, 2) corners, got shape {quads.shape}."
        raise ValueError(msg)
    polys, gaps = _rings(polygons), _rings(holes)
    if n == 0 or not polys:
        return np.zeros(n, dtype=bool)
    quads = _ccw(quads)
    rings = [*polys, *gaps]
    crossed = _boundary_crosses(quads, rings)
    probe = np.concatenate([quads, quads.mean(axis=1, keepdims=True)], axis=1)  # corners and centre
    out: BoolArray = np.asarray(in_region(probe.reshape(-1, 2), polys, gaps).reshape(n, 5).all(axis=1))
    if len(rings) == 1:  # a boundary of the only ring through the interior: part of it is outside
        return np.asarray(out & ~crossed)
    check = np.nonzero(out & crossed)[0]
    if len(check):
        sides = (
            np.hypot(*(quads[check, 1] - quads[check, 0]).T),
            np.hypot(*(quads[check, 3] - quads[check, 0]).T),
        )
        k = int(min(MAX_AREA_SAMPLES, max(2, math.ceil(max(sides[0].max(), sides[1].max()) / AREA_SAMPLE_M))))
        points = _grid(quads[check], k)
        out[check] = in_region(points.reshape(-1, 2), polys, gaps).reshape(len(check), -1).all(axis=1)
    return out


def line_of_sight(
    footprints: FloatArray,
    mid_z: FloatArray,
    origin: tuple[float, float, float],
    occluders: Solids,
    *,
    own: IndexArray | None = None,
) -> BoolArray:
    """``(n,) bool``: whether every sight line from ``origin`` (x, y, z world) to the grid of
    ``SIGHT_LINES**2`` points over each footprint ``(n, 4, 2)``, at its ``mid_z`` ``(n,)``, passes
    clear of the ``occluders`` (``own[i]``: the row of footprint ``i``'s own box in them, -1 none)
    until it reaches the element's own footprint (its box in ``occluders``, else the one given): what
    overlaps an element hides it only from the side it stands on."""
    quads = np.asarray(footprints, dtype=np.float64)
    n = len(quads)
    if quads.shape != (n, 4, 2) or np.shape(mid_z) != (n,):
        msg = (
            f"line_of_sight needs footprints (n, 4, 2) and mid_z (n,), got {quads.shape}, {np.shape(mid_z)}."
        )
        raise ValueError(msg)
    out = np.ones(n, dtype=bool)
    if n == 0 or len(occluders) == 0:
        return out
    ox, oy, oz = (float(v) for v in origin)
    g = SIGHT_LINES * SIGHT_LINES
    ends = _grid(quads, SIGHT_LINES).reshape(-1, 2)  # (n*g, 2)
    ez = np.repeat(np.asarray(mid_z, dtype=np.float64), g)
    target = np.repeat(np.arange(n), g)
    mine = np.repeat(np.full(n, -1) if own is None else np.asarray(own), g)
    boxes = _ccw(occluders.corners)
    ob = _bounds(boxes)
    feet = _ccw(quads)
    whole = np.where((mine >= 0)[:, None, None], boxes[np.maximum(mine, 0)], np.repeat(feet, g, axis=0))
    start = np.broadcast_to(np.array([ox, oy]), (len(ends), 2))
    reach, _ = _clip_interval(start, ends - start, whole, np.zeros(len(ends)), np.ones(len(ends)))
    reach = np.clip(reach, 0.0, 1.0)  # where each sight line enters the element's footprint
    sx0, sx1 = np.minimum(ox, ends[:, 0]), np.maximum(ox, ends[:, 0])
    sy0, sy1 = np.minimum(oy, ends[:, 1]), np.maximum(oy, ends[:, 1])
    blocked = np.zeros(len(ends), dtype=bool)
    step = max(1, _CHUNK // max(1, len(boxes)))
    for lo in range(0, len(ends), step):
        sl = slice(lo, lo + step)
        near = (
            (ob[None, :, 0] < sx1[sl, None])
            & (ob[None, :, 2] > sx0[sl, None])
            & (ob[None, :, 1] < sy1[sl, None])
            & (ob[None, :, 3] > sy0[sl, None])
            & (np.arange(len(boxes))[None, :] != mine[sl, None])
        )
        si, bi = np.nonzero(near)
        if len(si) == 0:
            continue
        si = si + lo
        p0 = np.broadcast_to(np.array([ox, oy]), (len(si), 2))
        d = ends[si] - p0
        dz = ez[si] - oz
        # the z slab: oz + t dz strictly between the box's zmin and zmax
        zlo, zhi = occluders.zmin[bi] + GRAZE_M, occluders.zmax[bi] - GRAZE_M
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (zlo - oz) / dz, (zhi - oz) / dz
        flat = dz == 0
        t_lo = np.where(flat, np.where((oz > zlo) & (oz < zhi), 0.0, np.inf), np.minimum(ta, tb))
        t_hi = np.where(flat, np.where((oz > zlo) & (oz < zhi), 1.0, -np.inf), np.maximum(ta, tb))
        t_lo, t_hi = _clip_interval(p0, d, boxes[bi], np.maximum(t_lo, 0.0), np.minimum(t_hi, reach[si]))
        hit = t_lo < t_hi
        blocked[si[hit]] = True
    out[np.unique(target[blocked])] = False
    return out


def visible_in_view(
    footprints: FloatArray,
    polygons: Sequence[FloatArray],
    *,
    holes: Sequence[FloatArray] = (),
    origin: tuple[float, float, float] | None = None,
    mid_z: FloatArray | None = None,
    occluders: Solids | None = None,
    own: IndexArray | None = None,
) -> BoolArray:
    """``(n,) bool``: which elements a view should have seen (a miss if it did not).

    Args:
        footprints: ``(n, 4, 2)`` the candidates' inset footprints (map frame).
        polygons, holes: the view's region (its union of polygons less its holes).
        origin: the sensor's position (x, y, world z), or None: the region is taken as given.
        mid_z: ``(n,)`` the candidates' mid-heights (world z; needed with an origin).
        occluders: what stands in the way of sight lines (needed with an origin).
        own: ``(n,)`` each candidate's row in ``occluders`` (-1: none).
    """
    seen = inside_by_area(footprints, polygons, holes)
    if origin is not None and occluders is not None and seen.any():
        if mid_z is None:
            msg = "visible_in_view with an origin needs the candidates' mid_z."
            raise ValueError(msg)
        idx = np.nonzero(seen)[0]
        mine = None if own is None else np.asarray(own)[idx]
        seen[idx] = line_of_sight(
            np.asarray(footprints)[idx], np.asarray(mid_z)[idx], origin, occluders, own=mine
        )
    return seen


def view_sees(
    view: ObservedView,
    poses: Sequence[Pose],
    *,
    iris: Sequence[str],
    held: Mapping[str, Pose],
    sightings: Sequence[Pose] = (),
    elevation_m: float,
    inset_m: float,
) -> list[bool]:
    """Which elements (``poses``, named ``iris``) ``view`` should have seen: :func:`visible_in_view`
    with their footprints ``inset_m`` smaller on each side, and with the view's origin (``twin:origin``,
    z above ``elevation_m``, the storey's) past the elements ``held`` on the storey (by IRI; each
    element's own pose among them is its own) and the boxes ``sightings`` reported with the view.
    Only elements and occluders near the view's polygons (and its origin) are looked at."""
    n = len(poses)
    if n == 0:
        return []
    ring = np.concatenate(view.polygons)
    lo, hi = ring.min(axis=0), ring.max(axis=0)

    def near(p: Pose) -> bool:
        r = (p.sx + p.sy) / 2  # at least half the diagonal
        return bool(lo[0] - r <= p.cx <= hi[0] + r and lo[1] - r <= p.cy <= hi[1] + r)

    picked = [i for i, p in enumerate(poses) if near(p)]
    seen = np.zeros(n, dtype=bool)
    if not picked:
        return [False] * n
    origin, occluders, own = None, None, None
    if view.origin is not None:
        x, y, z = view.origin
        origin = (x, y, elevation_m + z)
        lo, hi = np.minimum(lo, (x, y)), np.maximum(hi, (x, y))  # what may stand between
        between = [(iri, p) for iri, p in held.items() if near(p)]
        rows = {iri: i for i, (iri, _) in enumerate(between)}
        occluders = Solids.of([p for _, p in between] + list(sightings))
        own = np.array([rows.get(iris[i], -1) for i in picked], dtype=np.int64)
    seen[picked] = visible_in_view(
        np.stack([corners(poses[i], inset=inset_m) for i in picked]),
        view.polygons,
        holes=view.holes,
        origin=origin,
        mid_z=np.array([poses[i].cz for i in picked]),
        occluders=occluders,
        own=own,
    )
    return [bool(v) for v in seen]
