"""Polygons and sections to cells: strip spans, fill spans, and the window's cell accumulator."""

from __future__ import annotations

from itertools import pairwise

import numpy as np

from twin.maps.grid import GridFrame, Window
from twin.maps.raster.clip import _Polygons
from twin.maps.raster.settings import (
    MAX_VERTICES,
    BoolArray,
    FloatArray,
    IndexArray,
    Int8Array,
    RasterSettings,
    Spans,
)
from twin.tolerances import Tolerances


class _Cells:
    """Collects the spans of one window as difference-array indices, and the section segments to fill."""

    def __init__(self, frame: GridFrame, win: Window, tol: Tolerances, settings: RasterSettings) -> None:
        self.frame, self.win, self.tol = frame, win, tol.cell_m / frame.resolution_m
        self.chunk_pairs = settings.chunk_pairs
        self.starts: list[IndexArray] = []
        self.ends: list[IndexArray] = []
        self.segments: list[FloatArray] = [np.empty((4, 0))]
        self.segment_element: list[IndexArray] = [np.empty(0, np.intp)]
        self.segment_winding: list[Int8Array] = [np.empty(0, np.int8)]

    def add_polygons(self, polygons: _Polygons, idx: IndexArray | None = None) -> None:
        for spans in _polygon_spans(
            polygons, idx, self.win, self.tol, chunk_pairs=self.chunk_pairs
        ):
            self._add(spans)

    def add_segments(self, source: _Polygons, idx: IndexArray | slice = slice(None)) -> None:
        self.segments.append(source.segments[:, idx])
        self.segment_element.append(source.segment_element[idx])
        self.segment_winding.append(source.segment_winding[idx])

    def _add(self, spans: Spans) -> None:
        win = self.win
        row, c_lo, c_hi = spans
        c_lo = np.maximum(c_lo, win.col0)
        c_hi = np.minimum(c_hi, win.col1 - 1)
        ok = c_lo <= c_hi
        start = (row[ok] - win.row0) * (win.col1 - win.col0 + 1) - win.col0
        self.starts.append(start + c_lo[ok])
        self.ends.append(start + c_hi[ok] + 1)

    def occupied(self) -> BoolArray:
        win = self.win
        seg = np.concatenate(self.segments, axis=1)
        element, winding = np.concatenate(self.segment_element), np.concatenate(self.segment_winding)
        self._add(_fill_spans(seg, element, winding, win))
        rows, cols = win.shape
        size = rows * (cols + 1)
        diff = np.bincount(np.concatenate(self.starts), minlength=size)
        diff -= np.bincount(np.concatenate(self.ends), minlength=size)
        return np.cumsum(diff.reshape(rows, cols + 1)[:, :cols], axis=1) > 0


def _expand(lo: IndexArray, hi: IndexArray) -> tuple[IndexArray, IndexArray]:
    """For inclusive ranges ``[lo, hi]`` (non-empty): the owner of every member, and the member."""
    count = hi - lo + 1
    owner = np.repeat(np.arange(len(lo)), count)
    shift = lo - (np.cumsum(count) - count)
    return owner, np.arange(len(owner)) + shift[owner]


def _batches(counts: IndexArray, limit: int) -> list[slice]:
    """Consecutive runs of items of at most ``limit`` total ``counts`` each (or of one item)."""
    if not len(counts):
        return []
    total = np.cumsum(counts)
    cuts = np.searchsorted(total, np.arange(limit, total[-1], limit), side="right")
    bounds = [0, *np.unique(cuts[(cuts > 0) & (cuts < len(counts))]).tolist(), len(counts)]
    return [slice(a, b) for a, b in pairwise(bounds)]


def _polygon_spans(
    polygons: _Polygons,
    idx: IndexArray | None,
    win: Window,
    tol: float,
    *,
    chunk_pairs: int,
) -> list[Spans]:
    """Spans of the cells of ``win`` rows touched by the polygons ``idx`` (None: all), expanded in
    batches of at most ``chunk_pairs`` (polygon, row) pairs.

    Cells are ``[c + s, c + 1 - s] x [r + s, r + 1 - s]`` in grid units, ``s = tol`` (``-tol`` for thin
    polygons); the polygons are in grid units already (:func:`twin.maps.raster.clip._slab_chunk`). A
    convex polygon touches every row its y-range meets; in a row, the columns its x-range within the
    strip meets.
    """
    sel = slice(None) if idx is None else idx
    s = np.where(polygons.thin[sel], -tol, tol)
    umin, vmin, umax, vmax = polygons.bounds[:, sel]
    c_lo = np.ceil(umin + s).astype(np.intp) - 1
    c_hi = np.floor(umax - s).astype(np.intp)
    r_lo = np.ceil(vmin + s).astype(np.intp) - 1
    r_hi = np.floor(vmax - s).astype(np.intp)
    # Inside one column's (or one row strip's) cell interval, a polygon's cells are its box's cells.
    boxed = ((c_lo == c_hi) & (umin >= c_lo + s) & (umax <= c_hi + 1 - s)) | (
        (r_lo == r_hi) & (vmin >= r_lo + s) & (vmax <= r_hi + 1 - s)
    )
    r_lo, r_hi = np.maximum(r_lo, win.row0), np.minimum(r_hi, win.row1 - 1)
    live = (r_lo <= r_hi) & (c_lo <= c_hi) & (c_hi >= win.col0) & (c_lo < win.col1)

    one = live & boxed & (r_lo == r_hi)  # most polygons: one span, no expansion
    out = [(r_lo[one], c_lo[one], c_hi[one])]
    pick = np.flatnonzero(live & boxed & ~one)
    for sl in _batches(r_hi[pick] - r_lo[pick] + 1, chunk_pairs):
        p = pick[sl]
        owner, row = _expand(r_lo[p], r_hi[p])
        out.append((row, c_lo[p][owner], c_hi[p][owner]))

    gen = np.flatnonzero(live & ~boxed)
    if not len(gen):
        return out
    xs = polygons.xs[:, gen if idx is None else idx[gen]]
    ys = polygons.ys[:, gen if idx is None else idx[gen]]
    # Triangles first, then quadrilaterals, then pentagons: zero-length padding edges are skipped.
    size = np.where(
        (xs[4] != xs[3]) | (ys[4] != ys[3]), 5, np.where((xs[3] != xs[2]) | (ys[3] != ys[2]), 4, 3)
    )
    order = np.argsort(size, kind="stable")
    gen, size = gen[order], size[order]
    u, v = xs[:, order], ys[:, order]
    for sl in _batches(r_hi[gen] - r_lo[gen] + 1, chunk_pairs):
        g = gen[sl]
        out.append(_strip_spans(u[:, sl], v[:, sl], size[sl], s=s[g], r_lo=r_lo[g], r_hi=r_hi[g]))
    return out


def _strip_spans(
    u: FloatArray, v: FloatArray, size: IndexArray, *, s: FloatArray, r_lo: IndexArray, r_hi: IndexArray
) -> Spans:
    """Exact spans of ``(5, g)`` polygons (grid units, sorted by vertex count) in rows ``[r_lo, r_hi]``.

    In the strip ``[r + s, r + 1 - s]`` each edge's part lies between its points at the clamped
    heights; the polygon's x-range there is the hull of those parts.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = (np.roll(u, -1, axis=0) - u) / (np.roll(v, -1, axis=0) - v)  # of edge j -> j+1
    slope[~np.isfinite(slope)] = 0.0  # horizontal edges (their end vertices count on their own)
    owner, row = _expand(r_lo, r_hi)
    so = s[owner]
    lo, hi = row + so, row + 1 - so
    pu = [u[j][owner] for j in range(MAX_VERTICES)]
    pv = [v[j][owner] for j in range(MAX_VERTICES)]
    n = len(row)
    p4, p5 = np.searchsorted(size[owner], [4, 5])
    a, b = np.full(n, np.inf), np.full(n, -np.inf)
    for j, k, first in ((0, 1, 0), (1, 2, 0), (4, 0, 0), (2, 3, p4), (3, 4, p5)):
        sl = slice(first, n)
        u1, v1, u2, v2, bottom, top = pu[j][sl], pv[j][sl], pu[k][sl], pv[k][sl], lo[sl], hi[sl]
        k_ = slope[j][owner[sl]]
        ua = u1 + (np.minimum(np.maximum(v1, bottom), top) - v1) * k_
        ub = u2 + (np.minimum(np.maximum(v2, bottom), top) - v2) * k_
        missed = (np.maximum(v1, v2) < bottom) | (np.minimum(v1, v2) > top)
        np.minimum(a[sl], np.where(missed, np.inf, np.minimum(ua, ub)), out=a[sl])
        np.maximum(b[sl], np.where(missed, -np.inf, np.maximum(ua, ub)), out=b[sl])
    keep = a <= b
    sk = so[keep]
    return row[keep], np.ceil(a[keep] + sk).astype(np.intp) - 1, np.floor(b[keep] - sk).astype(np.intp)


def _fill_spans(seg: FloatArray, seg_element: IndexArray, winding: Int8Array, win: Window) -> Spans:
    """Spans of the cells of ``win`` rows whose centre lies inside a closed element's section.

    ``seg`` is ``(4, s)`` in grid units, lower v first. A segment crosses the row line
    ``v = r + 0.5`` iff ``v1 <= r + 0.5 < v2`` (half-open, so a shared endpoint counts once).
    Crossings are sorted along each (element, row); between consecutive ones the points are inside
    iff the running winding number is non-zero.
    """
    u1, v1, u2, v2 = seg
    r_lo = np.maximum(np.ceil(v1 - 0.5).astype(np.intp), win.row0)
    r_hi = np.minimum(np.ceil(v2 - 0.5).astype(np.intp) - 1, win.row1 - 1)
    live = np.flatnonzero(r_lo <= r_hi)
    owner, row = _expand(r_lo[live], r_hi[live])
    owner = live[owner]
    x = u1[owner] + (row + 0.5 - v1[owner]) * ((u2 - u1) / np.where(v2 > v1, v2 - v1, 1.0))[owner]
    key = seg_element[owner] * (win.row1 - win.row0 + 1) + (row - win.row0)
    order = np.lexsort((x, key))
    key, x, row, step = key[order], x[order], row[order], winding[owner[order]]
    new = np.ones(len(key), dtype=bool)
    new[1:] = key[1:] != key[:-1]
    wind = np.cumsum(step, dtype=np.intp)
    wind -= (wind - step)[np.maximum.accumulate(np.where(new, np.arange(len(key)), 0))]
    start = np.flatnonzero((wind[:-1] != 0) & ~new[1:])
    return row[start], np.ceil(x[start] - 0.5).astype(np.intp), np.floor(x[start + 1] - 0.5).astype(np.intp)
