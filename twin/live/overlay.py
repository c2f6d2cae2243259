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

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from twin.maps.grid import Window
from twin.maps.raster import BoolArray
from twin.maps.raster.boxes import local_footprint, placed_footprint
from twin.maps.render import MapPlan
from twin.maps.scene import MeshSet
from twin.records import FloatArray, Mesh, Shape, to_world
from twin.tolerances import TOLERANCES

MapKey = tuple[str, str]
"""``(storey key, skill name)``."""


@dataclass(frozen=True, eq=False, slots=True)
class _MeshFacts:
    """What an overlay element's bounds and fast path need of its mesh alone (kept while it moves)."""

    box: bool
    """Eight corners, two distinct values per axis, each corner once, 12 faces, closed."""
    used: npt.NDArray[np.intp] | None
    """The vertices its faces use, None if all (the bounds are those of the used vertices)."""
    local: FloatArray | None = None
    """A box's local footprint corners (:func:`~twin.maps.raster.boxes.local_footprint`); None: no box."""

    @classmethod
    def of(cls, mesh: Mesh) -> _MeshFacts:
        used = np.unique(mesh.faces)
        box = _is_box_mesh(mesh)
        return cls(
            box,
            None if len(used) == len(mesh.vertices) else used.astype(np.intp),
            local_footprint(mesh.vertices) if box else None,
        )


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
    _facts: _MeshFacts | None = None

    @classmethod
    def of(cls, shape: Shape, *, previous: OverlayElement | None = None) -> OverlayElement:
        """The element of ``shape``; ``previous``: the element it was, whose facts about the mesh are
        kept when the mesh is the same object (a move: the placement alone changed)."""
        mesh, placement = shape
        if not mesh.triangle_count:
            return cls(shape, None)
        same = previous is not None and previous._facts is not None and previous.shape[0] is mesh
        facts = previous._facts if same and previous is not None else _MeshFacts.of(mesh)
        assert facts is not None
        world = to_world(mesh.vertices, placement)  # as MeshSet.build, bit for bit
        used = world if facts.used is None else world[facts.used]
        b = np.concatenate([used.min(axis=0), used.max(axis=0)])
        upright = facts.local is not None and _turns_about_z(placement)
        footprint = placed_footprint(facts.local, placement) if facts.local is not None and upright else None
        return cls(shape, None if np.isnan(b).any() else b, footprint, _facts=facts)

    def footprint_in(self, plan: MapPlan) -> FloatArray | None:
        """The footprint, if this is an upright box that crosses ``plan``'s band (then its cells are the
        footprint's, the same in every band it crosses); else None (the general rasteriser)."""
        return self.footprint if self.footprint is not None and crosses(self.bounds, plan) else None

    def meshes(self, iri: str) -> MeshSet:
        if self._meshes is None:
            self._meshes = MeshSet.build([(iri, self.shape[0], self.shape[1])])
        return self._meshes


def is_upright_box(shape: Shape) -> bool:
    """The shape is a box (eight corners, 12 faces, closed) turned about +z only."""
    mesh, placement = shape
    return _is_box_mesh(mesh) and _turns_about_z(placement)


def _turns_about_z(placement: FloatArray) -> bool:
    r: list[list[float]] = placement[:3, :3].tolist()  # Python floats: five compares, no numpy call
    return r[2][2] == 1.0 and r[0][2] == 0.0 and r[1][2] == 0.0 and r[2][0] == 0.0 and r[2][1] == 0.0


def _is_box_mesh(mesh: Mesh) -> bool:
    if mesh.vertices.shape != (8, 3) or len(mesh.faces) != 12 or not mesh.closed:
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
    _maps_of: dict[str, set[MapKey]] = field(default_factory=dict)
    _frames_of: dict[str, set[object]] = field(default_factory=dict)
    """Each element's keys in :attr:`cells` and :attr:`shared` (a change drops its own, not a scan)."""

    def put(self, key: tuple[str, MapKey], out: tuple[Window, BoolArray] | None) -> None:
        self.cells[key] = out
        self._maps_of.setdefault(key[0], set()).add(key[1])

    def put_shared(self, key: tuple[str, object], out: tuple[Window, BoolArray] | None) -> None:
        self.shared[key] = out
        self._frames_of.setdefault(key[0], set()).add(key[1])

    def drop(self, iri: str) -> None:
        for m in self._maps_of.pop(iri, ()):
            self.cells.pop((iri, m), None)
        for f in self._frames_of.pop(iri, ()):
            self.shared.pop((iri, f), None)


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
    windows, not the rectangle between them).

    Worked in Python numbers (each box's six floats read at once, the windows as tuples until the end):
    the same arithmetic as :func:`in_band`, :meth:`GridFrame.window_for`, :func:`grow` and
    :meth:`Window.intersect`, and the same merges in the same order."""
    frame = plan.frame
    g = TOLERANCES.grid_m
    z_top, z_bottom = plan.z_hi + g, plan.z_lo - g
    res, ox, oy, height, width = frame.resolution_m, frame.origin_x, frame.origin_y, frame.height, frame.width
    floor = math.floor
    windows: list[tuple[int, int, int, int]] = []
    for b in boxes:
        xmin, ymin, zmin, xmax, ymax, zmax = b.tolist()
        if zmin > z_top or zmax < z_bottom:
            continue  # not in the band
        r0, c0 = max(floor((ymin - oy) / res), 0), max(floor((xmin - ox) / res), 0)
        r1, c1 = min(floor((ymax - oy) / res) + 1, height), min(floor((xmax - ox) / res) + 1, width)
        r0, c0 = max(r0 - pad, 0), max(c0 - pad, 0)
        r1, c1 = min(r1 + pad, height), min(c1 + pad, width)
        if r1 > r0 and c1 > c0:
            windows.append((r0, c0, r1, c1))
    merged = True
    while merged and len(windows) > 1:
        merged = False
        for i in range(len(windows)):
            a0, a1, a2, a3 = windows[i]
            for j in range(i + 1, len(windows)):
                e0, e1, e2, e3 = windows[j]
                if a0 <= e2 and e0 <= a2 and a1 <= e3 and e1 <= a3:
                    windows[i] = (min(a0, e0), min(a1, e1), max(a2, e2), max(a3, e3))
                    del windows[j]
                    merged = True
                    break
            if merged:
                break
    return [Window(*w) for w in windows]
