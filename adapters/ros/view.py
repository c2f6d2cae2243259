"""The floor a camera saw: its field of view on the floor at the heights of what it detects, cut by the
building's structure and by the shadows of what it detected.

A camera (:class:`Camera`: its pose in the map frame from TF, pitch and roll included; its horizontal
and vertical field of view; its range and near blind zone) sees an object standing at a point of the
floor when its frustum holds the object's band of heights there (``band_m``, e.g. 0.1 to 0.5 m
above the floor): both the band's bottom and its top must be in the frame, no nearer than ``near_m``
and no farther than ``range_m`` (horizontal distances from the sensor). A camera pitched down thus
does not claim the floor just in front of it (under its frame), nor the floor beyond where the band's
top leaves its frame.

Rays fan out from the sensor's position over the bearings the frustum covers (found on a coarse
1-degree pass, then a cell apart at full range, at least ``rays`` per field of view): along each, at
half a cell's step, the floor it claims runs from the first sample in the frustum to the last
contiguous one, and stops short of the first occupied cell of the structure grid (e.g. the
localization map) or the grid's edge, and of the footprint of every box in ``shadows`` (each
detection of the array, of any class: what stands behind a person is not seen). Each ray then claims
no farther and no nearer than its neighbours (conservative between rays), and runs of rays of one
reach keep only their ends and a ray every 22.5° (the chord lies inside). Each run of rays that claim
something is one polygon: the far ends in angular order, then the near ends back (or the sensor's
position when the camera has neither a blind zone nor a vertical limit and the run starts at its
first cell); a full circle with a blind zone is a ring and its hole.
Everything at once in numpy: ``(rays, samples)``.

Example::

    cam = Camera.from_pose(map_from_sensor, optical=True, hfov_rad=1.5, vfov_rad=1.0, range_m=6.0)
    seen = camera_view(grid, cam, band_m=(0.1, 0.5), shadows=[(3.0, 1.0, 0.5, 0.4, 0.0)])
    seen.polygons, seen.holes      # map frame, metres
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from twin.maps.grid import OccupancyGrid

__all__ = [
    "OCCUPIED_AT",
    "Camera",
    "FloorView",
    "Structure",
    "ViewCache",
    "camera_view",
    "polygon_area",
    "visibility_polygon",
]

Point = tuple[float, float]
Ring = tuple[Point, ...]
FloatArray = npt.NDArray[np.float64]
MAX_RAYS = 4096
"""At most this many rays, however wide and long the view."""
MAX_CHORD_RAD = math.pi / 8
"""Merged rays span at most this angle (the chord of a 5 m arc over it is 10 cm inside)."""
OCCUPIED_AT = 50
"""Cells at or above this value block a ray (``nav_msgs/OccupancyGrid``: 100 occupied, 0 free)."""
BLOCK = 4
"""A pinhole camera's rays are first sampled a few cells apart against blocks of this many cells a
side (:class:`Structure`'s ``near``), and marched sample by sample only from where structure may be."""
COARSE_BEARINGS = 360
COARSE_SAMPLES = 48
MIN_AREA_M2 = 1e-2
"""A view smaller than this claims nothing."""


@dataclass(frozen=True, slots=True)
class Camera:
    """A sensor in the map frame: its ``position`` (z in the same frame as the band's heights), its
    unit axes ``forward``, ``right`` and ``down``, its fields of view (``vfov_rad`` None: no vertical
    limit), ``range_m`` and the near blind zone ``near_m`` (horizontal distances)."""

    position: tuple[float, float, float]
    forward: tuple[float, float, float]
    right: tuple[float, float, float]
    down: tuple[float, float, float]
    hfov_rad: float
    vfov_rad: float | None
    range_m: float
    near_m: float = 0.0

    @classmethod
    def from_pose(
        cls,
        map_from_sensor: FloatArray,
        *,
        optical: bool,
        hfov_rad: float,
        vfov_rad: float | None = None,
        range_m: float,
        near_m: float = 0.0,
        z_offset_m: float = 0.0,
    ) -> Camera:
        """The camera of a sensor frame: ``optical`` (z forward, x right, y down: REP 103's camera
        optical frame) or not (x forward, y left, z up); ``z_offset_m`` is subtracted from its z."""
        r = np.asarray(map_from_sensor, dtype=np.float64)[:3, :3]
        if optical:
            forward, right, down = r[:, 2], r[:, 0], r[:, 1]
        else:
            forward, right, down = r[:, 0], -r[:, 1], -r[:, 2]
        x, y, z = (float(v) for v in map_from_sensor[:3, 3])

        def vec(v: FloatArray) -> tuple[float, float, float]:
            return (float(v[0]), float(v[1]), float(v[2]))

        return cls(
            (x, y, z - z_offset_m), vec(forward), vec(right), vec(down), hfov_rad, vfov_rad, range_m, near_m
        )

    def sees(self, x: FloatArray, y: FloatArray, z: float) -> npt.NDArray[np.bool_]:
        """Which points ``(x, y)`` at height ``z`` lie in the field of view (distance limits apart)."""
        px, py, pz = self.position
        vx, vy, vz = x - px, y - py, z - pz
        f, r, d = self.forward, self.right, self.down
        a = vx * f[0] + vy * f[1] + vz * f[2]
        b = vx * r[0] + vy * r[1] + vz * r[2]
        c = vx * d[0] + vy * d[1] + vz * d[2]
        h = self.hfov_rad / 2
        pinhole = self.hfov_rad < math.pi
        if pinhole:
            ok = (a > 0) & (np.abs(b) <= a * math.tan(h))
        elif self.hfov_rad >= 2 * math.pi - 1e-9:
            ok = np.ones(np.shape(a), dtype=bool)
        else:
            ok = np.abs(np.arctan2(b, a)) <= h
        if self.vfov_rad is not None:
            v = self.vfov_rad / 2
            if pinhole:
                ok &= np.abs(c) <= a * math.tan(v)
            else:
                ok &= np.abs(np.arctan2(c, np.hypot(a, b))) <= v
        return np.asarray(ok)


@dataclass(frozen=True, eq=False, slots=True)
class Structure:
    """A structure grid as rays march it: which cells block (at or above :data:`OCCUPIED_AT`), flat,
    with a border of blocking cells round the grid (a ray that leaves the grid stops at its edge)."""

    grid: OccupancyGrid
    blocked: npt.NDArray[np.bool_]
    """``((height + 2) * (width + 2),)``: row-major, the grid's cell (row, col) at (row + 1, col + 1)."""
    near: npt.NDArray[np.bool_]
    """Blocks of :data:`BLOCK` x :data:`BLOCK` cells of ``blocked`` (flat, row-major, ``near_width`` a
    row): True where a blocking cell lies in the block or in one of its eight neighbours (a point in
    a block that is not near has no blocking cell within ``BLOCK`` rows or columns of its own cell)."""
    near_width: int

    @classmethod
    def of(cls, grid: OccupancyGrid) -> Structure:
        h, w = grid.frame.height + 2, grid.frame.width + 2
        blocked = np.ones((h, w), dtype=np.bool_)
        blocked[1:-1, 1:-1] = grid.data >= OCCUPIED_AT
        bh, bw = -(-h // BLOCK), -(-w // BLOCK)
        padded = np.ones((bh * BLOCK, bw * BLOCK), dtype=np.bool_)  # beyond the border: blocking too
        padded[:h, :w] = blocked
        near = np.pad(padded.reshape(bh, BLOCK, bw, BLOCK).any(axis=(1, 3)), 1, constant_values=True)
        near[1:-1, :] |= near[:-2, :] | near[2:, :]  # and the neighbouring blocks (3 x 3)
        near[:, 1:-1] |= near[:, :-2] | near[:, 2:]
        return cls(grid, blocked.ravel(), np.ascontiguousarray(near[1:-1, 1:-1]).ravel(), bw)


@dataclass(frozen=True, eq=False, slots=True)
class FloorView:
    """The floor a sensor saw: the union of ``rings`` less ``hole_rings`` (map frame, metres; each
    ``(n, 2) float64``); ``polygons`` and ``holes`` are the same as tuples of points."""

    rings: tuple[FloatArray, ...]
    hole_rings: tuple[FloatArray, ...] = ()

    @property
    def polygons(self) -> tuple[Ring, ...]:
        return tuple(_as_points(r) for r in self.rings)

    @property
    def holes(self) -> tuple[Ring, ...]:
        return tuple(_as_points(r) for r in self.hole_rings)

    @property
    def area(self) -> float:
        return sum(polygon_area(p) for p in self.rings) - sum(polygon_area(h) for h in self.hole_rings)


def _as_points(ring: FloatArray) -> Ring:
    return tuple((x, y) for x, y in ring.tolist())


def _covered_bearings(cam: Camera, band: tuple[float, float], angles: FloatArray) -> npt.NDArray[np.bool_]:
    """``(rays,) bool``: which bearings ``angles`` (in ``[0, 2 pi)``) meet the frustum, from a coarse
    pass (each coarse bearing widened by its neighbours)."""
    px, py, _ = cam.position
    bearings = 2 * math.pi * np.arange(COARSE_BEARINGS) / COARSE_BEARINGS
    start = max(cam.near_m, 0.02)
    dist = np.linspace(start, max(cam.range_m, start), COARSE_SAMPLES)
    xs = px + np.cos(bearings)[:, None] * dist[None, :]
    ys = py + np.sin(bearings)[:, None] * dist[None, :]
    hit = (cam.sees(xs, ys, band[0]) & cam.sees(xs, ys, band[1])).any(axis=1)
    hit = hit | np.roll(hit, 1) | np.roll(hit, -1)
    fine = np.floor(angles * (COARSE_BEARINGS / (2 * math.pi)) + 1e-9).astype(np.int64) % COARSE_BEARINGS
    return np.asarray(hit[fine])


MIN_RAY_GAP_RAD = 1e-3
"""Rays added at given bearings stay this far apart (the finest even spacing is 1.5 mrad): of two
closer ones, the first (1 cm at 10 m; nearer, the points' 0.1 mm on the wire would fold a ring)."""


def _with_bearings(angles: FloatArray, bearings: FloatArray) -> FloatArray:
    """The evenly spaced rays ``angles`` with a ray at each of ``bearings`` too (in their order, of two
    closer than :data:`MIN_RAY_GAP_RAD` the first), sorted: the nearest ray moved onto one within a
    quarter of the spacing, else one added."""
    step = 2 * math.pi / len(angles)
    out = angles.copy()
    kept: list[float] = []
    added: list[float] = []
    moved: set[int] = set()
    for b in bearings.tolist():
        if any(abs((b - k + math.pi) % (2 * math.pi) - math.pi) < MIN_RAY_GAP_RAD for k in kept):
            continue
        kept.append(b)
        i = round(b / step) % len(angles)
        if abs((b - angles[i] + math.pi) % (2 * math.pi) - math.pi) < step / 4 and i not in moved:
            out[i] = b
            moved.add(i)
        else:
            added.append(b)
    return np.sort(np.concatenate([out, added]) % (2 * math.pi))


def _wedge_bearings(cam: Camera, band: tuple[float, float]) -> FloatArray:
    """The bearings (from the sensor's xy, in ``[0, 2 pi)``) that bound the blind wedge of a camera whose
    horizontal field of view lies between 180° and 360°: ``|atan2(b, a)| > hfov / 2`` is the meet of
    two half-spaces whose planes hold the sensor, so at each height of ``band`` its floor section is
    a wedge of two half-planes, its apex off the sensor's xy when the camera tilts. A ray at the
    bearing of each apex, of each edge's two directions and of each point where an edge of one height
    crosses one of the other leaves, between two neighbouring rays, one straight stretch of the two
    wedges' boundary: the chord between them stays outside it (an apex at the sensor's xy: a ray
    inside the wedge instead, its edges being rays from the sensor)."""
    if not math.pi <= cam.hfov_rad < 2 * math.pi - 1e-9:
        return np.zeros(0)
    h = cam.hfov_rad / 2
    f, r = np.asarray(cam.forward), np.asarray(cam.right)
    # blind: u1 > 0 and u2 > 0, u_k = g_k . (x - px, y - py) + k_k (z - pz)
    g = np.stack([-math.sin(h) * f + math.cos(h) * r, -math.sin(h) * f - math.cos(h) * r])
    bearings: list[float] = []  # the rays inside a wedge whose apex is at the sensor's xy first
    edges: list[float] = []
    for gx, gy, _ in g:
        if math.hypot(gx, gy) > 1e-12:  # the edge's line, both ways along it
            edges += [math.atan2(gx, -gy), math.atan2(-gx, gy)]
    det = float(g[0, 0] * g[1, 1] - g[0, 1] * g[1, 0])
    if abs(det) > 1e-12:
        for z in band:
            k = -(z - cam.position[2]) * g[:, 2]  # g_xy . w = k: the apex w from the sensor's xy
            wx = (k[0] * g[1, 1] - k[1] * g[0, 1]) / det
            wy = (g[0, 0] * k[1] - g[1, 0] * k[0]) / det
            if math.hypot(wx, wy) > 1e-9:
                edges.append(math.atan2(wy, wx))
            else:  # the apex at the sensor's xy: a ray inside the wedge, lest two on its edges span it
                n1, n2 = g[0, :2] / math.hypot(*g[0, :2]), g[1, :2] / math.hypot(*g[1, :2])
                bearings.append(math.atan2(n1[1] + n2[1], n1[0] + n2[0]))
        # where one height's edge crosses the other's: there the blind union's boundary turns, so a
        # ray there too leaves one straight stretch of it between neighbouring rays
        z1, z2 = (b - cam.position[2] for b in band)
        for za, zb in ((z1, z2), (z2, z1)):
            k = np.array([-za * g[0, 2], -zb * g[1, 2]])
            wx = (k[0] * g[1, 1] - k[1] * g[0, 1]) / det
            wy = (g[0, 0] * k[1] - g[1, 0] * k[0]) / det
            if math.hypot(wx, wy) > 1e-9:
                edges.append(math.atan2(wy, wx))
    return np.mod(np.asarray(bearings + edges, dtype=np.float64), 2 * math.pi)


def _pinhole_reach(
    cam: Camera, band: tuple[float, float], angles: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """``(lo, hi)`` ``(rays,)``: for a pinhole camera (horizontal field of view under 180°), the
    distances along each bearing between which both heights of ``band`` lie in its frustum, within
    ``[near_m, range_m]`` (empty where ``lo >= hi``). Along a ray at a fixed height each side of the
    frustum is a linear inequality in the distance, so the interval is exact."""
    cos, sin = np.cos(angles), np.sin(angles)
    f, r, d = (np.asarray(v) for v in (cam.forward, cam.right, cam.down))
    af, ar, ad = cos * f[0] + sin * f[1], cos * r[0] + sin * r[1], cos * d[0] + sin * d[1]
    th = math.tan(cam.hfov_rad / 2)
    tv = math.tan(cam.vfov_rad / 2) if cam.vfov_rad is not None else 0.0
    lo = np.full(len(angles), max(cam.near_m, 0.0))
    hi = np.full(len(angles), float(cam.range_m))
    # each side p + q t <= 0: q is the bearing's (the same at both heights), p the height's
    qs = [-af, ar - th * af, -ar - th * af]
    if cam.vfov_rad is not None:
        qs += [ad - tv * af, -ad - tv * af]
    signs = [(q > 0, q < 0, q == 0) for q in qs]
    for z in band:
        dz = z - cam.position[2]
        kf, kr, kd = dz * f[2], dz * r[2], dz * d[2]
        ps = [-kf, kr - th * kf, -kr - th * kf]
        if cam.vfov_rad is not None:
            ps += [kd - tv * kf, -kd - tv * kf]
        for p, q, (ahead, behind, level) in zip(ps, qs, signs, strict=True):
            with np.errstate(divide="ignore", invalid="ignore"):
                t = np.divide(-p, q)
            np.minimum(hi, t, out=hi, where=ahead)
            np.maximum(lo, t, out=lo, where=behind)
            if p > 0:
                hi[level] = -np.inf
    return lo, hi


def _box_entry(ox: float, oy: float, angles: FloatArray, boxes: FloatArray) -> FloatArray:
    """``(rays,)``: the distance at which each ray from ``(ox, oy)`` first enters a box footprint
    ``(k, 5)`` (cx, cy, sx, sy, yaw); inf if none. Boxes holding the sensor are ignored.

    Only the pairs of a ray and a box whose bearing from the sensor lies within the box's angular
    reach (its circumscribed circle's, with a margin; every ray for a box that reaches the sensor) are
    worked out, each with the same floats as all pairs would be: the others cannot meet."""
    out = np.full(len(angles), np.inf)
    if len(boxes) == 0 or len(angles) == 0:
        return out
    cx, cy, sx, sy, yaw = (boxes[:, i][None, :] for i in range(5))
    c, s = np.cos(yaw), np.sin(yaw)
    lx, ly = (ox - cx) * c + (oy - cy) * s, -(ox - cx) * s + (oy - cy) * c  # sensor in the box's frame
    hx, hy = sx / 2, sy / 2
    cos_a, sin_a = np.cos(angles), np.sin(angles)
    rays, which = _pairs(ox, oy, angles, boxes)
    if len(rays) == 0:
        return out
    c, s, lx, ly, hx, hy = (v[0][which] for v in (c, s, lx, ly, hx, hy))
    dx = cos_a[rays] * c + sin_a[rays] * s
    dy = -cos_a[rays] * s + sin_a[rays] * c
    t_in, hit = _slab_entry((lx, ly), (hx, hy), (dx, dy))
    np.minimum.at(out, rays[hit], t_in[hit])
    return out


_Pair = tuple[FloatArray, FloatArray]


def _slab_entry(sensor: _Pair, half: _Pair, ray: _Pair) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """The slab test of rays against boxes in each box's frame (broadcast): the sensor at ``(lx, ly)``,
    the box's half sizes ``(hx, hy)``, the ray's direction ``(dx, dy)``. Returns the distance at which
    each ray enters its box and whether it does (ahead of the sensor, the sensor not inside the box)."""
    (lx, ly), (hx, hy), (dx, dy) = sensor, half, ray
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        t1x, t2x = (-hx - lx) / dx, (hx - lx) / dx
        t1y, t2y = (-hy - ly) / dy, (hy - ly) / dy
    inside_x = np.abs(lx) < hx
    inside_y = np.abs(ly) < hy
    tminx = np.where(dx == 0, np.where(inside_x, -np.inf, np.inf), np.minimum(t1x, t2x))
    tmaxx = np.where(dx == 0, np.where(inside_x, np.inf, -np.inf), np.maximum(t1x, t2x))
    tminy = np.where(dy == 0, np.where(inside_y, -np.inf, np.inf), np.minimum(t1y, t2y))
    tmaxy = np.where(dy == 0, np.where(inside_y, np.inf, -np.inf), np.maximum(t1y, t2y))
    t_in, t_out = np.maximum(tminx, tminy), np.minimum(tmaxx, tmaxy)
    hit = (t_in <= t_out) & (t_in >= 0) & ~(inside_x & inside_y)
    return t_in, hit


def _pairs(
    ox: float, oy: float, angles: FloatArray, boxes: FloatArray
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """``(rays, boxes)``: the pairs of a ray (``angles``, sorted in ``[0, 2 pi)``) and a box footprint
    ``(k, 5)`` whose bearing lies within the box's angular reach from ``(ox, oy)`` (its circumscribed
    circle's, with a margin; every ray for a box that reaches the sensor or is not a number), by box."""
    cx, cy, sx, sy = boxes[:, 0], boxes[:, 1], boxes[:, 2], boxes[:, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = np.hypot(sx / 2, sy / 2)
        gap = np.hypot(cx - ox, cy - oy)
        half = np.arcsin(np.minimum(reach / gap, 1.0)) + 1e-6
        every = ~(gap > reach * (1.0 + 1e-9) + 1e-9)  # reaches the sensor (or not a number): every ray
        low = np.mod(np.arctan2(cy - oy, cx - ox) - half, 2 * math.pi)
        high = low + 2 * half
    tau = 2 * math.pi
    low, high = np.where(every, 0.0, low), np.where(every, tau, high)
    # [low, high] within [0, 2 pi), and its part past 2 pi from 0 again
    starts = np.concatenate([np.searchsorted(angles, low), np.zeros(len(boxes), dtype=np.intp)])
    ends = np.concatenate(
        [np.searchsorted(angles, np.minimum(high, tau), side="right"),
         np.searchsorted(angles, np.where(high > tau, high - tau, -1.0), side="right")]
    )  # fmt: skip
    lengths = np.maximum(ends - starts, 0)
    total = int(lengths.sum())
    owner = np.repeat(np.tile(np.arange(len(boxes)), 2), lengths)
    first = np.repeat(starts - (np.cumsum(lengths) - lengths), lengths)
    return first + np.arange(total), owner


def _box_entry_all(ox: float, oy: float, angles: FloatArray, boxes: FloatArray) -> FloatArray:
    """:func:`_box_entry` over every pair of a ray and a box (the reference it is tested against)."""
    out = np.full(len(angles), np.inf)
    if len(boxes) == 0:
        return out
    cx, cy, sx, sy, yaw = (boxes[:, i][None, :] for i in range(5))
    c, s = np.cos(yaw), np.sin(yaw)
    lx, ly = (ox - cx) * c + (oy - cy) * s, -(ox - cx) * s + (oy - cy) * c  # sensor in the box's frame
    dx = np.cos(angles)[:, None] * c + np.sin(angles)[:, None] * s
    dy = -np.cos(angles)[:, None] * s + np.sin(angles)[:, None] * c
    t_in, hit = _slab_entry((lx, ly), (sx / 2, sy / 2), (dx, dy))
    return np.asarray(np.where(hit, t_in, np.inf).min(axis=1))


def _runs(valid: npt.NDArray[np.bool_], full: bool) -> list[npt.NDArray[np.int64]]:
    """Index runs of consecutive valid rays (wrapping round when ``full``)."""
    n = len(valid)
    if not valid.any():
        return []
    if full and valid.all():
        return [np.arange(n)]
    if full:  # start after an invalid ray so that no run is cut at index 0
        shift = int(np.argmin(valid))
        order = (np.arange(n) + shift) % n
    else:
        order = np.arange(n)
    v = valid[order]
    edges = np.diff(np.concatenate([[0], v.astype(np.int8), [0]]))
    starts, ends = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]
    return [order[a:b] for a, b in zip(starts, ends, strict=True) if b - a >= 2]


def _thin(angles: FloatArray, near: FloatArray, far: FloatArray, step_rad: float) -> npt.NDArray[np.bool_]:
    """Rays to keep: the ends of runs of one reach (near and far), and a ray every MAX_CHORD_RAD."""
    n = len(far)
    keep = np.ones(n, dtype=bool)
    if n > 2:
        same = (
            (far[1:-1] == far[:-2])
            & (far[1:-1] == far[2:])
            & (near[1:-1] == near[:-2])
            & (near[1:-1] == near[2:])
        )
        keep[1:-1] = ~same
        keep[:: max(1, int(MAX_CHORD_RAD / max(step_rad, 1e-9)))] = True
    return keep


@dataclass(frozen=True, eq=False, slots=True)
class _Marched:
    """What a camera's view owes to its pose and the structure alone (not to the array's detections):
    the rays (``count`` round the circle, ``covered`` those in the frustum, at ``angles``), each's
    ``near`` and ``far`` ends in the frustum and its distance to the structure (``first_block``; for a
    pinhole camera inf where that lies beyond ``far``: it cannot shorten the ray's floor).
    ``count`` 0: the frustum meets no floor."""

    count: int
    step: float
    near0: float
    angles_all: FloatArray
    covered: npt.NDArray[np.bool_]
    angles: FloatArray
    near: FloatArray
    far: FloatArray
    first_block: FloatArray
    cos_all: FloatArray
    """``(count,)``: ``math.cos`` of each covered ray's angle (0 elsewhere), the floats its points
    are made with; ``sin_all`` likewise."""
    sin_all: FloatArray


_NONE = np.zeros(0)
_NOTHING = _Marched(0, 0.0, 0.0, _NONE, np.zeros(0, dtype=np.bool_), _NONE, _NONE, _NONE, _NONE, _NONE, _NONE)


def _trig(count: int, covered: npt.NDArray[np.bool_], angles: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``(count,)`` each: the covered rays' cosines and sines (``math``'s, as Python makes a point
    ``ox + math.cos(t) * r``: numpy's own may differ in the last bit), 0 elsewhere."""
    cos_all, sin_all = np.zeros(count), np.zeros(count)
    listed = angles.tolist()
    cos_all[covered] = [math.cos(t) for t in listed]
    sin_all[covered] = [math.sin(t) for t in listed]
    return cos_all, sin_all


class ViewCache:
    """The last march of a robot's camera (:func:`camera_view` with ``cache``), reused while its pose,
    its band, its rays and the structure object stay the same (a robot standing still): only the
    detections' shadows are cut again. One per robot, used by one thread."""

    __slots__ = ("_key", "_value", "hits", "misses")

    def __init__(self) -> None:
        self._key: tuple[object, ...] | None = None
        self._value: _Marched | None = None
        self.hits = 0
        self.misses = 0

    def get(self, key: tuple[object, ...]) -> _Marched | None:
        if self._key is not None and self._key[0] is key[0] and self._key[1:] == key[1:]:
            self.hits += 1
            return self._value
        self.misses += 1
        return None

    def put(self, key: tuple[object, ...], value: _Marched) -> None:
        self._key, self._value = key, value


CHUNK_SAMPLES = 16
"""A pinhole camera's rays are marched this many samples first, then twice as many at a time, each
chunk only for the rays that have not met the structure yet and still reach that far."""


Cells = npt.NDArray[np.intp]


def _cells(structure: Structure, xs: FloatArray, ys: FloatArray) -> tuple[Cells, Cells]:
    """``(rows, cols)`` in ``structure.blocked``'s bordered grid of the cells of the points ``(xs, ys)``
    (any shape; beyond the grid's edge: its blocking border). Overwrites nothing it is given."""
    f = structure.grid.frame
    res = f.resolution_m
    cells = np.subtract(xs, f.origin_x)  # in place from here on: the same values, no temporaries
    cells /= res
    np.floor(cells, out=cells)
    cols = cells.astype(np.intp)
    np.subtract(ys, f.origin_y, out=cells)
    cells /= res
    np.floor(cells, out=cells)
    rows = cells.astype(np.intp)
    np.maximum(cols, -1, out=cols)  # beyond the grid's edge: the border, which blocks
    np.minimum(cols, f.width, out=cols)
    np.maximum(rows, -1, out=rows)
    np.minimum(rows, f.height, out=rows)
    rows += 1
    cols += 1
    return rows, cols


def _cell_index(structure: Structure, xs: FloatArray, ys: FloatArray) -> npt.NDArray[np.intp]:
    """Indices into ``structure.blocked`` of the cells of the points ``(xs, ys)`` (:func:`_cells`)."""
    rows, cols = _cells(structure, xs, ys)
    rows *= structure.grid.frame.width + 2
    rows += cols
    return rows


def _first_blocks(
    structure: Structure | None,
    ox: float,
    oy: float,
    angles: FloatArray,
    dist: FloatArray,
    *,
    upto: FloatArray,
    step: float,
) -> FloatArray:
    """``(rays,)``: for each ray from ``(ox, oy)`` at ``angles``, the distance of its first sample (at
    ``dist``, ``step`` apart, half a cell) in a blocking cell, less ``step``; inf if none at or before
    ``upto`` (a ray's own limit: what lies beyond cannot shorten its floor). The samples are the whole
    march's, the same floats; each ray is first looked at every ``2 BLOCK - 4`` cells against the
    structure's blocks (``near``): a sample within ``BLOCK - 2`` cells of a look that is not near
    structure is in a cell at most ``BLOCK`` rows and columns from the look's (a cell for the floor, one
    for rounding), so it does not block; the samples before halfway from the last clear look to the
    first near one are clear, and from there the ray is marched sample by sample, in chunks
    (:data:`CHUNK_SAMPLES`, doubling) while it goes."""
    out = np.full(len(angles), np.inf)
    if structure is None or len(angles) == 0 or len(dist) == 0:
        return out
    cos, sin = np.cos(angles), np.sin(angles)
    every = 4 * BLOCK - 8  # samples (half cells) between two looks at the blocks: 2 BLOCK - 4 cells
    coarse = dist[::every]
    xs = np.multiply.outer(cos, coarse)
    xs += ox
    ys = np.multiply.outer(sin, coarse)
    ys += oy
    rows, cols = _cells(structure, xs, ys)
    rows //= BLOCK
    rows *= structure.near_width
    cols //= BLOCK
    rows += cols
    near = structure.near[rows]
    first = np.where(near.any(axis=1), near.argmax(axis=1), len(coarse))
    # the first sample that may be in a blocking cell: past half the way from the last clear look (2 to spare)
    pos = np.maximum(first * every - every // 2 - 2, 0)
    going = np.nonzero(pos < len(dist))[0]
    chunk, last = CHUNK_SAMPLES, len(dist) - 1
    while len(going):
        going = going[upto[going] >= dist[pos[going]]]  # rays whose limit is behind are done
        if len(going) == 0:
            break
        at = pos[going][:, None] + np.arange(chunk)
        inside = at <= last
        np.minimum(at, last, out=at)
        d = dist[at]
        xs = cos[going][:, None] * d
        xs += ox
        ys = sin[going][:, None] * d
        ys += oy
        blocked = structure.blocked[_cell_index(structure, xs, ys)]
        blocked &= inside
        blocked &= d <= upto[going][:, None]
        hit = blocked.any(axis=1)
        if hit.any():
            rows_hit = np.nonzero(hit)[0]
            out[going[hit]] = d[rows_hit, blocked[hit].argmax(axis=1)] - step
        pos[going] += chunk
        going = going[~hit & (pos[going] <= last)]
        chunk *= 2
    return out


def _march(structure: Structure | None, cam: Camera, band_m: tuple[float, float], rays: int) -> _Marched:
    """The rays of ``cam`` marched through ``structure`` (see :class:`_Marched`)."""
    ox, oy, _ = cam.position
    res = structure.grid.frame.resolution_m if structure is not None else 0.05
    per_fov = max(int(rays), 3) * 2 * math.pi / min(cam.hfov_rad, 2 * math.pi)
    count = int(min(MAX_RAYS, max(per_fov, math.ceil(2 * math.pi * cam.range_m / res) + 1)))
    angles_all = 2 * math.pi * np.arange(count) / count
    pinhole = cam.hfov_rad < math.pi
    if not pinhole:  # rays also at the bounds of the blind wedge (none for a pinhole camera: exact rays)
        angles_all = _with_bearings(angles_all, _wedge_bearings(cam, band_m))
        count = len(angles_all)
    step = res / 2
    near0 = max(res, 0.05)  # a ray's floor never starts closer than one cell (the sensor's own cell)
    if pinhole:
        lo_all, hi_all = _pinhole_reach(cam, band_m, angles_all)
        lo_all = np.maximum(lo_all, near0)
        covered = hi_all > lo_all + step
    else:
        covered = _covered_bearings(cam, band_m, angles_all)
    if not covered.any():
        return _NOTHING
    angles = angles_all[covered]
    reach = float(hi_all[covered].max()) if pinhole else cam.range_m
    dist = np.arange(near0, reach + step, step)
    dist = dist[dist <= reach + 1e-9]
    if len(dist) < 2:
        return _NOTHING
    if pinhole:  # each ray only as far as it could claim floor, and only to its first blocking cell
        near, far = lo_all[covered], hi_all[covered]
        first_block = _first_blocks(structure, ox, oy, angles, dist, upto=far + 2 * step, step=step)
        trig = _trig(count, covered, angles)
        return _Marched(count, step, near0, angles_all, covered, angles, near, far, first_block, *trig)
    xs = np.multiply.outer(np.cos(angles), dist)  # (rays, k); the same floats as ox + cos * dist
    xs += ox
    ys = np.multiply.outer(np.sin(angles), dist)
    ys += oy
    if structure is not None:
        blocked = structure.blocked[_cell_index(structure, xs, ys)]
        first_block = np.where(blocked.any(axis=1), dist[blocked.argmax(axis=1)] - step, np.inf)
    else:
        first_block = np.full(len(angles), np.inf)
    # sampled: the first run of samples in the frustum
    seen = cam.sees(xs, ys, band_m[0]) & cam.sees(xs, ys, band_m[1]) & (dist >= cam.near_m)[None, :]
    has = seen.any(axis=1)
    first = seen.argmax(axis=1)
    after = np.where(np.arange(len(dist))[None, :] >= first[:, None], ~seen, False)
    last = np.where(after.any(axis=1), after.argmax(axis=1) - 1, len(dist) - 1)
    near = np.where(has, dist[first], np.inf)
    far = np.where(has, dist[last], -np.inf)
    trig = _trig(count, covered, angles)
    return _Marched(count, step, near0, angles_all, covered, angles, near, far, first_block, *trig)


def _simple(ring: Sequence[Point] | FloatArray) -> bool:
    """Whether the closed ``ring``, rounded to 0.1 mm as the wire writes it, has no two non-adjacent
    edges that meet (all pairs at once)."""
    p = np.rint(np.asarray(ring, dtype=np.float64) * 1e4) / 1e4
    q = np.roll(p, -1, axis=0)
    n = len(p)
    if n < 4:
        return True

    def side(a: FloatArray, b: FloatArray, c: FloatArray) -> FloatArray:
        return np.sign(
            (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
            - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])
        )

    a, b = p[:, None, :], q[:, None, :]
    c, d = p[None, :, :], q[None, :, :]
    meet = (side(a, b, c) * side(a, b, d) <= 0) & (side(c, d, a) * side(c, d, b) <= 0)
    i, j = np.triu_indices(n, 2)
    keep = ~((i == 0) & (j == n - 1))  # the first and the last edge share a corner
    return not bool(meet[i[keep], j[keep]].any())


def _roll(a: npt.NDArray[Any], shift: int) -> npt.NDArray[Any]:
    """``np.roll(a, shift)`` of a 1-d array by one place (without its general machinery)."""
    if shift == 1:
        return np.concatenate((a[-1:], a[:-1]))
    return np.concatenate((a[1:], a[:1]))


def _points(ox: float, oy: float, cos: FloatArray, sin: FloatArray, radii: FloatArray) -> FloatArray:
    """``(n, 2)``: the points at ``radii`` from ``(ox, oy)`` along the rays of cosines ``cos`` and sines
    ``sin`` (the floats of ``ox + math.cos(t) * r``, each)."""
    out = np.empty((len(radii), 2))
    np.multiply(cos, radii, out=out[:, 0])
    out[:, 0] += ox
    np.multiply(sin, radii, out=out[:, 1])
    out[:, 1] += oy
    return out


def camera_view(
    grid: OccupancyGrid | Structure | None,
    cam: Camera,
    *,
    band_m: tuple[float, float] = (0.0, 0.0),
    shadows: Sequence[tuple[float, float, float, float, float]] | FloatArray = (),
    rays: int = 64,
    cache: ViewCache | None = None,
) -> FloorView | None:
    """The floor ``cam`` saw (see the module's docstring), or None when it claims less than 1 dm².

    ``grid`` None: no structure occludes (a :class:`Structure` of it: made once per grid by a caller
    that views it many times). ``shadows``: ``(cx, cy, sx, sy, yaw)`` box footprints
    (``(k, 5)``). ``cache``: the march of the last call with the same structure, camera, band and
    rays is reused (the result is the same; only the shadows are cut again).
    """
    ox, oy, _ = cam.position
    structure = Structure.of(grid) if isinstance(grid, OccupancyGrid) else grid
    key = (structure, cam, (float(band_m[0]), float(band_m[1])), int(rays))
    marched = cache.get(key) if cache is not None else None
    if marched is None:
        marched = _march(structure, cam, band_m, rays)
        if cache is not None:
            cache.put(key, marched)
    if marched.count == 0:
        return None
    count, step, near0, angles_all = marched.count, marched.step, marched.near0, marched.angles_all
    covered, angles = marched.covered, marched.angles
    boxes = np.asarray(shadows, dtype=np.float64).reshape(-1, 5)
    wall = np.minimum(marched.first_block, _box_entry(ox, oy, angles, boxes) - step)
    near, far = marched.near, np.minimum(marched.far, wall)
    # conservative between rays: no farther and no nearer than the neighbours that claim floor too
    # (on the fine circle; next to a ray that claims none, the polygon's edge runs back to the sensor)
    far_all = np.full(count, -np.inf)
    near_all = np.full(count, np.inf)
    far_all[covered], near_all[covered] = far, near
    claims = far_all > near_all + step
    far_all = np.where(claims, far_all, -np.inf)
    for side in (1, -1):
        other = _roll(claims, side)
        far_all = np.where(other, np.minimum(far_all, _roll(far_all, side)), far_all)
    near_n = np.where(claims, near_all, -np.inf)
    near_all = np.maximum(near_all, np.maximum(_roll(near_n, 1), _roll(near_n, -1)))
    valid = far_all > near_all + step
    whole_circle = bool(valid.all())
    polygons: list[FloatArray] = []
    holes: list[FloatArray] = []
    step_rad = 2 * math.pi / count
    for run in _runs(valid, full=True):
        a, lo, hi = angles_all[run], near_all[run], far_all[run]
        keep = _thin(a, lo, hi, step_rad)
        keep[0] = keep[-1] = True
        a, lo, hi, kept = a[keep], lo[keep], hi[keep], run[keep]
        at_sensor = cam.near_m <= 0 and cam.vfov_rad is None and bool((lo <= near0 + 1e-9).all())
        # a chord between two near ends cuts into the blind zone: push each out to clear its chords
        gaps = np.diff(a) % (2 * math.pi)
        wrap = float((a[0] - a[-1]) % (2 * math.pi)) if whole_circle else 0.0
        before = np.concatenate([[wrap], gaps])
        after = np.concatenate([gaps, [wrap]])
        half = np.minimum(np.maximum(before, after), 2.0) / 2
        lo = np.minimum(lo / np.cos(half), hi - 1e-6)
        cos, sin = marched.cos_all[kept], marched.sin_all[kept]
        outer = _points(ox, oy, cos, sin, hi)
        if whole_circle:
            if len(outer) < 3:
                continue
            polygons.append(outer)
            if not at_sensor:
                holes.append(_points(ox, oy, cos, sin, lo))
        elif at_sensor:
            polygons.append(np.concatenate([[(float(ox), float(oy))], outer]))
        else:
            ring = np.concatenate([outer, _points(ox, oy, cos, sin, lo)[::-1]])
            if cam.hfov_rad < math.pi or cam.vfov_rad is None or _simple(ring):
                polygons.append(ring)
            # else: a wide camera's vertical limit curves the near and far ends so that they cross
            # between rays (a known limit): the run claims no floor rather than floor it did not see
    view = FloorView(tuple(polygons), tuple(holes))
    if not polygons or _small(view):
        return None
    return view


def _small(view: FloorView) -> bool:
    """Whether ``view`` claims less than :data:`MIN_AREA_M2`: its area worked out without the shoelace's
    rolls (the last bits may differ), and exactly as :attr:`FloorView.area` does only when that is
    within 1e-9 m² of the limit."""
    area = 0.0
    for rings, sign in ((view.rings, 1.0), (view.hole_rings, -1.0)):
        for ring in rings:
            if len(ring) < 3:
                continue
            x, y = ring[:, 0], ring[:, 1]
            twice = float(x[:-1] @ y[1:] - y[:-1] @ x[1:]) + float(x[-1] * y[0] - y[-1] * x[0])
            area += sign * abs(twice) / 2
    if abs(area - MIN_AREA_M2) > 1e-9:
        return area < MIN_AREA_M2
    return view.area < MIN_AREA_M2


def visibility_polygon(
    grid: OccupancyGrid | None,
    origin_xy: tuple[float, float],
    *,
    heading_rad: float,
    fov_rad: float,
    range_m: float,
    rays: int = 64,
) -> tuple[tuple[float, float], ...]:
    """The floor polygon a level sensor at ``origin_xy`` looking along ``heading_rad`` saw, with no
    vertical limit and no blind zone (the first polygon of :func:`camera_view`; empty if none)."""
    c, s = math.cos(heading_rad), math.sin(heading_rad)
    cam = Camera(
        (float(origin_xy[0]), float(origin_xy[1]), 0.0), (c, s, 0.0), (s, -c, 0.0), (0.0, 0.0, -1.0),
        fov_rad, None, range_m,
    )  # fmt: skip
    view = camera_view(grid, cam, rays=rays)
    return view.polygons[0] if view is not None else ()


def polygon_area(polygon: Sequence[tuple[float, float]] | FloatArray) -> float:
    """The area of a simple polygon (shoelace), m²."""
    if len(polygon) < 3:
        return 0.0
    p = np.asarray(polygon, dtype=np.float64)
    x, y = p[:, 0], p[:, 1]
    return float(abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) / 2)
