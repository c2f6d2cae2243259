"""Slab geometry: input checks, culling, clipping triangles to the slab, and the mid-height section.

Produces the projected polygons (:class:`_Polygons`, chunk by chunk) that :mod:`twin.maps.raster.spans`
turns into cells, and defines :class:`SlabGeometry`, their grid-independent, indexed whole.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from twin.errors import MapError
from twin.maps.grid import GridFrame, Window, grid_coordinates
from twin.maps.raster.settings import (
    MAX_VERTICES,
    RASTER_SETTINGS,
    BoolArray,
    FloatArray,
    IndexArray,
    Int8Array,
    RasterSettings,
)
from twin.tolerances import Tolerances


class _Polygons(NamedTuple):
    """Clipped, projected polygons and section segments of some triangles.

    Attributes:
        xs, ys: ``(5, m) float64`` XY in grid units (:func:`twin.maps.grid.grid_coordinates`) of the
            vertices of each clipped triangle's convex polygon (polygon ``i`` is ``xs[:, i], ys[:, i]``,
            in order); unused slots repeat the last.
        bounds: ``(4, m) float64`` rows ``xmin, ymin, xmax, ymax`` of each polygon.
        thin: ``(m,) bool`` degenerate polygon of an open element (rasterised with grown cells).
        segments: ``(4, s) float64`` rows ``x1, y1, x2, y2`` (grid units): the closed elements' section
            at the slab's mid-height, the endpoint of lower y (then lower x) first.
        segment_element: ``(s,) intp`` element of each segment.
        segment_winding: ``(s,) int8`` +1 if the segment, oriented with its solid on the left, runs
            towards +y, else -1.
    """

    xs: FloatArray
    ys: FloatArray
    bounds: FloatArray
    thin: BoolArray
    segments: FloatArray
    segment_element: IndexArray
    segment_winding: Int8Array


@dataclass(frozen=True, eq=False, slots=True)
class SlabGeometry:
    """The projected geometry of one slab on one grid: rasterise it with :func:`rasterize`.

    Attributes:
        grid: ``(origin_x, origin_y, resolution_m)`` of the frames it can be rasterised on (its
            coordinates are in their grid units; a frame's size and windows may vary).
        polygons: the clipped polygons and section segments (see :class:`_Polygons`), sorted chunk
            by chunk by the ``RasterSettings.tile_m`` tile of their centre.
        block_bounds: ``(4, ceil(m / block)) float64`` bounds of each run of ``block`` consecutive
            polygons: a coarse spatial index that lets a window skip most polygons.
        block: polygons per run of ``block_bounds`` (the ``RasterSettings.block`` it was made with).
    """

    grid: tuple[float, float, float]
    polygons: _Polygons
    block_bounds: FloatArray
    block: int = RASTER_SETTINGS.block


def _region(frame: GridFrame, win: Window, pad: float) -> tuple[float, float, float, float]:
    """World ``xmin, ymin, xmax, ymax`` of the window's cells grown by ``pad``."""
    res = frame.resolution_m
    return (
        frame.origin_x + win.col0 * res - pad,
        frame.origin_y + win.row0 * res - pad,
        frame.origin_x + win.col1 * res + pad,
        frame.origin_y + win.row1 * res + pad,
    )


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
    element: IndexArray,
    closed: BoolArray,
    *,
    z_lo: float,
    z_hi: float,
    region: tuple[float, float, float, float] | None,
    frame: GridFrame,
    tol: Tolerances,
    settings: RasterSettings,
) -> Iterator[_Polygons]:
    """The slab geometry of the triangles meeting the slab (and the world ``region``), chunk by chunk,
    in ``frame``'s grid units.

    The triangles are culled first (a few cheap passes), so the clipping works on full chunks of
    survivors. Triangles missing the region are dropped, except that the section keeps all those
    of the region's y-range: a row's fill needs all its crossings, however far in x.
    """
    res = frame.resolution_m
    picked: list[IndexArray] = []
    inside: list[BoolArray] = []
    size = settings.chunk_triangles
    for i in range(0, len(triangles), size):
        chunk = triangles[i : i + size]
        if not (np.isfinite(chunk.sum()) or np.isfinite(chunk).all()):
            bad = i + int(np.flatnonzero(~np.isfinite(chunk).all(axis=(1, 2)))[0])
            msg = f"triangles must be finite, triangle {bad} is {triangles[bad].tolist()}."
            raise MapError(msg)
        zmin, zmax = _min_max(chunk, 2)
        idx = np.flatnonzero((zmax >= z_lo - tol.grid_m) & (zmin <= z_hi + tol.grid_m))  # see _slab_chunk
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
        rows: slice | IndexArray = slice(sel[0], sel[-1] + 1) if run else sel  # a run needs no copy
        keep = flags[i : i + size]
        part = _slab_chunk(
            triangles[rows], element[rows], keep, closed=closed, z_lo=z_lo, z_hi=z_hi, frame=frame, tol=tol
        )
        if region is not None:
            seg = part.segments
            y0, y1 = (region[1] - frame.origin_y) / res, (region[3] - frame.origin_y) / res
            near = (seg[3] >= y0) & (seg[1] <= y1)
            part = part._replace(
                segments=seg[:, near],
                segment_element=part.segment_element[near],
                segment_winding=part.segment_winding[near],
            )
        yield part


def _slab_chunk(
    chunk: FloatArray,
    element: IndexArray,
    keep: BoolArray,
    *,
    closed: BoolArray,
    z_lo: float,
    z_hi: float,
    frame: GridFrame,
    tol: Tolerances,
) -> _Polygons:
    """Polygons of the triangles ``keep`` of a chunk meeting the slab; section of them all.

    Triangles wholly inside the slab come first, then clipped ones. The vertices are taken to the
    frame's grid units first (:func:`twin.maps.grid.grid_coordinates`: a coordinate within
    ``Tolerances.grid_m`` of a grid line is on it), so clipping interpolates between the vertices on
    the lines, and a polygon of an open element flattened onto a line is thin (its cells grown). A z
    within ``grid_m`` of the slab's bottom or top is on it, so a face on the band's end is decided the
    same wherever the building sits (an elevation of 10 km rounds ``elevation + height`` and the face's
    z differently, by picometres). A filled solid that only touches the band's end (a box resting on
    its bottom, a shelf hanging at its top) occupies no space in it and contributes nothing, as in a
    boolean with the band's cuboid; an open surface lying on the end is in the band (thin things never
    vanish). A slab of no thickness keeps every touching triangle.
    """
    res = frame.resolution_m
    grid = np.empty_like(chunk)
    grid[..., 0] = grid_coordinates(chunk[..., 0], frame.origin_x, res)
    grid[..., 1] = grid_coordinates(chunk[..., 1], frame.origin_y, res)
    grid[..., 2] = snap_to_band(chunk[..., 2], z_lo, z_hi, tol.grid_m)
    chunk = grid
    zmin, zmax = _min_max(chunk, 2)
    if z_lo < z_hi:  # a filled solid that only touches the band's end occupies no space in it
        keep = keep & ~(closed[element] & ((zmax <= z_lo) | (zmin >= z_hi)))
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
    thin = (np.abs(area2) <= (2 * tol.cell_m / res) * extent) & ~solid[np.concatenate([whole, cut])]

    z_f = 0.5 * (z_lo + z_hi)
    crossing = np.flatnonzero(solid & (zmin < z_f) & (zmax >= z_f))
    segments, winding = _section(chunk[crossing], z_f)
    return _Polygons(xs, ys, bounds, thin, segments, element[crossing].astype(np.intp), winding)


def snap_to_band(z: FloatArray, z_lo: float, z_hi: float, within: float) -> FloatArray:
    """``z`` with every value within ``within`` of ``z_lo`` or ``z_hi`` set to it exactly.

    Example::

        snap_to_band(np.array([0.0499999999, 0.3, 1.5000004]), 0.05, 1.5, 1e-6)   # [0.05, 0.3, 1.5]
    """
    out = np.where(np.abs(z - z_lo) <= within, z_lo, z)
    return np.where(np.abs(z - z_hi) <= within, z_hi, out)


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
