"""Drawing the live scene: the imported base (less what robots hid) and the overlay, and how a window
of a map is drawn from them (the static raster OR the overlay elements' own rasters, inflated).

:class:`~twin.live.live_maps.LiveMaps` keeps the maps current with this; :meth:`Drawing.rebuild` is the
reference a live map equals bit for bit, and :meth:`Drawing.elements_at` answers which elements make a
cell occupied (``twin explain``).

Example::

    drawing = Drawing(scene)
    cells = drawing.render(live_map, Window(10, 10, 40, 60))
"""

from __future__ import annotations

import numpy as np

from twin.live.live_map import LiveMap
from twin.live.overlay import (
    MapKey,
    OverlayElement,
    RasterCache,
    grow,
    in_band,
)
from twin.maps.grid import GridData, Window
from twin.maps.raster import BoolArray
from twin.maps.raster.boxes import footprint_cells
from twin.maps.render import occupancy, render_cells, render_layers
from twin.maps.scene import IndexArray, MeshSet, Scene
from twin.records import FloatArray, Shape
from twin.tolerances import TOLERANCES

_ONE: IndexArray = np.zeros(1, dtype=np.intp)


class Drawing:
    """The live scene (base + overlay) and how a map's cells are drawn from it. One writer."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.hidden = np.zeros(len(scene.elements), dtype=np.bool_)
        self._overlay: dict[str, OverlayElement] = {}
        self._rasters = RasterCache()
        self.skill_maps: dict[MapKey, LiveMap] = {}

    # --- geometry ----------------------------------------------------------------------------------
    def bounds_of(self, iri: str) -> FloatArray | None:
        """``(6,)`` world AABB of the element's current geometry, None if it has none."""
        el = self._overlay.get(iri)
        if el is not None:
            return el.bounds
        i = self.scene.elements.index.get(iri)
        if i is None or self.hidden[i]:
            return None
        b = self.scene.elements.bounds[i]
        return None if np.isnan(b).any() else b

    def shape_of(self, iri: str) -> Shape | None:
        """The element's current local mesh and placement, None if it has none."""
        el = self._overlay.get(iri)
        if el is not None:
            return el.shape
        i = self.scene.elements.index.get(iri)
        if i is None or self.hidden[i]:
            return None
        return self.scene.shapes.get(iri)

    # --- rendering ----------------------------------------------------------------------------------
    def _base_ids(self, m: LiveMap) -> IndexArray:
        return np.flatnonzero(m.base_mask & ~self.hidden).astype(np.intp)

    def _raster(self, m: LiveMap, iri: str, el: OverlayElement) -> tuple[Window, BoolArray] | None:
        """The element's occupancy on ``m``'s grid in its own window (cached), None if it has none."""
        key = (iri, m.key)
        if key in self._rasters.cells:
            return self._rasters.cells[key]
        b = el.bounds
        out: tuple[Window, BoolArray] | None = None
        shared = None
        footprint = el.footprint_in(m.plan)
        if footprint is not None:
            shared = (iri, ("upright", m.plan.frame))  # the same cells in every band it crosses
            if shared in self._rasters.shared:
                out = self._rasters.shared[shared]
                self._rasters.put(key, out)
                return out
        if b is not None and in_band(b, m.plan):
            frame = m.plan.frame
            win = grow(frame.window_for(b[0], b[1], b[3], b[4]), 1).intersect(frame.full)
            if not win.empty:
                if footprint is not None:
                    cells = footprint_cells(footprint, frame, win)
                else:
                    cells = occupancy(el.meshes(iri), _ONE, m.plan, win)
                out = (win, cells) if cells.any() else None
        self._rasters.put(key, out)
        if shared is not None:
            self._rasters.put_shared(shared, out)
        return out

    def _or_raster(self, m: LiveMap, iri: str, el: OverlayElement, occ: BoolArray, window: Window) -> None:
        """OR the element's own occupancy on ``m`` into ``occ``, the cells of ``window``."""
        cached = self._rasters.cells
        hit = cached[(iri, m.key)] if (iri, m.key) in cached else self._raster(m, iri, el)
        if hit is None:
            return
        win, cells = hit
        if not win.meets(window):
            return  # its raster lies elsewhere
        w = win.intersect(window)
        dst = occ[w.row0 - window.row0 : w.row1 - window.row0, w.col0 - window.col0 : w.col1 - window.col0]
        dst |= cells[w.row0 - win.row0 : w.row1 - win.row0, w.col0 - win.col0 : w.col1 - win.col0]

    def _occupancy(self, m: LiveMap, window: Window) -> BoolArray:
        """Occupancy (before inflation) of ``window``: the static cells OR each overlay element's."""
        r0, c0 = window.row0, window.col0
        occ = m.static[r0 : window.row1, c0 : window.col1].copy()
        cached, key = self._rasters.cells, m.key
        for iri in m.overlay:  # a map may hold many: those whose raster lies elsewhere cost a lookup
            el = self._overlay.get(iri)
            if el is None:
                continue
            hit = cached[(iri, key)] if (iri, key) in cached else self._raster(m, iri, el)
            if hit is None:
                continue
            win, cells = hit
            if not win.meets(window):
                continue
            w = win.intersect(window)
            occ[w.row0 - r0 : w.row1 - r0, w.col0 - c0 : w.col1 - c0] |= cells[
                w.row0 - win.row0 : w.row1 - win.row0, w.col0 - win.col0 : w.col1 - win.col0
            ]
        return occ

    def _occupancy_at_once(self, m: LiveMap, window: Window) -> BoolArray:
        """Like :meth:`_occupancy`, with every overlay element in ``window`` that is not an upright box
        rasterised in one call (cheaper than one per element when several changed at once, as under
        load); upright boxes take their own fast path."""
        occ = m.static[window.row0 : window.row1, window.col0 : window.col1].copy()
        f = m.plan.frame
        res, pad = f.resolution_m, 2 * TOLERANCES.grid_m  # within grid_m of the window's edge is on it
        x0, y0 = f.origin_x + window.col0 * res - pad, f.origin_y + window.row0 * res - pad
        x1, y1 = f.origin_x + window.col1 * res + pad, f.origin_y + window.row1 * res + pad
        items = []
        for iri in sorted(m.overlay):
            el = self._overlay.get(iri)
            if el is None:
                continue
            if el.footprint_in(m.plan) is not None:  # drawn from its own (cached) raster: cheaper
                self._or_raster(m, iri, el, occ, window)  # (nothing where its raster is not)
                continue
            b = el.bounds
            if b is None or not in_band(b, m.plan):
                continue
            if b[0] <= x1 and b[3] >= x0 and b[1] <= y1 and b[4] >= y0:
                items.append((iri, *el.shape))
        if items:
            meshes = MeshSet.build(items)
            occ |= occupancy(meshes, np.arange(len(items), dtype=np.intp), m.plan, window)
        return occ

    def render(
        self, m: LiveMap, window: Window, *, source: tuple[Window, BoolArray] | None = None
    ) -> GridData:
        """The values of ``window`` of ``m`` from its static cells and overlay elements (or from
        ``source``: the occupancy of a window that holds this one's, grown by the inflation), drawn by
        the maps' one renderer (:func:`~twin.maps.render.render_cells`)."""

        def occupied_in(padded: Window) -> BoolArray:
            if source is None:
                return self._occupancy(m, padded)
            sw, cells = source
            return cells[
                padded.row0 - sw.row0 : padded.row1 - sw.row0, padded.col0 - sw.col0 : padded.col1 - sw.col0
            ]

        inside = m.inside
        inside_in = None if inside is None else (lambda w: inside[w.row0 : w.row1, w.col0 : w.col1])
        return render_cells(occupied_in, m.plan, window, inside_in=inside_in)

    def rebuild(self, m: LiveMap) -> GridData:
        """The full map rendered from scratch from the triangles (the reference the live one equals)."""
        items = sorted((i, *self._overlay[i].shape) for i in m.overlay if i in self._overlay)
        over = MeshSet.build([(i, mesh, p) for i, mesh, p in items])
        layers = [(self.scene.elements, self._base_ids(m)), (over, np.arange(len(items), dtype=np.intp))]
        return render_layers(layers, m.plan, m.plan.frame.full, spaces=self.scene.spaces)

    # --- maps ---------------------------------------------------------------------------------------
    def elements_at(self, key: MapKey, window: Window) -> list[str]:
        """The elements the map ``key`` selects whose own occupancy (before inflation) touches
        ``window``: what makes its cells occupied (what ``twin explain`` answers)."""
        m = self.skill_maps[key]
        f = m.plan.frame
        res, pad = f.resolution_m, 2 * TOLERANCES.grid_m  # within grid_m of the window's edge is on it
        x0, y0 = f.origin_x + window.col0 * res - pad, f.origin_y + window.row0 * res - pad
        x1, y1 = f.origin_x + window.col1 * res + pad, f.origin_y + window.row1 * res + pad
        out = []
        for i in self._base_ids(m):
            b = self.scene.elements.bounds[i]
            outside = b[0] > x1 or b[3] < x0 or b[1] > y1 or b[4] < y0
            if np.isnan(b).any() or outside or not in_band(b, m.plan):
                continue
            if occupancy(self.scene.elements, np.array([i], dtype=np.intp), m.plan, window).any():
                out.append(self.scene.elements.iris[int(i)])
        for iri in sorted(m.overlay):
            el = self._overlay.get(iri)
            hit = None if el is None else self._raster(m, iri, el)
            if hit is None:
                continue
            win, cells = hit
            w = win.intersect(window)
            if w.empty:
                continue
            if cells[w.row0 - win.row0 : w.row1 - win.row0, w.col0 - win.col0 : w.col1 - win.col0].any():
                out.append(iri)
        return out
