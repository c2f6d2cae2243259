"""Point-cloud maps for 3D lidars: one point per voxel the selected surfaces touch, in a storey's band.

A ``points`` skill (:mod:`twin.selection.skills`) selects elements like the 2D skills do. Its map of a
storey is the set of voxels (cubes of ``resolution_m``, half-open) that the selected elements' triangles
touch within the height band (from ``band_bottom_m`` to ``band_top_m`` above the storey's elevation, by
default from just below the floor's top to the next storey's elevation): the 3D analogue of the 2D rule,
so thin elements never vanish and touching elements leave no gaps. The touch test is exact
(:mod:`twin.maps.voxels`), on coordinates whose grid planes are decided in world metres (within 1 um of
a plane is on it: :func:`twin.maps.grid.grid_coordinates`), against the voxel with its lower faces moved
out by 3.1 nm and its upper faces in by 0.5 um (``TOLERANCES.voxel_out_m``, ``voxel_in_m``: a slanted
surface through a voxel's edge, its vertices off the grid, is then decided by its geometry, not by its
vertices' rounding), so the voxels do not depend on where the building sits. Each voxel holds one
point: the point of the selected surfaces nearest the voxel's centre within the voxel's *closed* box (a
centre would bias the cloud by up to half a voxel; the point may lie on the box's boundary, its upper
faces included, which the half-open voxel does not hold), with the unit normal of the triangle it lies
on, oriented by the triangle's winding (outward: the importer turns every closed shell outward; float32,
rounded to 2**-20; taken from the element's local mesh, :attr:`MeshSet.normals`, so that the building's
position does not round it). Ties (a point on an edge or vertex several triangles
share, or equal points of several elements) go to the smallest point, then to the smallest normal (x,
then y, then z; a degenerate triangle's zero normal last), distances and points compared rounded to
2**-20 of a voxel, then to the nearest exactly (two elements' surfaces a nanometre apart), then to the
smallest point exactly (:func:`best_rows`), so the cloud depends neither on the order triangles and
elements are processed in (incremental updates equal a full rebuild voxel for voxel, normals included)
nor on float noise.

Frames: the voxels' x, y are the cells of the storey's 2D maps at this resolution (same origin, the
``map`` frame); z is metres above the storey's elevation, voxel layer ``k`` covering
``[k*res, (k+1)*res)``. Voxel ``(col, row, k)`` has the key ``((k - k_lo) * rows + row) * cols + col``;
clouds are sorted by key.

Example::

    plan = plan_points(scene, skill, "ground-floor", iris, margin_m=1.0)
    cloud = build_points(scene, plan)   # keys, xyz: x, y in the map frame, z above the storey; normals
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from twin.errors import MapError
from twin.maps.grid import GridFrame, grid_coordinates, grid_units
from twin.maps.nearest import distance_to_centres, nearest_points_of
from twin.maps.scene import IndexArray, MeshSet, Scene, StoreyInfo, unit_normals
from twin.maps.voxels import FloatArray, IntArray, touched_pairs
from twin.selection.skills import SkillProfile
from twin.tolerances import TOLERANCES

__all__ = [
    "MAX_POINTS_VOXELS",
    "PointCloud",
    "PointsPlan",
    "Voxels",
    "best_per_voxel",
    "best_rows",
    "build_points",
    "cloud_of",
    "estimate_points",
    "plan_points",
    "sorted_unique",
    "triangle_normals",
    "voxels_by_element",
    "voxels_of",
]

_CHUNK = 100_000
"""Pairs whose nearest points are computed at once (bounds the temporaries to ~100 MB)."""
_SHARED_VOXELS = 1.25
"""Surfaces closer than a voxel (a slab's faces, a covering on a slab, walls that touch) share voxels,
which a sum of areas counts twice: on the sample lab and the shared models the sum is 1.04 to 2.4 times
the built count (more at coarse voxels, and with furniture), so :func:`estimate_points` divides by this."""
MAX_POINTS_VOXELS = 2**62
"""Keys are int64: a points map's frame (columns x rows x layers) must have fewer voxels."""


@dataclass(frozen=True, eq=False, slots=True)
class PointsPlan:
    """One (storey, points skill) map: the 2D frame, the band, the selected elements."""

    skill: SkillProfile
    storey: StoreyInfo
    frame: GridFrame
    band: tuple[float, float]
    """``[bottom, top)`` metres above the storey's elevation."""
    selected: IndexArray

    @property
    def resolution_m(self) -> float:
        return self.frame.resolution_m

    @property
    def w_band(self) -> tuple[float, float]:
        """The band in cell units of z (above the elevation); an end within 1 um of a layer's plane is
        on it (``grid_units``)."""
        return (grid_units(self.band[0], self.resolution_m), grid_units(self.band[1], self.resolution_m))

    @property
    def layers(self) -> tuple[int, int]:
        """``[k_lo, k_hi)``: the voxel layers the band cuts."""
        w_lo, w_hi = self.w_band
        return math.floor(w_lo), math.ceil(w_hi)

    @property
    def lo(self) -> tuple[int, int, int]:
        return (0, 0, self.layers[0])

    @property
    def hi(self) -> tuple[int, int, int]:
        return (self.frame.width, self.frame.height, self.layers[1])

    @property
    def world_band(self) -> tuple[float, float]:
        e = self.storey.elevation_m
        return (e + self.band[0], e + self.band[1])

    def cells(self, triangles: FloatArray) -> FloatArray:
        """World triangles ``(n, 3, 3)`` in cell coordinates (the voxels' units; see
        :mod:`twin.maps.voxels`), grid planes and the band's ends decided in world metres
        (:func:`twin.maps.grid.grid_coordinates`: within 1 um of one is on it)."""
        out = np.empty_like(triangles, dtype=np.float64)
        res = self.resolution_m
        out[..., 0] = grid_coordinates(triangles[..., 0], self.frame.origin_x, res)
        out[..., 1] = grid_coordinates(triangles[..., 1], self.frame.origin_y, res)
        out[..., 2] = grid_coordinates(triangles[..., 2], self.storey.elevation_m, res, ends=self.band)
        return out

    @property
    def shift(self) -> tuple[float, float]:
        """How far the voxels' lower faces move out and their upper faces in for the touch test, cell
        units (``TOLERANCES.voxel_out_m``, ``voxel_in_m``: see :func:`twin.maps.voxels.touched_pairs`)."""
        res = self.resolution_m
        return (TOLERANCES.voxel_out_m / res, TOLERANCES.voxel_in_m / res)

    def keys(self, ijk: IntArray) -> IntArray:
        k_lo = self.layers[0]
        return np.asarray(((ijk[:, 2] - k_lo) * self.frame.height + ijk[:, 1]) * self.frame.width + ijk[:, 0])

    def ijk(self, keys: IntArray) -> IntArray:
        w, h = self.frame.width, self.frame.height
        out = np.empty((len(keys), 3), dtype=np.int64)
        out[:, 0] = keys % w
        out[:, 1] = (keys // w) % h
        out[:, 2] = keys // (w * h) + self.layers[0]
        return out

    def distance(self, keys: IntArray, q: FloatArray) -> FloatArray:
        """Points ``q`` (cell coordinates) in voxels ``keys``: their squared distances to the voxels'
        centres (cell units; the numbers the voxelisation gives)."""
        return distance_to_centres(q, self.ijk(keys), w_band=self.w_band)

    def to_xyz(self, q: FloatArray) -> FloatArray:
        """Cell coordinates to map-frame metres: world x, y; z above the storey's elevation."""
        res = self.resolution_m
        out = np.empty_like(q)
        out[:, 0] = self.frame.origin_x + q[:, 0] * res
        out[:, 1] = self.frame.origin_y + q[:, 1] * res
        out[:, 2] = q[:, 2] * res
        return out


def _band_top(scene: Scene, storey: StoreyInfo, res: float) -> float:
    above = [s.elevation_m for s in scene.storeys if s.elevation_m > storey.elevation_m]
    if above:
        return min(above) - storey.elevation_m
    b = scene.elements.bounds
    b = b[~np.isnan(b).any(axis=1)]
    top = float(b[:, 5].max()) if len(b) else storey.elevation_m
    return max(top - storey.elevation_m, 0.0) + res  # the top storey: the model's top is in


def plan_points(
    scene: Scene, skill: SkillProfile, storey_key: str, element_iris: Sequence[str], *, margin_m: float = 1.0
) -> PointsPlan:
    """Fix the frame (the storey's 2D map frame at the skill's resolution), the band and the elements."""
    if skill.kind != "points":
        msg = f"Skill {skill.name!r} is a {skill.kind} skill, not a points skill."
        raise MapError(msg)
    storey = scene.storey(storey_key)
    xmin, ymin, xmax, ymax = storey.extent
    frame = GridFrame.around(xmin, ymin, xmax, ymax, resolution_m=skill.resolution_m, margin_m=margin_m)
    top = skill.band_top_m if skill.band_top_m is not None else _band_top(scene, storey, skill.resolution_m)
    if top <= skill.band_bottom_m:
        msg = (
            f"Skill {skill.name!r}: storey {storey_key!r} has an empty band ({skill.band_bottom_m} to "
            f"{top} m): the next storey is at or below its bottom; set band_top_m."
        )
        raise MapError(msg)
    selected = scene.elements.indices_of(tuple(element_iris))
    plan = PointsPlan(skill, storey, frame, (skill.band_bottom_m, top), selected)
    k_lo, k_hi = plan.layers
    if frame.width * frame.height * (k_hi - k_lo) >= MAX_POINTS_VOXELS:
        msg = (
            f"Skill {skill.name!r}: resolution_m={skill.resolution_m} gives too many voxels for storey "
            f"{storey_key!r}; use a coarser resolution."
        )
        raise MapError(msg)
    return plan


Float32Array = npt.NDArray[np.float32]


@dataclass(frozen=True, eq=False, slots=True)
class Voxels:
    """Touched voxels and their points: ``keys (n,)`` sorted, unique; ``q (n, 3)`` the point in cell
    coordinates; ``d2 (n,)`` its squared distance to the voxel's centre (cell units); ``n (n, 3)
    float32`` the unit normal of the triangle the point lies on (zero for a degenerate triangle)."""

    keys: IntArray
    q: FloatArray
    d2: FloatArray
    n: Float32Array

    @classmethod
    def empty(cls) -> Voxels:
        f32 = np.empty((0, 3), dtype=np.float32)
        return cls(np.empty(0, dtype=np.int64), np.empty((0, 3)), np.empty(0), f32)

    def __len__(self) -> int:
        return len(self.keys)

    def take(self, rows: IntArray | npt.NDArray[np.bool_] | slice) -> Voxels:
        return Voxels(self.keys[rows], self.q[rows], self.d2[rows], self.n[rows])

    @classmethod
    def concat(cls, parts: Sequence[Voxels]) -> Voxels:
        if not parts:
            return cls.empty()
        return cls(
            np.concatenate([p.keys for p in parts]),
            np.concatenate([p.q for p in parts]),
            np.concatenate([p.d2 for p in parts]),
            np.concatenate([p.n for p in parts]),
        )


def triangle_normals(triangles: FloatArray) -> Float32Array:
    """The unit normals ``(n, 3) float32`` of triangles ``(n, 3, 3)``, by their winding (right hand:
    ``(b - a) x (c - a)``); zero for a triangle of no area; components rounded to multiples of 2**-20
    (:func:`twin.maps.scene.unit_normals`). Scenes carry their triangles' normals from the local meshes
    (:attr:`MeshSet.normals`), which the building's position does not round; this is for loose triangles."""
    t = np.asarray(triangles, dtype=np.float64)
    u, v = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    c = np.empty((len(t), 3))
    c[:, 0] = u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1]
    c[:, 1] = u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2]
    c[:, 2] = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    return unit_normals(c)


def sorted_unique(keys: IntArray) -> IntArray:
    """``keys`` sorted, each once (by sorting: numpy's hashing ``unique`` is slower here; a stable sort
    merges runs already sorted, as concatenated voxel sets are)."""
    s = np.sort(keys, kind="stable")
    if len(s) < 2:
        return s
    first = np.ones(len(s), dtype=np.bool_)
    first[1:] = s[1:] != s[:-1]
    return s[first]


def _quantised(values: FloatArray) -> IntArray:
    """Values in voxels (squared distances, points) rounded to ``TOLERANCES.point_quantum``: the ranks
    ties are decided by (float noise of a few ulp does not change them)."""
    out: IntArray = np.rint(values / TOLERANCES.point_quantum).astype(np.int64)
    return out


def best_rows(
    keys: IntArray, q: FloatArray, d2: FloatArray, normals: Float32Array, owner: IndexArray | None = None
) -> IntArray:
    """The row of each key's best point, one per key, in the order of the keys; with ``owner``, one per
    (owner, key), in that order.

    The order is total and on quantised values (:data:`TOLERANCES.point_quantum` of a voxel), so that
    the points of a voxel that are equal but for rounding (one point of an edge two triangles share,
    a building moved by whole voxels) are ranked by what they are, not by their noise: the smallest
    squared distance to the voxel's centre, then the smallest point (x, y, z), then the smallest normal
    (x, y, z; zero normals last), then the exact values (distance, then point: two elements' surfaces a
    nanometre apart are told apart by their distance, which their rounding does not reach, where the
    exact points' first coordinate may be equal but for rounding)."""
    n = len(keys)
    if n < 2:
        return np.arange(n, dtype=np.int64)
    order = np.argsort(keys, kind="stable") if owner is None else np.lexsort((keys, owner))
    k = keys[order]
    first = np.ones(n, dtype=np.bool_)
    first[1:] = k[1:] != k[:-1]
    if owner is not None:
        o = owner[order]
        first[1:] |= o[1:] != o[:-1]
    starts = np.flatnonzero(first)
    if len(starts) == n:
        return order.astype(np.int64)
    dk = _quantised(d2[order])
    group = np.cumsum(first) - 1
    at_min = dk == np.minimum.reduceat(dk, starts)[group]
    # the first row at the minimum of each group; groups with two rows at it are tie-broken by the point
    pick = order[at_min]
    g = group[at_min]
    lead = np.ones(len(g), dtype=np.bool_)
    lead[1:] = g[1:] != g[:-1]
    tied = np.zeros(len(g), dtype=np.bool_)
    tied[1:] = ~lead[1:]
    if not tied.any():
        out: IntArray = pick[lead].astype(np.int64)
        return out
    tied_group = np.zeros(len(starts), dtype=np.bool_)
    tied_group[g[tied]] = True
    in_tie = tied_group[g]
    sub = pick[in_tie]
    sub_g = g[in_tie]
    ns = normals[sub]
    zero = ~ns.any(axis=1)
    qs, rq = q[sub], _quantised(q[sub])
    ranks = (qs[:, 2], qs[:, 1], qs[:, 0], d2[sub], ns[:, 2], ns[:, 1], ns[:, 0], zero)
    sub = sub[np.lexsort((*ranks, rq[:, 2], rq[:, 1], rq[:, 0], sub_g))]
    sg = np.sort(sub_g)
    keep = np.ones(len(sub), dtype=np.bool_)
    keep[1:] = sg[1:] != sg[:-1]
    out = pick[lead].astype(np.int64)  # one per group, in group order
    out[tied_group] = sub[keep]
    return out


def best_per_voxel(v: Voxels) -> Voxels:
    """One point per key: the nearest the voxel's centre, ties to the smallest (x, y, z), then normal
    (compared quantised: :func:`best_rows`); sorted by key."""
    if not len(v):
        return v
    return v.take(best_rows(v.keys, v.q, v.d2, v.n))


def _pairs(
    plan: PointsPlan, triangles: FloatArray, normals: Float32Array | None = None
) -> tuple[IntArray, Voxels]:
    """Every touching (triangle, voxel) pair of world ``triangles`` with the pair's point and its
    triangle's normal (from ``normals``, else from the world triangles)."""
    if not len(triangles):
        return np.empty(0, dtype=np.int64), Voxels.empty()
    cells = plan.cells(triangles)
    tri, ijk, hint = touched_pairs(cells, lo=plan.lo, hi=plan.hi, w_band=plan.w_band, shift=plan.shift)
    q = np.empty((len(tri), 3))
    d2 = np.empty(len(tri))
    for s in range(0, len(tri), _CHUNK):  # element-wise: the same values in any chunks, less memory
        e = s + _CHUNK
        q[s:e], d2[s:e] = nearest_points_of(cells, tri[s:e], ijk[s:e], w_band=plan.w_band, hint=hint[s:e])
    n = normals[tri] if normals is not None else triangle_normals(triangles[tri])
    return tri, Voxels(plan.keys(ijk), q, d2, n)


def _near_band(meshes: MeshSet, ids: IndexArray, plan: PointsPlan) -> tuple[FloatArray, IndexArray]:
    """The triangles of ``ids`` whose bounds meet the frame and the band, and their owner (into ids)."""
    rows, owner = _near_band_rows(meshes, ids, plan)
    return meshes.triangles[rows], owner


def _near_band_rows(meshes: MeshSet, ids: IndexArray, plan: PointsPlan) -> tuple[IndexArray, IndexArray]:
    """The rows of :func:`_near_band`'s triangles in ``meshes``, and their owner (into ids)."""
    rows, owner = meshes._rows_of(ids)
    tb = meshes.triangle_bounds[rows]
    f = plan.frame
    z_lo, z_hi = plan.world_band
    g = TOLERANCES.grid_m  # (a vertex that near a bound may be on it)
    keep = (
        (tb[:, 0] <= f.origin_x + f.width * f.resolution_m + g)
        & (tb[:, 3] >= f.origin_x - g)
        & (tb[:, 1] <= f.origin_y + f.height * f.resolution_m + g)
        & (tb[:, 4] >= f.origin_y - g)
        & (tb[:, 2] <= z_hi + g)
        & (tb[:, 5] >= z_lo - g)
    )
    return rows[keep], owner[keep]


def _normals_of(meshes: MeshSet, rows: IndexArray) -> Float32Array | None:
    return meshes.normals[rows] if meshes.normals is not None else None


def estimate_points(scene: Scene, plan: PointsPlan) -> int:
    """About how many points ``plan``'s cloud has, from its selected triangles' area, before building it
    (milliseconds): a plane of area ``A`` and unit normal ``n`` crosses about ``A (|nx| + |ny| + |nz|)
    / res**2`` voxels, each triangle's area counted for the part of its height within the band, each
    element's sum at most the voxels of its bounding box in the band (a chair's many faces share few
    voxels), divided by :data:`_SHARED_VOXELS`. Within a factor of 2 of the built count on the sample lab
    and the shared models (0.83 to 1.93 times it at 0.05 to 0.2 m)."""
    triangles, owner = _near_band(scene.elements, plan.selected, plan)
    if not len(triangles):
        return 0
    res = plan.resolution_m
    e = plan.storey.elevation_m
    lo, hi = e + plan.band[0], e + plan.band[1]
    u, v = triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    crossed = 0.5 * np.abs(np.cross(u, v)).sum(axis=1)  # the area times (|nx| + |ny| + |nz|)
    z = triangles[:, :, 2]
    z0, z1 = z.min(axis=1), z.max(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        part = np.where(z1 > z0, (np.minimum(z1, hi) - np.maximum(z0, lo)) / (z1 - z0), 1.0)
    inside = (z1 >= lo) & (z0 < hi)
    voxels = np.maximum(crossed * np.clip(part, 0.0, 1.0) * inside / res**2, inside)
    n = int(owner.max()) + 1
    per_element = np.bincount(owner, weights=voxels, minlength=n)
    b_lo = np.full((n, 3), np.inf)
    b_hi = np.full((n, 3), -np.inf)
    np.minimum.at(b_lo, owner, triangles.min(axis=1))
    np.maximum.at(b_hi, owner, triangles.max(axis=1))
    b_lo[:, 2], b_hi[:, 2] = np.maximum(b_lo[:, 2], lo), np.minimum(b_hi[:, 2], hi)
    box = np.prod(np.floor(np.maximum(b_hi - b_lo, 0.0) / res) + 2, axis=1)
    return int(np.minimum(per_element, box).sum() / _SHARED_VOXELS)


def voxels_of(plan: PointsPlan, triangles: FloatArray) -> Voxels:
    """The voxels a set of world triangles (one element, or many) touches, one point each."""
    _, v = _pairs(plan, triangles)
    return best_per_voxel(v)


def voxels_by_element(meshes: MeshSet, ids: IndexArray, plan: PointsPlan) -> list[Voxels]:
    """Per element of ``ids`` (in that order): its own voxels (what the live maps keep per element)."""
    rows, owner = _near_band_rows(meshes, ids, plan)
    tri, v = _pairs(plan, meshes.triangles[rows], _normals_of(meshes, rows))
    out = [Voxels.empty() for _ in ids]
    if not len(v):
        return out
    own = owner[tri]
    rows = best_rows(v.keys, v.q, v.d2, v.n, own if len(ids) > 1 else None)
    own, v = own[rows], v.take(rows)
    bounds = np.searchsorted(own, np.arange(len(ids) + 1))
    for i in range(len(ids)):
        if bounds[i + 1] > bounds[i]:
            out[i] = v.take(slice(bounds[i], bounds[i + 1]))
    return out


@dataclass(frozen=True, eq=False, slots=True)
class PointCloud:
    """A points map: ``xyz (n, 3) float64`` (x, y in the map frame, z above the storey's elevation),
    one per touched voxel, sorted by the voxels' ``keys``; ``normals (n, 3) float32``: each point's
    surface normal (unit, outward for closed shells; zero where the surface is degenerate)."""

    storey: str
    skill: str
    elevation_m: float
    resolution_m: float
    frame: GridFrame
    keys: IntArray
    xyz: FloatArray
    normals: Float32Array

    def __len__(self) -> int:
        return len(self.keys)


def cloud_of(plan: PointsPlan, v: Voxels) -> PointCloud:
    """The cloud of a plan's voxels (one point per key, sorted)."""
    return PointCloud(
        storey=plan.storey.key,
        skill=plan.skill.name,
        elevation_m=plan.storey.elevation_m,
        resolution_m=plan.resolution_m,
        frame=plan.frame,
        keys=v.keys,
        xyz=plan.to_xyz(v.q),
        normals=v.n,
    )


def build_points(scene: Scene, plan: PointsPlan) -> PointCloud:
    """The full points map of ``plan``, from the selected elements' triangles."""
    rows, _ = _near_band_rows(scene.elements, plan.selected, plan)
    _, v = _pairs(plan, scene.elements.triangles[rows], _normals_of(scene.elements, rows))
    return cloud_of(plan, best_per_voxel(v))
