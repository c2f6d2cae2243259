"""Slab rasterising: which grid cells the elements' geometry between two heights touches.

The geometry of a height slab ``z_lo <= z <= z_hi`` is, for every triangle, its part inside the slab
(a convex polygon of up to 5 vertices) projected to XY, plus, for closed (watertight) elements, the
solid's interior inside the slab. A cell is occupied iff that geometry touches the cell, where

- cells are closed squares *shrunk* by ``Tolerances.cell_m`` for every projected polygon of positive
  area and for every polygon of a closed element (a wall face lying exactly on a grid line does not
  spill into the neighbouring cell), and
- cells are *grown* by ``Tolerances.cell_m`` for the degenerate polygons (area at most ``cell_m``
  times their extent: a vertical face seen from above, a point) of open elements, so thin open
  surfaces never vanish, not even on a grid line.

Closed elements are filled exactly: a cell overlapping the solid's projection either contains part of
its boundary, which lies on some clipped triangle, or has its centre inside the solid's section at
the slab's mid-height ``z_f``. The section is cast against every cell-centre row line; the crossings
are sorted per element and row and a point is inside where the winding number is non-zero, so
overlapping shells of one element, and overlapping elements, never cancel.

In each row strip a convex polygon touches exactly the cells whose x-interval overlaps the polygon's
x-range within the strip; spans become cells through a difference array. Everything is computed in
global grid coordinates, so a window is bit for bit the same window of the full result. A window can
also be computed from only the elements whose bounds meet it (with all their triangles): the other
elements contribute nothing there.

Arrays are processed whole, in cache-sized chunks, never per triangle or per cell. Inputs follow
trimesh's conventions (triangles ``(n, 3, 3) float64``, world metres); prepared geometry is stored
coordinate-major (``(5, m)``) because column access dominates the cost.

Example::

    frame = GridFrame.around(0.0, 0.0, 10.0, 8.0, resolution_m=0.05)
    occupied = rasterize_slab(triangles, element, closed, 0.05, 1.5, frame)  # (height, width) bool
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from itertools import pairwise
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from twin.errors import MapError
from twin.grid import GridFrame, Window

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]
BoolArray = npt.NDArray[np.bool_]
Int8Array = npt.NDArray[np.int8]
Spans = tuple[IntArray, IntArray, IntArray]  # (row, first column, last column), global cells

#: Polygon slots: a triangle clipped by two planes has at most 5 vertices.
MAX_VERTICES = 5


@dataclass(frozen=True, slots=True)
class Tolerances:
    """Numerical tolerances of rasterising.

    Attributes:
        cell_m: cells are shrunk (solid geometry) or grown (degenerate open surfaces) by this many
            metres; an open polygon is degenerate when its area is at most ``cell_m`` times its extent.
    """

    cell_m: float = 1e-9


TOLERANCES = Tolerances()


@dataclass(frozen=True, slots=True)
class RasterSettings:
    """Work sizes of rasterising: they change speed and memory, never the result.

    Attributes:
        chunk_triangles: triangles clipped at once (about 1 MB of input: the working set stays in cache).
        chunk_polygons: polygons rasterised at once.
        chunk_pairs: (polygon, row) pairs rasterised at once.
        tile_m: side, in metres, of the tiles :func:`slab_geometry` sorts each chunk's polygons by
            (the tile of their centre), so that runs of ``block`` polygons are compact.
        block: polygons per run whose bounds :class:`SlabGeometry` keeps as its window index.

    Example::

        tiny = RasterSettings(chunk_triangles=7, chunk_polygons=5, chunk_pairs=16, tile_m=0.3, block=3)
        assert (rasterize_slab(tri, el, closed, 0.0, 1.0, frame, settings=tiny) == full).all()
    """

    chunk_triangles: int = 1 << 14
    chunk_polygons: int = 1 << 15
    chunk_pairs: int = 1 << 17
    tile_m: float = 1.0
    block: int = 1 << 8

    def __post_init__(self) -> None:
        for name in ("chunk_triangles", "chunk_polygons", "chunk_pairs", "block"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
                msg = f"RasterSettings.{name} must be a positive integer, got {value!r}."
                raise MapError(msg)
        if not (isinstance(self.tile_m, int | float) and 0 < self.tile_m < np.inf):
            msg = f"RasterSettings.tile_m must be a positive, finite number of metres, got {self.tile_m!r}."
            raise MapError(msg)


RASTER_SETTINGS = RasterSettings()


class _Polygons(NamedTuple):
    """Clipped, projected polygons and section segments of some triangles (fields as in SlabGeometry)."""

    xs: FloatArray
    ys: FloatArray
    bounds: FloatArray
    thin: BoolArray
    segments: FloatArray
    segment_element: IntArray
    segment_winding: Int8Array


@dataclass(frozen=True, eq=False, slots=True)
class SlabGeometry:
    """The projected geometry of one slab, independent of any grid: rasterise it with :func:`rasterize`.

    Attributes:
        xs, ys: ``(5, m) float64`` world XY of the vertices of each clipped triangle's convex
            polygon (polygon ``i`` is ``xs[:, i], ys[:, i]``, in order); unused slots repeat the last.
        bounds: ``(4, m) float64`` rows ``xmin, ymin, xmax, ymax`` of each polygon.
        thin: ``(m,) bool`` degenerate polygon of an open element (rasterised with grown cells).
        segments: ``(4, s) float64`` rows ``x1, y1, x2, y2``: the closed elements' section at the
            slab's mid-height, the endpoint of lower y (then lower x) first.
        segment_element: ``(s,) intp`` element of each segment.
        segment_winding: ``(s,) int8`` +1 if the segment, oriented with its solid on the left, runs
            towards +y, else -1.
        block_bounds: ``(4, ceil(m / block)) float64`` bounds of each run of ``block`` consecutive
            polygons (sorted, chunk by chunk, by the ``RasterSettings.tile_m`` tile of their centre): a
            coarse spatial index that lets a window skip most polygons.
        block: polygons per run of ``block_bounds`` (the ``RasterSettings.block`` it was made with).
    """

    xs: FloatArray
    ys: FloatArray
    bounds: FloatArray
    thin: BoolArray
    segments: FloatArray
    segment_element: IntArray
    segment_winding: Int8Array
    block_bounds: FloatArray
    block: int = RASTER_SETTINGS.block


def rasterize_slab(  # noqa: PLR0917 (the map generator's established call)
    triangles: FloatArray,
    element: IntArray,
    closed: BoolArray,
    z_lo: float,
    z_hi: float,
    frame: GridFrame,
    window: Window | None = None,
    *,
    tol: Tolerances = TOLERANCES,
    settings: RasterSettings = RASTER_SETTINGS,
) -> BoolArray:
    """Cells of ``window`` (default: the whole frame) touched by the elements between ``z_lo`` and ``z_hi``.

    Args:
        triangles: ``(n, 3, 3) float64`` world xyz of each triangle's vertices, metres.
        element: ``(n,)`` integer index of the element each triangle belongs to, in ``[0, k)``.
        closed: ``(k,) bool`` per element: True if its mesh is a watertight solid (then it is filled;
            faces should be consistently oriented, as a solid's are).
        z_lo, z_hi: the slab, world z, ``z_lo <= z_hi``.
        frame: the grid.
        window: compute only these cells; equal bit for bit to the same window of the full result.
        tol: numerical tolerances.
        settings: work sizes (the result does not depend on them).

    Returns:
        ``(window rows, window cols) bool``, True = occupied.

    Raises:
        MapError: on a malformed argument (the message names it).
    """
    _check_inputs(triangles, element, closed, z_lo, z_hi)
    win = _check_window(frame, window)
    region = None if win == frame.full else _region(frame, win, frame.resolution_m + tol.cell_m)
    cells = _Cells(frame, win, tol, settings)
    parts = _parts(
        triangles, element, closed, z_lo=z_lo, z_hi=z_hi, region=region, tol=tol, settings=settings
    )
    for part in parts:
        cells.add_polygons(part)
        cells.add_segments(part)
    return cells.occupied()


def slab_geometry(
    triangles: FloatArray,
    element: IntArray,
    closed: BoolArray,
    z_lo: float,
    z_hi: float,
    *,
    tol: Tolerances = TOLERANCES,
    settings: RasterSettings = RASTER_SETTINGS,
) -> SlabGeometry:
    """Clip the triangles to the slab and section the closed elements at its mid-height.

    Arguments are those of :func:`rasterize_slab`. Keep the result to rasterise many windows of one
    slab quickly with :func:`rasterize`.
    """
    _check_inputs(triangles, element, closed, z_lo, z_hi)
    parts = [
        _by_tile(p, settings.tile_m)
        for p in _parts(
            triangles, element, closed, z_lo=z_lo, z_hi=z_hi, region=None, tol=tol, settings=settings
        )
    ]
    p = _Polygons(*(np.concatenate(field, axis=-1) for field in zip(*parts, strict=True)))
    starts = np.arange(0, p.thin.size, settings.block)
    blocks = np.empty((4, len(starts)))
    for i, op in enumerate((np.minimum, np.minimum, np.maximum, np.maximum)):
        blocks[i] = op.reduceat(p.bounds[i], starts) if len(starts) else blocks[i]
    return SlabGeometry(*p, block_bounds=blocks, block=settings.block)


def _by_tile(p: _Polygons, tile_m: float) -> _Polygons:
    """The polygons of one chunk sorted by the ``tile_m`` tile of their centre (compact index blocks)."""
    if not p.thin.size:
        return p
    centre = 0.5 * (p.bounds[:2] + p.bounds[2:]) / tile_m
    tile = (centre - centre.min(axis=1, keepdims=True)).astype(np.int64)
    order = np.argsort(tile[1] * (tile[0].max() + 1) + tile[0], kind="stable")
    return p._replace(xs=p.xs[:, order], ys=p.ys[:, order], bounds=p.bounds[:, order], thin=p.thin[order])


def rasterize(
    geometry: SlabGeometry,
    frame: GridFrame,
    window: Window | None = None,
    *,
    tol: Tolerances = TOLERANCES,
    settings: RasterSettings = RASTER_SETTINGS,
) -> BoolArray:
    """Cells of ``window`` (default: the whole frame) touched by ``geometry``: ``(rows, cols) bool``.

    Equal to :func:`rasterize_slab` with the arguments ``geometry`` was made from. The index block
    size is ``geometry``'s own; ``settings`` gives the chunk sizes.
    """
    win = _check_window(frame, window)
    cells = _Cells(frame, win, tol, settings)
    x0, y0, x1, y1 = _region(frame, win, tol.cell_m + 1e-6 * frame.resolution_m)
    chunk, block = settings.chunk_polygons, geometry.block
    if win == frame.full:
        for i in range(0, geometry.thin.size, chunk):
            cells.add_polygons(geometry, np.arange(i, min(i + chunk, geometry.thin.size)))
    else:
        bx0, by0, bx1, by1 = geometry.block_bounds
        blocks = np.flatnonzero((bx1 >= x0) & (by1 >= y0) & (bx0 <= x1) & (by0 <= y1))
        _, candidates = _expand(blocks * block, np.minimum(blocks * block + block, geometry.thin.size) - 1)
        xmin, ymin, xmax, ymax = geometry.bounds[:, candidates]
        picked = candidates[(xmax >= x0) & (ymax >= y0) & (xmin <= x1) & (ymin <= y1)]
        for i in range(0, len(picked), chunk):
            cells.add_polygons(geometry, picked[i : i + chunk])
    cells.add_segments(geometry, np.flatnonzero((geometry.segments[3] >= y0) & (geometry.segments[1] <= y1)))
    return cells.occupied()


def _region(frame: GridFrame, win: Window, pad: float) -> tuple[float, float, float, float]:
    """World ``xmin, ymin, xmax, ymax`` of the window's cells grown by ``pad``."""
    res = frame.resolution_m
    return (
        frame.origin_x + win.col0 * res - pad,
        frame.origin_y + win.row0 * res - pad,
        frame.origin_x + win.col1 * res + pad,
        frame.origin_y + win.row1 * res + pad,
    )


class _Cells:
    """Collects the spans of one window as difference-array indices, and the section segments to fill."""

    def __init__(self, frame: GridFrame, win: Window, tol: Tolerances, settings: RasterSettings) -> None:
        self.frame, self.win, self.tol = frame, win, tol.cell_m / frame.resolution_m
        self.chunk_pairs = settings.chunk_pairs
        self.starts: list[IntArray] = []
        self.ends: list[IntArray] = []
        self.segments: list[FloatArray] = [np.empty((4, 0))]
        self.segment_element: list[IntArray] = [np.empty(0, np.intp)]
        self.segment_winding: list[Int8Array] = [np.empty(0, np.int8)]

    def add_polygons(self, polygons: _Polygons | SlabGeometry, idx: IntArray | None = None) -> None:
        for spans in _polygon_spans(
            polygons, idx, self.frame, self.win, self.tol, chunk_pairs=self.chunk_pairs
        ):
            self._add(spans)

    def add_segments(self, source: _Polygons | SlabGeometry, idx: IntArray | slice = slice(None)) -> None:
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
        f, win = self.frame, self.win
        origin = np.array([[f.origin_x], [f.origin_y], [f.origin_x], [f.origin_y]])
        seg = (np.concatenate(self.segments, axis=1) - origin) / f.resolution_m
        element, winding = np.concatenate(self.segment_element), np.concatenate(self.segment_winding)
        self._add(_fill_spans(seg, element, winding, win))
        rows, cols = win.shape
        size = rows * (cols + 1)
        diff = np.bincount(np.concatenate(self.starts), minlength=size)
        diff -= np.bincount(np.concatenate(self.ends), minlength=size)
        return np.cumsum(diff.reshape(rows, cols + 1)[:, :cols], axis=1) > 0


# -- checks ----------------------------------------------------------------------------------------


def _check_inputs(triangles: object, element: object, closed: object, z_lo: float, z_hi: float) -> None:
    if not isinstance(triangles, np.ndarray) or triangles.ndim != 3 or triangles.shape[1:] != (3, 3):
        shape = getattr(triangles, "shape", type(triangles).__name__)
        msg = f"triangles must be an array of shape (n, 3, 3), got {shape}."
        raise MapError(msg)
    if triangles.dtype != np.float64:
        msg = f"triangles must be float64, got {triangles.dtype}."
        raise MapError(msg)
    n = len(triangles)
    if not isinstance(element, np.ndarray) or element.shape != (n,):
        shape = getattr(element, "shape", type(element).__name__)
        msg = f"element must be an array of shape ({n},), one per triangle, got {shape}."
        raise MapError(msg)
    if not np.issubdtype(element.dtype, np.integer):
        msg = f"element must have an integer dtype, got {element.dtype}."
        raise MapError(msg)
    if not isinstance(closed, np.ndarray) or closed.ndim != 1 or closed.dtype != np.bool_:
        desc = f"{closed.dtype} array of shape {closed.shape}" if isinstance(closed, np.ndarray) else closed
        msg = f"closed must be a 1-d bool array, one flag per element, got {desc}."
        raise MapError(msg)
    if n and (element.min() < 0 or element.max() >= len(closed)):
        msg = f"element indices must lie in [0, {len(closed)}), got [{element.min()}, {element.max()}]."
        raise MapError(msg)
    if not (np.isfinite(z_lo) and np.isfinite(z_hi) and z_lo <= z_hi):
        msg = f"Slab must be finite with z_lo <= z_hi, got z_lo={z_lo!r}, z_hi={z_hi!r}."
        raise MapError(msg)


def _check_window(frame: GridFrame, window: Window | None) -> Window:
    win = frame.full if window is None else window
    if not (0 <= win.row0 <= win.row1 <= frame.height and 0 <= win.col0 <= win.col1 <= frame.width):
        msg = f"Window {win} must lie inside the grid of {frame.height}x{frame.width} cells."
        raise MapError(msg)
    return win


# -- slab geometry ---------------------------------------------------------------------------------


def _parts(
    triangles: FloatArray,
    element: IntArray,
    closed: BoolArray,
    *,
    z_lo: float,
    z_hi: float,
    region: tuple[float, float, float, float] | None,
    tol: Tolerances,
    settings: RasterSettings,
) -> Iterator[_Polygons]:
    """The slab geometry of the triangles meeting the slab (and the world ``region``), chunk by chunk.

    The triangles are culled first (a few cheap passes), so the clipping works on full chunks of
    survivors. Triangles missing the region are dropped, except that the section keeps all those
    of the region's y-range: a row's fill needs all its crossings, however far in x.
    """
    picked: list[IntArray] = []
    inside: list[BoolArray] = []
    size = settings.chunk_triangles
    for i in range(0, len(triangles), size):
        chunk = triangles[i : i + size]
        if not (np.isfinite(chunk.sum()) or np.isfinite(chunk).all()):
            bad = i + int(np.flatnonzero(~np.isfinite(chunk).all(axis=(1, 2)))[0])
            msg = f"triangles must be finite, triangle {bad} is {triangles[bad].tolist()}."
            raise MapError(msg)
        zmin, zmax = _min_max(chunk, 2)
        idx = np.flatnonzero((zmax >= z_lo) & (zmin <= z_hi))
        if region is not None:
            ymin, ymax = _min_max(chunk[idx], 1)
            idx = idx[(ymax >= region[1]) & (ymin <= region[3])]
            xmin, xmax = _min_max(chunk[idx], 0)
            inside.append((xmax >= region[0]) & (xmin <= region[2]))
        picked.append(idx + i)
    idx = np.concatenate(picked) if picked else np.empty(0, np.intp)
    flags = np.concatenate(inside) if inside else np.ones(len(idx), dtype=bool)
    for i in range(0, max(len(idx), 1), size):
        sel = idx[i : i + size]
        run = len(sel) > 0 and sel[-1] - sel[0] == len(sel) - 1
        rows: slice | IntArray = slice(sel[0], sel[-1] + 1) if run else sel  # a run needs no copy
        keep = flags[i : i + size]
        part = _slab_chunk(triangles[rows], element[rows], keep, closed=closed, z_lo=z_lo, z_hi=z_hi, tol=tol)
        if region is not None:
            seg = part.segments
            near = (seg[3] >= region[1]) & (seg[1] <= region[3])
            part = part._replace(
                segments=seg[:, near],
                segment_element=part.segment_element[near],
                segment_winding=part.segment_winding[near],
            )
        yield part


def _slab_chunk(
    chunk: FloatArray,
    element: IntArray,
    keep: BoolArray,
    *,
    closed: BoolArray,
    z_lo: float,
    z_hi: float,
    tol: Tolerances,
) -> _Polygons:
    """Polygons of the triangles ``keep`` of a chunk meeting the slab; section of them all.

    Triangles wholly inside the slab come first, then clipped ones.
    """
    zmin, zmax = _min_max(chunk, 2)
    whole = np.flatnonzero(keep & (zmin >= z_lo) & (zmax <= z_hi))
    cut = np.flatnonzero(keep & ((zmin < z_lo) | (zmax > z_hi)))
    nw, m = len(whole), len(whole) + len(cut)
    xs, ys = np.empty((MAX_VERTICES, m)), np.empty((MAX_VERTICES, m))
    tw = chunk[whole]
    xs[:3, :nw], ys[:3, :nw] = tw[:, :, 0].T, tw[:, :, 1].T
    xs[3:, :nw], ys[3:, :nw] = xs[2, :nw], ys[2, :nw]
    xs[:, nw:], ys[:, nw:] = _clip_to_slab(chunk[cut], z_lo, z_hi)

    bounds = np.empty((4, m))
    x0, x1, x2 = xs[:3, :nw]
    y0, y1, y2 = ys[:3, :nw]
    np.minimum(np.minimum(x0, x1), x2, out=bounds[0, :nw])
    np.minimum(np.minimum(y0, y1), y2, out=bounds[1, :nw])
    np.maximum(np.maximum(x0, x1), x2, out=bounds[2, :nw])
    np.maximum(np.maximum(y0, y1), y2, out=bounds[3, :nw])
    area2 = np.empty(m)
    area2[:nw] = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
    px, py = xs[:, nw:], ys[:, nw:]
    bounds[:, nw:] = [px.min(axis=0), py.min(axis=0), px.max(axis=0), py.max(axis=0)]
    dx, dy = px[1:] - px[0], py[1:] - py[0]
    area2[nw:] = (dx[:-1] * dy[1:] - dy[:-1] * dx[1:]).sum(axis=0)
    solid = closed[element]
    extent = np.maximum(bounds[2] - bounds[0], bounds[3] - bounds[1])
    thin = (np.abs(area2) <= (2 * tol.cell_m) * extent) & ~solid[np.concatenate([whole, cut])]

    z_f = 0.5 * (z_lo + z_hi)
    crossing = np.flatnonzero(solid & (zmin < z_f) & (zmax >= z_f))
    segments, winding = _section(chunk[crossing], z_f)
    return _Polygons(xs, ys, bounds, thin, segments, element[crossing].astype(np.intp), winding)


def _min_max(chunk: FloatArray, axis: int) -> tuple[FloatArray, FloatArray]:
    """Per triangle, the least and greatest coordinate ``axis`` (0 x, 1 y, 2 z) of its vertices."""
    a, b, c = chunk[:, 0, axis], chunk[:, 1, axis], chunk[:, 2, axis]
    return np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)


def _clip_to_slab(tri: FloatArray, z_lo: float, z_hi: float) -> tuple[FloatArray, FloatArray]:
    """``(5, m)`` xs and ys of triangles ``(m, 3, 3)`` clipped to ``z_lo <= z <= z_hi`` and projected.

    Every triangle passed must touch the slab. Each edge contributes its start vertex if inside, then
    its strict crossings of the planes in order along it; the points keep the triangle's winding. An
    edge's crossing is computed from its lower endpoint, so neighbours share crossings exactly.
    """
    x, y, z = np.ascontiguousarray(tri.transpose(2, 1, 0))  # each (3 vertices, m)
    m = x.shape[1]
    inside = (z >= z_lo) & (z <= z_hi)
    sx, sy = np.empty((9, m)), np.empty((9, m))
    valid = np.empty((9, m), dtype=bool)
    for j in range(3):
        k = (j + 1) % 3
        zp, zq = z[j], z[k]
        up = zp < zq
        ax, ay, az = np.where(up, x[j], x[k]), np.where(up, y[j], y[k]), np.where(up, zp, zq)
        bx, by = np.where(up, x[k], x[j]), np.where(up, y[k], y[j])
        dz = np.abs(zq - zp)
        dz[dz == 0] = 1.0  # such an edge crosses no plane strictly
        with np.errstate(all="ignore"):  # edges crossing no plane get unused, possibly infinite, points
            t_lo, t_hi = (z_lo - az) / dz, (z_hi - az) / dz
            lo_x, lo_y = ax + t_lo * (bx - ax), ay + t_lo * (by - ay)
            hi_x, hi_y = ax + t_hi * (bx - ax), ay + t_hi * (by - ay)
        cross_lo = ((zp < z_lo) & (zq > z_lo)) | ((zp > z_lo) & (zq < z_lo))
        cross_hi = (((zp < z_hi) & (zq > z_hi)) | ((zp > z_hi) & (zq < z_hi))) & (z_hi > z_lo)
        sx[3 * j], sy[3 * j], valid[3 * j] = x[j], y[j], inside[j]
        sx[3 * j + 1], sy[3 * j + 1] = np.where(up, lo_x, hi_x), np.where(up, lo_y, hi_y)
        sx[3 * j + 2], sy[3 * j + 2] = np.where(up, hi_x, lo_x), np.where(up, hi_y, lo_y)
        valid[3 * j + 1] = np.where(up, cross_lo, cross_hi)
        valid[3 * j + 2] = np.where(up, cross_hi, cross_lo)
    slot = np.cumsum(valid, axis=0) - 1  # packed position of each valid point
    r, c = np.nonzero(valid)
    qx, qy = np.empty_like(sx), np.empty_like(sy)
    qx[slot[r, c], c], qy[slot[r, c], c] = sx[r, c], sy[r, c]
    take = np.minimum(np.arange(MAX_VERTICES)[:, None], slot[-1])  # then repeat the last point
    cols = np.arange(m)
    return qx[take, cols], qy[take, cols]


def _section(tri: FloatArray, z_f: float) -> tuple[FloatArray, Int8Array]:
    """Where triangles ``(s, 3, 3)`` crossing ``z_f`` meet that plane: ``(4, s)`` segments and windings.

    Segments are rows ``x1, y1, x2, y2``, the endpoint of lower y (then x) first; the winding is +1
    if the segment, oriented with the solid on its left (outward normal on its right), runs towards
    +y, else -1. The orientation follows from the vertex order alone: with ``k`` the vertex alone on
    its side, the segment runs from the crossing on edge ``k-1 -> k`` to the one on edge ``k -> k+1``
    if ``k`` is below, the other way if above. A vertex at exactly ``z_f`` counts as above (symbolic
    perturbation), so a watertight mesh gives closed loops with bit-identical joints.
    """
    x, y, z = np.ascontiguousarray(tri.transpose(2, 1, 0))
    below = z < z_f
    ex, ey = np.empty_like(x), np.empty_like(y)
    for j in range(3):  # the crossing on edge j -> j+1, computed from its endpoint below
        k = (j + 1) % 3
        bj = below[j]
        ax, ay, az = np.where(bj, x[j], x[k]), np.where(bj, y[j], y[k]), np.where(bj, z[j], z[k])
        bx, by = np.where(bj, x[k], x[j]), np.where(bj, y[k], y[j])
        dz = np.abs(z[k] - z[j])
        dz[dz == 0] = 1.0  # no crossing there
        with np.errstate(all="ignore"):  # edges not crossing get unused, possibly infinite, points
            t = (z_f - az) / dz
            ex[j], ey[j] = ax + t * (bx - ax), ay + t * (by - ay)
    odd_below = below.sum(axis=0) == 1
    k = np.where(odd_below, np.argmax(below, axis=0), np.argmin(below, axis=0))
    into, out = (k + 2) % 3, k  # edges k-1 -> k and k -> k+1
    first, second = np.where(odd_below, into, out), np.where(odd_below, out, into)
    cols = np.arange(x.shape[1])
    x1, y1, x2, y2 = ex[first, cols], ey[first, cols], ex[second, cols], ey[second, cols]
    swap = (y1 > y2) | ((y1 == y2) & (x1 > x2))
    lower = [np.where(swap, x2, x1), np.where(swap, y2, y1)]
    upper = [np.where(swap, x1, x2), np.where(swap, y1, y2)]
    return np.stack([*lower, *upper]), np.where(swap, -1, 1).astype(np.int8)


# -- rasterising -----------------------------------------------------------------------------------


def _expand(lo: IntArray, hi: IntArray) -> tuple[IntArray, IntArray]:
    """For inclusive ranges ``[lo, hi]`` (non-empty): the owner of every member, and the member."""
    count = hi - lo + 1
    owner = np.repeat(np.arange(len(lo)), count)
    shift = lo - (np.cumsum(count) - count)
    return owner, np.arange(len(owner)) + shift[owner]


def _batches(counts: IntArray, limit: int) -> list[slice]:
    """Consecutive runs of items of at most ``limit`` total ``counts`` each (or of one item)."""
    if not len(counts):
        return []
    total = np.cumsum(counts)
    cuts = np.searchsorted(total, np.arange(limit, total[-1], limit), side="right")
    bounds = [0, *np.unique(cuts[(cuts > 0) & (cuts < len(counts))]).tolist(), len(counts)]
    return [slice(a, b) for a, b in pairwise(bounds)]


def _polygon_spans(
    polygons: _Polygons | SlabGeometry,
    idx: IntArray | None,
    frame: GridFrame,
    win: Window,
    tol: float,
    *,
    chunk_pairs: int,
) -> list[Spans]:
    """Spans of the cells of ``win`` rows touched by the polygons ``idx`` (None: all), expanded in
    batches of at most ``chunk_pairs`` (polygon, row) pairs.

    Cells are ``[c + s, c + 1 - s] x [r + s, r + 1 - s]`` in grid units, ``s = tol`` (``-tol`` for thin
    polygons). A convex polygon touches every row its y-range meets; in a row, the columns its x-range
    within the strip meets. Grid units are monotone in world units, so bounds transform exactly.
    """
    res, ox, oy = frame.resolution_m, frame.origin_x, frame.origin_y
    sel = slice(None) if idx is None else idx
    s = np.where(polygons.thin[sel], -tol, tol)
    xmin, ymin, xmax, ymax = polygons.bounds[:, sel]
    umin, umax = (xmin - ox) / res, (xmax - ox) / res
    vmin, vmax = (ymin - oy) / res, (ymax - oy) / res
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
    u, v = (xs[:, order] - ox) / res, (ys[:, order] - oy) / res
    for sl in _batches(r_hi[gen] - r_lo[gen] + 1, chunk_pairs):
        g = gen[sl]
        out.append(_strip_spans(u[:, sl], v[:, sl], size[sl], s=s[g], r_lo=r_lo[g], r_hi=r_hi[g]))
    return out


def _strip_spans(
    u: FloatArray, v: FloatArray, size: IntArray, *, s: FloatArray, r_lo: IntArray, r_hi: IntArray
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


def _fill_spans(seg: FloatArray, seg_element: IntArray, winding: Int8Array, win: Window) -> Spans:
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
