"""A reference for which voxels a triangle touches, written apart from ``twin.maps.voxels`` (which it checks).

Plain Python, one triangle and one voxel at a time, in exact integer arithmetic: the closed separating
axis test (13 axes) of the triangle and the voxel's box *shrunk* at its upper faces by less than any
nonzero margin can be. A half-open cell ``[lo, hi)`` meets a closed triangle exactly when such a
shrunk closed box does, so no tie rule is needed. Candidates are every voxel of the triangle's bounding
box (no column enumeration), so the check covers what the production code chooses to test too. With a
``shift`` ``(out, in)``, the box's lower faces are moved out by ``out`` and its upper faces in by ``in``
first (what points maps test: ``twin.maps.voxels.touched_pairs``).

Slow (tens of microseconds per voxel): for small cases and samples of real models.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from fractions import Fraction

import numpy as np
import numpy.typing as npt


def _as_ints(values: Iterable[float | Fraction]) -> list[int]:
    """Floats (and sums of floats) as integers over one common power of two (exact)."""
    ratios = [
        (v.numerator, v.denominator) if isinstance(v, Fraction) else float(v).as_integer_ratio()
        for v in values
    ]
    top = max(d for _, d in ratios)
    return [n * (top // d) for n, d in ratios]


def _exactly(a: float, b: float) -> Fraction:
    """``a + b``, exactly."""
    return Fraction(a) + Fraction(b)


def _sub(a: list[int], b: list[int]) -> list[int]:
    return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]


def _cross(a: list[int], b: list[int]) -> list[int]:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def triangle_touches_cell(
    tri: npt.NDArray[np.float64], lo: Sequence[float | Fraction], hi: Sequence[float | Fraction]
) -> bool:
    """Does the closed triangle ``tri (3, 3)`` share a point with the half-open box ``[lo, hi)``?"""
    ints = _as_ints([*tri.reshape(-1).tolist(), *lo, *hi])
    v = [ints[0:3], ints[3:6], ints[6:9]]
    b_lo, b_hi = ints[9:12], ints[12:15]
    edges = [_sub(v[1], v[0]), _sub(v[2], v[1]), _sub(v[0], v[2])]
    units = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
    axes = units + [_cross(edges[0], edges[1])] + [_cross(e, u) for e in edges for u in units]
    scale = 2 + max(sum(abs(c) for c in ax) for ax in axes)
    # the box shrunk at its upper faces by 1/scale (of the integer unit): smaller than any margin
    s_lo = [scale * c for c in b_lo]
    s_hi = [scale * c - 1 for c in b_hi]
    s_v = [[scale * c for c in p] for p in v]
    for ax in axes:
        proj = [ax[0] * p[0] + ax[1] * p[1] + ax[2] * p[2] for p in s_v]
        box_min = sum(min(ax[i] * s_lo[i], ax[i] * s_hi[i]) for i in range(3))
        box_max = sum(max(ax[i] * s_lo[i], ax[i] * s_hi[i]) for i in range(3))
        if min(proj) > box_max or max(proj) < box_min:
            return False
    return True


def reference_voxels(
    tri: npt.NDArray[np.float64],
    lo: tuple[int, int, int],
    hi: tuple[int, int, int],
    w_band: tuple[float, float],
    *,
    shift: tuple[float, float] = (0.0, 0.0),
) -> set[tuple[int, int, int]]:
    """Every voxel ``(i, j, k)`` in ``[lo, hi)`` the triangle (cell coordinates) touches; voxel ``k``'s z
    range is cut by the band ``[w_lo, w_hi)``, then its faces moved by ``shift``."""
    first = [max(math.floor(tri[:, a].min()), lo[a]) for a in range(3)]
    last = [min(math.floor(tri[:, a].max()), hi[a] - 1) for a in range(3)]
    out = set()
    for i in range(first[0], last[0] + 1):
        for j in range(first[1], last[1] + 1):
            for k in range(first[2], last[2] + 1):
                z0, z1 = max(float(k), w_band[0]), min(float(k + 1), w_band[1])
                if z1 <= z0:
                    continue
                b_lo = [float(i), float(j), z0]
                b_hi = [float(i + 1), float(j + 1), z1]
                if shift != (0.0, 0.0):
                    b_lo = [_exactly(c, -shift[0]) for c in b_lo]
                    b_hi = [_exactly(c, -shift[1]) for c in b_hi]
                if triangle_touches_cell(tri, b_lo, b_hi):
                    out.add((i, j, k))
    return out
