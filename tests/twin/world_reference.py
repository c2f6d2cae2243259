"""An exact reference in world coordinates for which voxels a triangle touches, written apart from the
production code (``twin.maps.grid``, ``twin.maps.voxels``), which it checks.

The grid is what a surveyor would write down: planes at ``origin + i * resolution`` (x, y) and
``elevation + k * resolution`` (z), the origin, the elevation and the resolution read as the decimals
they print as (``8.8`` is 88/10, not its binary neighbour), the band's ends ``elevation + end`` too (an
end within 1 um of a layer's plane being that plane). A vertex coordinate (the float's exact value)
within 1 um of a plane is on it; the others are kept exactly. Voxel ``(i, j, k)`` is the half-open box
``[i, i+1) x [j, j+1) x [max(k, lo), min(k+1, hi))`` in those units, its lower faces moved out by
``OUT`` (3.09017 nm) and its upper faces in by ``IN`` (0.5 um): a slanted surface through a voxel's edge
with its vertices off the grid is then clear of it or into it by nanometres, not by float noise
(for vertices, which are on a plane or more than 1 um from it, the move changes nothing). A closed
triangle touches the voxel when they share a point: the separating-axis test (13 axes) in rational
arithmetic, on that box shrunk at its upper faces by less than any nonzero margin can be. A float
filter decides, per triangle and for all the voxels of its bounding box at once, the pairs far from a
tie either way; the rest go to the exact test.

Example::

    grid = WorldGrid(origin=(8.8, 3.7), elevation_m=3.0, resolution_m=0.1, band_m=(-0.05, 2.8))
    voxels = grid.voxels(triangles_world, lo=(0, 0, -1), hi=(143, 64, 28))
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from decimal import Decimal
from fractions import Fraction

import numpy as np
import numpy.typing as npt

SNAP = Fraction(1, 1_000_000)
"""A coordinate this near a plane (1 um) is on it."""
OUT = Fraction(309_017, 10**14)
"""A voxel's lower faces are moved out by this (metres)."""
IN = Fraction(1, 2_000_000)
"""A voxel's upper faces are moved in by this (metres)."""

Voxel = tuple[int, int, int]


def decimal(x: float) -> Fraction:
    """The decimal a float prints as, exactly (0.1 is 1/10)."""
    return Fraction(Decimal(repr(float(x))))


@dataclass(frozen=True)
class WorldGrid:
    """One storey's voxel grid: metres, as written (see the module)."""

    origin: tuple[float, float]
    elevation_m: float
    resolution_m: float
    band_m: tuple[float, float]

    @property
    def _r(self) -> Fraction:
        return decimal(self.resolution_m)

    def band(self) -> tuple[Fraction, Fraction]:
        """The band's ends in voxels (exact)."""
        return self._units(decimal(self.band_m[0])), self._units(decimal(self.band_m[1]))

    def _units(self, length: Fraction) -> Fraction:
        n = round(length / self._r)
        return Fraction(n) if abs(length - n * self._r) <= SNAP else length / self._r

    def coordinate(self, axis: int, x: float) -> Fraction:
        """World coordinate ``x`` (metres) of ``axis`` in voxels, exactly."""
        o = decimal(self.origin[axis]) if axis < 2 else decimal(self.elevation_m)
        value = Fraction(float(x))
        n = round((value - o) / self._r)
        out = Fraction(n) if abs(value - (o + n * self._r)) <= SNAP else (value - o) / self._r
        if axis == 2:
            for end in self.band_m:
                if abs(value - (o + decimal(end))) <= SNAP:
                    out = self._units(decimal(end))
        return out

    def voxels(
        self, triangles: npt.NDArray[np.float64], *, lo: tuple[int, int, int], hi: tuple[int, int, int]
    ) -> set[Voxel]:
        """Every voxel in ``[lo, hi)`` that one of the world ``triangles (n, 3, 3)`` touches."""
        out: set[Voxel] = set()
        for tri in np.asarray(triangles, dtype=np.float64):
            out |= self.triangle_voxels(tri, lo=lo, hi=hi)
        return out

    def triangle_voxels(
        self, tri: npt.NDArray[np.float64], *, lo: tuple[int, int, int], hi: tuple[int, int, int]
    ) -> set[Voxel]:
        v = [[self.coordinate(a, tri[c, a]) for a in range(3)] for c in range(3)]
        w_lo, w_hi = self.band()
        first = [max(math.floor(min(p[a] for p in v)), lo[a]) for a in range(3)]
        last = [min(math.floor(max(p[a] for p in v)), hi[a] - 1) for a in range(3)]
        if any(f > t for f, t in zip(first, last, strict=True)):
            return set()
        ii, jj, kk = np.meshgrid(*(np.arange(first[a], last[a] + 1) for a in range(3)), indexing="ij")
        ijk = np.stack([ii.ravel(), jj.ravel(), kk.ravel()], axis=1)
        b_lo = ijk.astype(np.float64)
        b_hi = b_lo + 1.0
        b_lo[:, 2] = np.maximum(b_lo[:, 2], float(w_lo))
        b_hi[:, 2] = np.minimum(b_hi[:, 2], float(w_hi))
        keep = b_hi[:, 2] > b_lo[:, 2]
        ijk, b_lo, b_hi = ijk[keep], b_lo[keep], b_hi[keep]
        out_v, in_v = OUT / self._r, IN / self._r  # the faces' moves in voxels
        b_lo, b_hi = b_lo - float(out_v), b_hi - float(in_v)
        verdict = _float_verdict(np.array([[float(c) for c in p] for p in v]), b_lo, b_hi)
        out = {(int(i), int(j), int(k)) for i, j, k in ijk[verdict == 1]}
        for n in np.flatnonzero(verdict == 0):
            i, j, k = (int(c) for c in ijk[n])
            box_lo = [c - out_v for c in (Fraction(i), Fraction(j), max(Fraction(k), w_lo))]
            box_hi = [c - in_v for c in (Fraction(i + 1), Fraction(j + 1), min(Fraction(k + 1), w_hi))]
            if touches(v, box_lo, box_hi):
                out.add((i, j, k))
        return out


def _axes(v: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]]
    units = np.eye(3)
    return np.array([*units, np.cross(edges[0], edges[1]), *(np.cross(e, u) for e in edges for u in units)])


def _float_verdict(
    v: npt.NDArray[np.float64], b_lo: npt.NDArray[np.float64], b_hi: npt.NDArray[np.float64]
) -> npt.NDArray[np.int8]:
    """Per box: 1 touches, -1 apart (both beyond any rounding), 0 to be decided exactly."""
    axes = _axes(v)  # (13, 3)
    proj = v @ axes.T  # (3, 13)
    t_min, t_max = proj.min(axis=0), proj.max(axis=0)
    pos, neg = np.maximum(axes, 0.0).T, np.minimum(axes, 0.0).T
    a_lo, a_hi = b_lo @ pos + b_hi @ neg, b_hi @ pos + b_lo @ neg  # (m, 13) the boxes' projections
    size = np.abs(axes).sum(axis=1)
    eps = 1e-9 * (size + 1.0) * (1.0 + np.abs(v).max() + np.abs(b_hi).max())
    used = size > 0
    apart = ((t_min > a_hi + eps) | (t_max < a_lo - eps)) & used
    inside = ((t_min < a_hi - eps) & (t_max > a_lo + eps)) | ~used
    out = np.zeros(len(b_lo), dtype=np.int8)
    out[inside.all(axis=1)] = 1
    out[apart.any(axis=1)] = -1
    return out


def touches(v: list[list[Fraction]], box_lo: list[Fraction], box_hi: list[Fraction]) -> bool:
    """Does the closed triangle ``v`` share a point with the half-open box ``[box_lo, box_hi)``? Exact."""
    values = [c for p in v for c in p] + box_lo + box_hi
    den = math.lcm(*(x.denominator for x in values))
    ints = [int(x * den) for x in values]
    p = [ints[0:3], ints[3:6], ints[6:9]]
    lo, hi = ints[9:12], ints[12:15]
    edges = [[p[(i + 1) % 3][c] - p[i][c] for c in range(3)] for i in range(3)]

    def cross(a: list[int], b: list[int]) -> list[int]:
        return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]

    units = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
    axes = [*units, cross(edges[0], edges[1]), *(cross(e, u) for e in edges for u in units)]
    shrink = 2 + max(sum(abs(c) for c in ax) for ax in axes)  # the upper faces move in by 1/shrink
    sp = [[shrink * c for c in q] for q in p]
    s_lo = [shrink * c for c in lo]
    s_hi = [shrink * c - 1 for c in hi]
    for ax in axes:
        proj = [ax[0] * q[0] + ax[1] * q[1] + ax[2] * q[2] for q in sp]
        b_min = sum(min(ax[a] * s_lo[a], ax[a] * s_hi[a]) for a in range(3))
        b_max = sum(max(ax[a] * s_lo[a], ax[a] * s_hi[a]) for a in range(3))
        if min(proj) > b_max or max(proj) < b_min:
            return False
    return True
