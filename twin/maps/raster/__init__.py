"""Slab rasterising: which grid cells the elements' geometry between two heights touches.

The geometry of a height slab ``z_lo <= z <= z_hi`` is, for every triangle, its part inside the slab
(a convex polygon of up to 5 vertices) projected to XY, plus, for closed elements (watertight, or
solids whose section is made of closed loops: :func:`closed_sections`), the interior inside the
slab. The triangles' x and y are first taken to the grid's units by
:func:`twin.maps.grid.grid_coordinates` (a coordinate within ``Tolerances.grid_m``, 1 um, of a grid line
is on it, as for the frame and the point clouds), so a tie with a grid line is decided on exact
coordinates, the same ones :func:`twin.maps.raster.boxes.footprint_cells` takes a box's corners to. A
cell is occupied iff that geometry touches the cell, where

- cells are closed squares *shrunk* by ``Tolerances.cell_m`` for every projected polygon of positive
  area and for every polygon of a closed element (a wall face lying exactly on a grid line does not
  spill into the neighbouring cell), and
- cells are *grown* by ``Tolerances.cell_m`` for the degenerate polygons (area at most ``cell_m``
  times their extent: a vertical face seen from above, a point) of open elements, so thin open
  surfaces never vanish, not even on a grid line (a sliver flattened onto a line by the rule above is
  degenerate too).

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
    geometry = slab_geometry(triangles, element, closed, 0.05, 1.5, frame)  # clip once on the grid
    assert (rasterize(geometry, frame) == occupied).all()
"""

from twin.maps.raster.api import rasterize, rasterize_slab, slab_geometry
from twin.maps.raster.clip import SlabGeometry
from twin.maps.raster.loops import closed_sections
from twin.maps.raster.settings import (
    MAX_VERTICES,
    RASTER_SETTINGS,
    BoolArray,
    FloatArray,
    IndexArray,
    Int8Array,
    RasterSettings,
    Spans,
)
from twin.tolerances import TOLERANCES, Tolerances

__all__ = [
    "MAX_VERTICES",
    "RASTER_SETTINGS",
    "TOLERANCES",
    "BoolArray",
    "FloatArray",
    "IndexArray",
    "Int8Array",
    "RasterSettings",
    "SlabGeometry",
    "Spans",
    "Tolerances",
    "closed_sections",
    "rasterize",
    "rasterize_slab",
    "slab_geometry",
]
