"""Straight segments against an occupancy mask: is a lane's centre line free?

Points are in cell coordinates: ``(row, col)`` floats, the centre of cell ``(r, c)`` at ``(r, c)``. A
segment is free when every cell its centre line passes through is free: it is sampled every quarter
cell (and at both ends), which finds every cell it crosses by more than a sliver; a line through a
cell's corner (two diagonal neighbours) counts as free, as an 8-connected grid path does. The
benchmark's safety check (``benchmarks/routes.py``) uses the same test.
"""

from __future__ import annotations

import itertools

import numpy as np
import numpy.typing as npt

BoolArray = npt.NDArray[np.bool_]
FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

SAMPLES_PER_CELL = 4
_PHASE = 0.381966  # samples at (k + phase) / n: never exactly half way, so never on a cell's corner


def segments_free(
    free: BoolArray, a: FloatArray, b: FloatArray, *, samples_per_cell: int = SAMPLES_PER_CELL
) -> BoolArray:
    """``(n,) bool``: whether each segment ``a[i] -> b[i]`` (``(n, 2)`` cell coordinates) is free.

    Points outside the mask are not free. ``samples_per_cell`` below the default gives a cheaper,
    coarser test: a segment it finds blocked passes through a blocked cell (a sample lies in it), so
    it is a sound first filter before the full test.
    """
    # to a millionth of a cell: a point given in metres and converted back tests as the cell centre
    a = np.round(np.asarray(a, dtype=np.float64).reshape(-1, 2), 6)
    b = np.round(np.asarray(b, dtype=np.float64).reshape(-1, 2), 6)
    n = len(a)
    out = np.ones(n, dtype=np.bool_)
    if n == 0:
        return out
    length = np.hypot(*(b - a).T)
    inner = np.ceil(length * samples_per_cell).astype(np.int64)
    steps = inner + 2  # both ends, and samples between at an offset that never hits a cell's corner
    # in chunks of about a million samples: many long segments at once would take gigabytes
    ends = np.cumsum(steps)
    cuts = np.searchsorted(ends, np.arange(_CHUNK, int(ends[-1]), _CHUNK), side="right")
    for lo, hi in itertools.pairwise([0, *np.unique(cuts).tolist(), n]):
        if hi > lo:
            out[lo:hi] = _free_chunk(free, a[lo:hi], b[lo:hi], inner[lo:hi], steps[lo:hi])
    return out


_CHUNK = 1 << 20


def _free_chunk(free: BoolArray, a: FloatArray, b: FloatArray, inner: IntArray, steps: IntArray) -> BoolArray:
    n = len(a)
    out = np.ones(n, dtype=np.bool_)
    owner = np.repeat(np.arange(n), steps)
    start = np.cumsum(steps) - steps
    k = np.arange(len(owner)) - start[owner]
    t = np.clip((k - 1 + _PHASE) / np.maximum(inner[owner], 1), 0.0, 1.0)
    t[k == 0] = 0.0
    t[k == steps[owner] - 1] = 1.0
    pts = a[owner] + (b - a)[owner] * t[:, None]
    rc = np.rint(pts).astype(np.int64)
    h, w = free.shape
    inside = (rc[:, 0] >= 0) & (rc[:, 0] < h) & (rc[:, 1] >= 0) & (rc[:, 1] < w)
    ok = np.zeros(len(rc), dtype=np.bool_)
    ok[inside] = free[rc[inside, 0], rc[inside, 1]]
    out[np.unique(owner[~ok])] = False
    return out


def segment_free(free: BoolArray, a: tuple[float, float], b: tuple[float, float]) -> bool:
    """Whether the one segment ``a -> b`` (cell coordinates) is free."""
    return bool(segments_free(free, np.array([a]), np.array([b]))[0])
