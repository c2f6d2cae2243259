"""The overlay: elements robots added, moved or reshaped, each with its world bounds and its rasters.

Each overlay element keeps its shape and bounds; its mesh set is made only when the general rasteriser
needs it. An upright box (a ``twin:box``) keeps its footprint instead: in a band it crosses, its cells
are the footprint's (:mod:`twin.maps.raster.boxes`), the same in every map of one grid frame. The rasters
are cached per element and map (or per element and frame for upright boxes) until the element changes.
The window helpers here say which cells a change can touch.

Example::

    el = OverlayElement.of((mesh, placement))
    windows = dirty_windows(plan, [el.bounds], pad=3)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from twin.maps.grid import Window
from twin.maps.raster import BoolArray
from twin.maps.raster.boxes import box_footprint
from twin.maps.render import MapPlan
from twin.maps.scene import MeshSet
from twin.records import FloatArray, Shape, to_world
from twin.tolerances import TOLERANCES

MapKey = tuple[str, str]
"""``(storey key, skill name)``."""


@dataclass(eq=False, slots=True)
class OverlayElement:
    """One overlay element: its shape, its world bounds and (made when first needed) its mesh set."""

    shape: Shape
    bounds: FloatArray | None
    footprint: FloatArray | None = None
    """An upright box's (a ``twin:box``: eight corners, turned about +z only) footprint corners: in a
    band it crosses its cells are those of the footprint (:mod:`twin.maps.raster.boxes`), the same in every
    map of one frame, so they are computed once for all of them."""
    _meshes: MeshSet | None = None

    @classmethod
    def of(cls, shape: Shape) -> OverlayElement:
        mesh, placement = shape
        if not mesh.triangle_count:
            return cls(shape, None)
        world = to_world(mesh.vertices, placement)  # as MeshSet.build, bit for bit
        used = world[mesh.faces.ravel()]
        b = np.concatenate([used.min(axis=0), used.max(axis=0)])
        footprint = box_footprint(mesh.vertices, placement) if is_upright_box(shape) else None
        return cls(shape, None if np.isnan(b).any() else b, footprint)

    def footprint_in(self, plan: MapPlan) -> FloatArray | None:
        """The footprint, if this is an upright box that crosses ``plan``'s band (then its cells are the
        footprint's, the same in every band it crosses); else None (the general rasteriser)."""
        return self.footprint if self.footprint is not None and crosses(self.bounds, plan) else None

    def meshes(self, iri: str) -> MeshSet:
        if self._meshes is None:
            self._meshes = MeshSet.build([(iri, self.shape[0], self.shape[1])])
        return self._meshes


def is_upright_box(shape: Shape) -> bool:
    mesh, placement = shape
    if mesh.vertices.shape != (8, 3) or len(mesh.faces) != 12 or not mesh.closed:
        return False
    r = placement[:3, :3]
    if r[2, 2] != 1.0 or r[0, 2] != 0.0 or r[1, 2] != 0.0 or r[2, 0] != 0.0 or r[2, 1] != 0.0:
        return False
    v = mesh.vertices
    lo, hi = v.min(axis=0), v.max(axis=0)
    if not ((lo < hi).all() and ((v == lo) | (v == hi)).all()):
        return False  # not two distinct values per axis
    corner = (v == hi) @ np.array([1, 2, 4])
    return bool((np.bincount(corner, minlength=8) == 1).all())  # the eight corners, each once


@dataclass(eq=False, slots=True)
class RasterCache:
    """Occupancy of each overlay element on each map's grid, in the element's own window."""

    cells: dict[tuple[str, MapKey], tuple[Window, BoolArray] | None] = field(default_factory=dict)
    shared: dict[tuple[str, object], tuple[Window, BoolArray] | None] = field(default_factory=dict)
    """Upright boxes: one raster per frame, for every map of that frame whose band they cross."""

    def drop(self, iri: str) -> None:
        for key in [k for k in self.cells if k[0] == iri]:
            del self.cells[key]
        for shared in [k for k in self.shared if k[0] == iri]:
            del self.shared[shared]


def grow(w: Window, pad: int) -> Window:
    return Window(w.row0 - pad, w.col0 - pad, w.row1 + pad, w.col1 + pad)


def in_band(b: FloatArray, plan: MapPlan) -> bool:
    """The bounds meet the band, a z within ``grid_m`` of its end being on it."""
    g = TOLERANCES.grid_m
    return not (b[2] > plan.z_hi + g or b[5] < plan.z_lo - g)


def crosses(b: FloatArray | None, plan: MapPlan) -> bool:
    """The bounds reach into the band by more than ``grid_m`` (an upright box's slab geometry is then its
    footprint: the fast path); a box only touching the band's end goes through the general rasteriser."""
    g = TOLERANCES.grid_m
    return b is not None and b[2] < plan.z_hi - g and b[5] > plan.z_lo + g


def dirty_windows(plan: MapPlan, boxes: Sequence[FloatArray], pad: int) -> list[Window]:
    """Disjoint windows of ``plan``'s grid covering ``boxes`` (world AABBs in the map's band), grown by
    ``pad`` cells; windows that touch are merged (a table moved across a storey dirties two small
    windows, not the rectangle between them)."""
    windows = []
    for b in boxes:
        if not in_band(b, plan):
            continue
        grown = grow(plan.frame.window_for(b[0], b[1], b[3], b[4]), pad).intersect(plan.frame.full)
        if not grown.empty:
            windows.append(grown)
    merged = True
    while merged and len(windows) > 1:
        merged = False
        for i in range(len(windows)):
            for j in range(i + 1, len(windows)):
                a, c = windows[i], windows[j]
                if a.row0 <= c.row1 and c.row0 <= a.row1 and a.col0 <= c.col1 and c.col0 <= a.col1:
                    windows[i] = Window(
                        min(a.row0, c.row0), min(a.col0, c.col0), max(a.row1, c.row1), max(a.col1, c.col1)
                    )
                    del windows[j]
                    merged = True
                    break
            if merged:
                break
    return windows
