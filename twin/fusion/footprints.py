"""An element's pose as a robot's detector sees it: an upright oriented box, and its footprint.

Robots report boxes (``twin:box``: centre, sizes, yaw); the twin holds meshes and placements. To compare
the two, every shape is reduced to a :class:`Pose`: the centre, the sizes and the yaw of its smallest
upright box (the box itself for a box mesh; the minimum-area rectangle of the footprint's convex hull
otherwise). Poses are canonical: ``sx >= sy`` and the yaw in ``[0, pi)``, so a detector's flipped
heading (yaw + pi), or a box given as 0.8 x 1.2 instead of 1.2 x 0.8 turned by 90 degrees, is the
same pose; a square footprint is the same every quarter turn.

Example::

    a, b = pose_of(shape), box_pose(16.6, 7.0, 0.375, 1.2, 0.8, 0.75, yaw=0.3)
    iou(a, b), centre_distance(a, b), yaw_difference(a, b)
    inside(corners(a), [polygon])                  # is the footprint inside a view?
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import shapely
import shapely.geometry

from twin.records import FloatArray, Shape

SQUARE_TOLERANCE_M = 0.05
"""Footprints whose sides differ by less than this are square: the same every quarter turn (a detector's
noise decides which side of a nearly square box is the longer, and so its canonical yaw)."""


@dataclass(frozen=True, slots=True)
class Pose:
    """An upright box in the world: centre (z of its middle), sizes (``sx >= sy``), yaw in [0, pi)."""

    cx: float
    cy: float
    cz: float
    sx: float
    sy: float
    sz: float
    yaw: float

    @property
    def zmin(self) -> float:
        return self.cz - self.sz / 2

    @property
    def zmax(self) -> float:
        return self.cz + self.sz / 2

    @property
    def square(self) -> bool:
        return self.sx - self.sy < SQUARE_TOLERANCE_M

    @property
    def area(self) -> float:
        return self.sx * self.sy


_NEW = object.__new__
_SET_CX, _SET_CY, _SET_CZ, _SET_SX, _SET_SY, _SET_SZ, _SET_YAW = (
    getattr(Pose, f).__set__ for f in ("cx", "cy", "cz", "sx", "sy", "sz", "yaw")
)
assert Pose.__slots__ == ("cx", "cy", "cz", "sx", "sy", "sz", "yaw")


def _pose(cx: float, cy: float, cz: float, sx: float, sy: float, sz: float, yaw: float) -> Pose:  # noqa: PLR0917
    """``Pose(cx, cy, cz, sx, sy, sz, yaw)`` made in half the time: its slots set through their
    descriptors, where the frozen dataclass's ``__init__`` calls ``object.__setattr__`` for each (the
    fusion rules make a few poses for every report)."""
    p = _NEW(Pose)
    _SET_CX(p, cx)
    _SET_CY(p, cy)
    _SET_CZ(p, cz)
    _SET_SX(p, sx)
    _SET_SY(p, sy)
    _SET_SZ(p, sz)
    _SET_YAW(p, yaw)
    return p


def box_pose(cx: float, cy: float, cz: float, sx: float, sy: float, sz: float, *, yaw: float) -> Pose:  # noqa: PLR0917
    """The canonical pose of a box (centre z is the world z of its middle)."""
    if sy > sx:
        sx, sy, yaw = sy, sx, yaw + math.pi / 2
    return _pose(cx, cy, cz, sx, sy, sz, yaw % math.pi)


def _is_box_mesh(vertices: FloatArray) -> FloatArray | None:
    """The sizes of a box mesh centred on its origin (as :func:`twin.maps.shapes.box_mesh` makes), or None."""
    if vertices.shape != (8, 3):
        return None
    size = np.abs(vertices)
    half = size.max(axis=0)
    if not (np.abs(size - half) <= 1e-9 + 1e-5 * half).all():  # np.allclose(size, half, atol=1e-9), faster
        return None
    return np.asarray(half * 2)


BoxSizes = tuple[float, float, float]
"""A box mesh's sizes along its local axes (:func:`box_sizes`)."""


def box_sizes(vertices: FloatArray) -> BoxSizes | None:
    """The sizes of a box mesh centred on its origin, or None: what :func:`pose_of` tests."""
    sizes = _is_box_mesh(vertices)
    if sizes is None:
        return None
    sx, sy, sz = sizes.tolist()
    return sx, sy, sz


def pose_of(shape: Shape) -> Pose:
    """The smallest upright box around a mesh placed in the world."""
    return placed_pose(shape, box_sizes(shape[0].vertices))


def placed_pose(shape: Shape, sizes: BoxSizes | None) -> Pose:
    """:func:`pose_of` given the mesh's :func:`box_sizes` (None: not a box mesh), for a caller that
    keeps them while the mesh stays the same object (a moving element: only its placement changes)."""
    mesh, placement = shape
    if sizes is not None:
        (r00, r01, r02, cx), (r10, r11, r12, cy), (r20, r21, r22, cz) = placement[:3].tolist()
        if abs(r20) < 1e-9 and abs(r21) < 1e-9:
            # in Python floats, as np.linalg.norm(placement[:3, :3], axis=0) sums (rows in order)
            sx = sizes[0] * math.sqrt(r00 * r00 + r10 * r10 + r20 * r20)
            sy = sizes[1] * math.sqrt(r01 * r01 + r11 * r11 + r21 * r21)
            sz = sizes[2] * math.sqrt(r02 * r02 + r12 * r12 + r22 * r22)
            return box_pose(cx, cy, cz, sx, sy, sz, yaw=math.atan2(r10, r00))
    world = mesh.vertices @ placement[:3, :3].T + placement[:3, 3]
    if len(world) == 0:
        x, y, z = (float(v) for v in placement[:3, 3])
        return Pose(x, y, z, 0.0, 0.0, 0.0, 0.0)
    zmin, zmax = float(world[:, 2].min()), float(world[:, 2].max())
    cx, cy, sx, sy, yaw = min_area_rectangle(world[:, :2])
    return box_pose(cx, cy, (zmin + zmax) / 2, sx, sy, zmax - zmin, yaw=yaw)


def convex_hull(points: FloatArray) -> FloatArray:
    """``(k, 2)`` the convex hull of 2D points, counter-clockwise (shapely's, in C; Andrew's monotone
    chain for the degenerate cases: fewer than three points, or all on a line)."""
    pts = np.unique(np.round(points, 9), axis=0)
    if len(pts) < 3:
        return np.asarray(pts, dtype=np.float64)
    hull = shapely.convex_hull(shapely.multipoints(pts))
    if isinstance(hull, shapely.Polygon):
        ring = np.asarray(shapely.geometry.polygon.orient(hull, 1.0).exterior.coords, dtype=np.float64)
        return ring[:-1]
    return _monotone_chain(pts)


def _monotone_chain(pts: FloatArray) -> FloatArray:
    """``(k, 2)`` the convex hull of sorted unique 2D points, counter-clockwise (Andrew's monotone chain)."""

    def half(seq: FloatArray) -> list[FloatArray]:
        out: list[FloatArray] = []
        for p in seq:
            while len(out) >= 2:
                (ax, ay), (bx, by) = out[-2], out[-1]
                if (bx - ax) * (p[1] - ay) - (by - ay) * (p[0] - ax) > 0:
                    break
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.asarray(lower[:-1] + upper[:-1], dtype=np.float64)


def min_area_rectangle(points: FloatArray) -> tuple[float, float, float, float, float]:
    """``(cx, cy, sx, sy, yaw)``: the smallest rectangle around 2D points (one side on a hull edge)."""
    hull = convex_hull(points)
    if len(hull) < 3:
        lo, hi = points.min(axis=0), points.max(axis=0)
        c = (lo + hi) / 2
        return float(c[0]), float(c[1]), float(hi[0] - lo[0]), float(hi[1] - lo[1]), 0.0
    edges = np.roll(hull, -1, axis=0) - hull
    angles = np.unique(np.round(np.arctan2(edges[:, 1], edges[:, 0]) % (math.pi / 2), 12))
    c, s = np.cos(angles), np.sin(angles)
    # the hull in each edge's frame: u along the edge, v across it
    u = hull[:, 0][None, :] * c[:, None] + hull[:, 1][None, :] * s[:, None]
    v = -hull[:, 0][None, :] * s[:, None] + hull[:, 1][None, :] * c[:, None]
    du, dv = u.max(axis=1) - u.min(axis=1), v.max(axis=1) - v.min(axis=1)
    best = int(np.argmin(du * dv))
    mu = (u[best].max() + u[best].min()) / 2
    mv = (v[best].max() + v[best].min()) / 2
    cb, sb = float(c[best]), float(s[best])
    cx, cy = mu * cb - mv * sb, mu * sb + mv * cb
    return float(cx), float(cy), float(du[best]), float(dv[best]), float(angles[best])


def corners(p: Pose, *, inset: float = 0.0) -> FloatArray:
    """``(4, 2)`` the footprint's corners, counter-clockwise (moved ``inset`` metres inwards on each
    side, to at most the centre line)."""
    c, s = math.cos(p.yaw), math.sin(p.yaw)
    hx, hy = max(p.sx / 2 - inset, 0.0), max(p.sy / 2 - inset, 0.0)
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    return np.asarray(local @ np.array([[c, s], [-s, c]]) + (p.cx, p.cy))


def _clip(subject: list[tuple[float, float]], clip: FloatArray) -> list[tuple[float, float]]:
    """Sutherland-Hodgman: ``subject`` clipped by the convex counter-clockwise polygon ``clip``."""
    out = subject
    n = len(clip)
    for i in range(n):
        if not out:
            break
        ax, ay = clip[i]
        bx, by = clip[(i + 1) % n]
        ex, ey = bx - ax, by - ay
        src, out = out, []
        for j, (px, py) in enumerate(src):
            qx, qy = src[j - 1]
            p_in = ex * (py - ay) - ey * (px - ax) >= 0
            q_in = ex * (qy - ay) - ey * (qx - ax) >= 0
            if p_in != q_in:
                dx, dy = px - qx, py - qy
                den = ex * dy - ey * dx
                t = (ex * (ay - qy) - ey * (ax - qx)) / den if den else 0.0
                out.append((qx + t * dx, qy + t * dy))
            if p_in:
                out.append((px, py))
    return out


def _area(poly: Sequence[tuple[float, float]]) -> float:
    n = len(poly)
    return (
        abs(sum(poly[i][0] * poly[(i + 1) % n][1] - poly[(i + 1) % n][0] * poly[i][1] for i in range(n))) / 2
    )


def iou(a: Pose, b: Pose) -> float:
    """Intersection over union of the two footprints (0 when either has no area)."""
    if a.area <= 0 or b.area <= 0:
        return 0.0
    reach = (math.hypot(a.sx, a.sy) + math.hypot(b.sx, b.sy)) / 2
    if math.hypot(a.cx - b.cx, a.cy - b.cy) > reach:
        return 0.0
    inter = _area(_clip([(float(x), float(y)) for x, y in corners(a)], corners(b)))
    return inter / (a.area + b.area - inter)


def centre_distance(a: Pose, b: Pose) -> float:
    return math.hypot(a.cx - b.cx, a.cy - b.cy)


def heights_overlap(a: Pose, b: Pose) -> bool:
    return a.zmin <= b.zmax and b.zmin <= a.zmax


def yaw_difference(a: Pose, b: Pose) -> float:
    """The yaw between two poses modulo their footprint's symmetry (pi, or pi/2 when either is square)."""
    period = math.pi / 2 if a.square or b.square else math.pi
    d = (a.yaw - b.yaw) % period
    return min(d, period - d)


def aligned(seen: Pose, held: Pose) -> Pose:
    """``seen`` turned by the multiple of its symmetry period that brings its yaw nearest ``held``'s
    (sizes swapped for a quarter turn), so that sightings of one object average without wrapping."""
    period = math.pi / 2 if seen.square or held.square else math.pi
    d = (seen.yaw - held.yaw + period / 2) % period - period / 2
    quarter = round((seen.yaw - held.yaw - d) / (math.pi / 2)) % 2 == 1
    sx, sy = (seen.sy, seen.sx) if quarter else (seen.sx, seen.sy)
    return _pose(seen.cx, seen.cy, seen.cz, sx, sy, seen.sz, held.yaw + d)


def inside(points: FloatArray, polygons: Sequence[FloatArray]) -> bool:
    """Whether every point lies inside the union of ``polygons`` (each point in at least one)."""
    left = np.ones(len(points), dtype=bool)
    for poly in polygons:
        left &= ~points_in_polygon(points, poly)
        if not left.any():
            return True
    return False


def points_in_polygon(points: FloatArray, polygon: FloatArray) -> npt.NDArray[np.bool_]:
    """``(k,) bool``: which points lie inside ``polygon`` (even-odd rule; a simple polygon)."""
    x, y = points[:, 0][:, None], points[:, 1][:, None]
    ax, ay = polygon[:, 0][None, :], polygon[:, 1][None, :]
    b = np.roll(polygon, -1, axis=0)
    bx, by = b[:, 0][None, :], b[:, 1][None, :]
    straddles = (ay > y) != (by > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xcross = ax + (y - ay) * (bx - ax) / (by - ay)
    hits = straddles & (x < xcross)
    return np.asarray(hits.sum(axis=1) % 2 == 1)
