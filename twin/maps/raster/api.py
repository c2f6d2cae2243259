"""The rasterising entry points: :func:`rasterize_slab`, and :func:`slab_geometry` with :func:`rasterize`."""

from __future__ import annotations

import numpy as np

from twin.errors import MapError
from twin.maps.grid import GridFrame, Window
from twin.maps.raster.clip import SlabGeometry, _check_inputs, _check_window, _parts, _Polygons, _region
from twin.maps.raster.settings import RASTER_SETTINGS, BoolArray, FloatArray, IndexArray, RasterSettings
from twin.maps.raster.spans import _Cells, _expand
from twin.tolerances import TOLERANCES, Tolerances


def rasterize_slab(  # noqa: PLR0917 (the map generator's established call)
    triangles: FloatArray,
    element: IndexArray,
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
        closed: ``(k,) bool`` per element: True to fill it, for a watertight mesh or a solid's mesh
            whose section is made of closed loops (:func:`twin.maps.raster.closed_sections`); faces should
            be consistently oriented, as a solid's are.
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
        triangles,
        element,
        closed,
        z_lo=z_lo,
        z_hi=z_hi,
        region=region,
        frame=frame,
        tol=tol,
        settings=settings,
    )
    for part in parts:
        cells.add_polygons(part)
        cells.add_segments(part)
    return cells.occupied()


def slab_geometry(  # noqa: PLR0917 (rasterize_slab's call, less the window)
    triangles: FloatArray,
    element: IndexArray,
    closed: BoolArray,
    z_lo: float,
    z_hi: float,
    frame: GridFrame,
    *,
    tol: Tolerances = TOLERANCES,
    settings: RasterSettings = RASTER_SETTINGS,
) -> SlabGeometry:
    """Clip the triangles to the slab and section the closed elements at its mid-height, in the grid
    units of ``frame`` (its origin and resolution: the grid's ties are decided on its lines).

    Arguments are those of :func:`rasterize_slab`. Keep the result to rasterise many windows of one
    slab quickly with :func:`rasterize`, on ``frame`` or any frame of the same origin and resolution.
    """
    _check_inputs(triangles, element, closed, z_lo, z_hi)
    tile = settings.tile_m / frame.resolution_m
    parts = [
        _by_tile(p, tile)
        for p in _parts(
            triangles,
            element,
            closed,
            z_lo=z_lo,
            z_hi=z_hi,
            region=None,
            frame=frame,
            tol=tol,
            settings=settings,
        )
    ]
    p = _Polygons(*(np.concatenate(field, axis=-1) for field in zip(*parts, strict=True)))
    starts = np.arange(0, p.thin.size, settings.block)
    blocks = np.empty((4, len(starts)))
    for i, op in enumerate((np.minimum, np.minimum, np.maximum, np.maximum)):
        blocks[i] = op.reduceat(p.bounds[i], starts) if len(starts) else blocks[i]
    grid = (frame.origin_x, frame.origin_y, frame.resolution_m)
    return SlabGeometry(grid, p, block_bounds=blocks, block=settings.block)


def _by_tile(p: _Polygons, side: float) -> _Polygons:
    """The polygons of one chunk sorted by the tile (of ``side`` grid units) of their centre (compact
    index blocks)."""
    if not p.thin.size:
        return p
    centre = 0.5 * (p.bounds[:2] + p.bounds[2:]) / side
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

    Raises:
        MapError: ``frame``'s origin or resolution is not the one ``geometry`` was made on.
    """
    win = _check_window(frame, window)
    if geometry.grid != (frame.origin_x, frame.origin_y, frame.resolution_m):
        msg = (
            f"Slab geometry made on the grid (origin_x, origin_y, resolution_m) = {geometry.grid} cannot "
            f"be rasterised on a frame at ({frame.origin_x}, {frame.origin_y}, {frame.resolution_m})."
        )
        raise MapError(msg)
    cells = _Cells(frame, win, tol, settings)
    pad = tol.cell_m / frame.resolution_m + 1e-6  # grid units
    x0, y0, x1, y1 = win.col0 - pad, win.row0 - pad, win.col1 + pad, win.row1 + pad
    chunk, block, p = settings.chunk_polygons, geometry.block, geometry.polygons
    if win == frame.full:
        for i in range(0, p.thin.size, chunk):
            cells.add_polygons(p, np.arange(i, min(i + chunk, p.thin.size)))
    else:
        bx0, by0, bx1, by1 = geometry.block_bounds
        blocks = np.flatnonzero((bx1 >= x0) & (by1 >= y0) & (bx0 <= x1) & (by0 <= y1))
        _, candidates = _expand(blocks * block, np.minimum(blocks * block + block, p.thin.size) - 1)
        xmin, ymin, xmax, ymax = p.bounds[:, candidates]
        picked = candidates[(xmax >= x0) & (ymax >= y0) & (xmin <= x1) & (ymin <= y1)]
        for i in range(0, len(picked), chunk):
            cells.add_polygons(p, picked[i : i + chunk])
    cells.add_segments(p, np.flatnonzero((p.segments[3] >= y0) & (p.segments[1] <= y1)))
    return cells.occupied()
