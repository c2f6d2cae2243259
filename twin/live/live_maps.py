"""The live maps: the twin's geometry as it changes, and every skill map kept current, fast.

The imported elements form a frozen base (:class:`~twin.scene.MeshSet`); what robots changed lives in
an overlay (:mod:`twin.live.overlay`: a new element, a moved or reshaped one); a base element that was
moved, reshaped or removed is hidden in the base. One map's cells and versions: :mod:`twin.live.live_map`.

Each (storey, skill) map keeps, besides its cells:

- ``static``: the occupancy (before inflation) of its selected, visible base elements over the whole
  grid, rendered once at start and patched only when a base element changes (a door opened, a wall
  removed: rare);
- the occupancy of each selected overlay element in its own small window (cached per element and map,
  dropped when the element changes); an upright box (``twin:box``) crossing the band is drawn straight
  from its footprint (:mod:`twin.raster.boxes`), once for all the maps of one grid frame.

A map is the union of its elements' maps, so a window is re-rendered by OR-ing the static cells with
the overlay elements that overlap it, then inflating; moving a table costs one rasterisation of the
table, not of the walls around it. The result equals a full rebuild from the triangles bit for bit
(:meth:`LiveMaps.rebuild` is that reference, and the tests hold the two together).

Example::

    maps = LiveMaps(scene, margin_m=1.0)
    maps.add_map(skill, "ground-floor", selected_iris)
    updates = maps.redraw([GeometryChange(iri, new=(mesh, placement))], {skill.name: {iri: True}})
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from twin.grid import FREE, UNKNOWN, GridData, Window
from twin.live.live_map import LiveMap, WindowUpdate
from twin.live.overlay import (
    MapKey,
    OverlayElement,
    RasterCache,
    crosses,
    dirty_windows,
    grow,
    in_band,
)
from twin.maps import BoolGrid, dilate_disk, occupancy, plan_map, render_layers
from twin.raster.boxes import footprint_cells
from twin.records import FloatArray, GeometryChange, Shape
from twin.scene import IndexArray, MeshSet, Scene
from twin.skills import SkillProfile

_ONE: IndexArray = np.zeros(1, dtype=np.intp)
_AT_ONCE_AREA = 4
"""Windows changed together are rendered in one pass over their bounding window when it is at most this
many times their total area (else each alone)."""


class LiveMaps:
    """The live scene (base + overlay) and every map over it. Not thread-safe: one writer."""

    def __init__(self, scene: Scene, *, margin_m: float) -> None:
        self.scene = scene
        self.margin_m = margin_m
        self.hidden = np.zeros(len(scene.elements), dtype=np.bool_)
        self._overlay: dict[str, OverlayElement] = {}
        self._rasters = RasterCache()
        self.maps: dict[MapKey, LiveMap] = {}

    @classmethod
    def restored(
        cls,
        scene: Scene,
        *,
        margin_m: float,
        hidden: BoolGrid,
        overlay: Mapping[str, Shape],
        maps: Iterable[LiveMap],
    ) -> LiveMaps:
        """Live maps as they were saved (:mod:`twin.live.snapshots`): which base elements are hidden,
        the overlay elements' shapes, and maps whose cells are already rendered."""
        out = cls(scene, margin_m=margin_m)
        out.hidden = hidden
        out._overlay = {iri: OverlayElement.of(shape) for iri, shape in overlay.items()}
        out.maps = {m.key: m for m in maps}
        return out

    def overlay_shapes(self) -> dict[str, Shape]:
        """Every overlay element's shape (what robots added, moved or reshaped since the base)."""
        return {iri: el.shape for iri, el in self._overlay.items()}

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

    def _raster(self, m: LiveMap, iri: str, el: OverlayElement) -> tuple[Window, BoolGrid] | None:
        """The element's occupancy on ``m``'s grid in its own window (cached), None if it has none."""
        key = (iri, m.key)
        if key in self._rasters.cells:
            return self._rasters.cells[key]
        b = el.bounds
        out: tuple[Window, BoolGrid] | None = None
        shared = None
        if el.footprint is not None and crosses(b, m.plan):
            shared = (iri, ("upright", m.plan.frame))  # the same cells in every band it crosses
            if shared in self._rasters.shared:
                out = self._rasters.shared[shared]
                self._rasters.cells[key] = out
                return out
        if b is not None and in_band(b, m.plan):
            frame = m.plan.frame
            win = grow(frame.window_for(b[0], b[1], b[3], b[4]), 1).intersect(frame.full)
            if not win.empty:
                if shared is not None and el.footprint is not None:
                    cells = footprint_cells(el.footprint, frame, win)
                else:
                    cells = occupancy(el.meshes(iri), _ONE, m.plan, win)
                out = (win, cells) if cells.any() else None
        self._rasters.cells[key] = out
        if shared is not None:
            self._rasters.shared[shared] = out
        return out

    def _or_raster(self, m: LiveMap, iri: str, el: OverlayElement, occ: BoolGrid, window: Window) -> None:
        """OR the element's own occupancy on ``m`` into ``occ``, the cells of ``window``."""
        hit = self._raster(m, iri, el)
        if hit is None:
            return
        win, cells = hit
        w = win.intersect(window)
        if w.empty:
            return
        dst = occ[w.row0 - window.row0 : w.row1 - window.row0, w.col0 - window.col0 : w.col1 - window.col0]
        dst |= cells[w.row0 - win.row0 : w.row1 - win.row0, w.col0 - win.col0 : w.col1 - win.col0]

    def _occupancy(self, m: LiveMap, window: Window) -> BoolGrid:
        """Occupancy (before inflation) of ``window``: the static cells OR each overlay element's."""
        occ = m.static[window.row0 : window.row1, window.col0 : window.col1].copy()
        for iri in m.overlay:
            el = self._overlay.get(iri)
            if el is not None:
                self._or_raster(m, iri, el, occ, window)
        return occ

    def _occupancy_at_once(self, m: LiveMap, window: Window) -> BoolGrid:
        """Like :meth:`_occupancy`, with every overlay element in ``window`` that is not an upright box
        rasterised in one call (cheaper than one per element when several changed at once, as under
        load); upright boxes take their own fast path."""
        occ = m.static[window.row0 : window.row1, window.col0 : window.col1].copy()
        f = m.plan.frame
        x0, y0 = f.origin_x + window.col0 * f.resolution_m, f.origin_y + window.row0 * f.resolution_m
        x1, y1 = f.origin_x + window.col1 * f.resolution_m, f.origin_y + window.row1 * f.resolution_m
        items = []
        for iri in sorted(m.overlay):
            el = self._overlay.get(iri)
            b = None if el is None else el.bounds
            if el is None or b is None or not in_band(b, m.plan):
                continue
            if not (b[0] <= x1 and b[3] >= x0 and b[1] <= y1 and b[4] >= y0):
                continue
            if el.footprint is not None and crosses(b, m.plan):
                self._or_raster(m, iri, el, occ, window)
            else:
                items.append((iri, *el.shape))
        if items:
            meshes = MeshSet.build(items)
            occ |= occupancy(meshes, np.arange(len(items), dtype=np.intp), m.plan, window)
        return occ

    def render(
        self, m: LiveMap, window: Window, *, source: tuple[Window, BoolGrid] | None = None
    ) -> GridData:
        """The values of ``window`` of ``m`` from its static cells and overlay elements (or from
        ``source``: the occupancy of a window that holds this one's, grown by the inflation)."""
        plan = m.plan
        window = window.intersect(plan.frame.full)
        if window.empty:
            return np.zeros((max(window.shape[0], 0), max(window.shape[1], 0)), dtype=np.int8)
        pad = math.floor(plan.inflation_cells + 1e-9)
        padded = grow(window, pad).intersect(plan.frame.full)
        if source is None:
            occupied = self._occupancy(m, padded)
        else:
            sw, cells = source
            occupied = cells[
                padded.row0 - sw.row0 : padded.row1 - sw.row0, padded.col0 - sw.col0 : padded.col1 - sw.col0
            ]
        if pad:
            occupied = dilate_disk(occupied, plan.inflation_cells)
        r0, c0 = window.row0 - padded.row0, window.col0 - padded.col0
        occupied = occupied[r0 : r0 + window.shape[0], c0 : c0 + window.shape[1]]
        data = np.where(occupied, np.int8(plan.skill.occupied_value), FREE).astype(np.int8)
        if m.inside is not None:
            inside = m.inside[window.row0 : window.row1, window.col0 : window.col1]
            data[~inside & ~occupied] = UNKNOWN
        return data

    def rebuild(self, m: LiveMap) -> GridData:
        """The full map rendered from scratch from the triangles (the reference the live one equals)."""
        items = sorted((i, *self._overlay[i].shape) for i in m.overlay if i in self._overlay)
        over = MeshSet.build([(i, mesh, p) for i, mesh, p in items])
        layers = [(self.scene.elements, self._base_ids(m)), (over, np.arange(len(items), dtype=np.intp))]
        return render_layers(layers, m.plan, m.plan.frame.full, spaces=self.scene.spaces)

    # --- maps ---------------------------------------------------------------------------------------
    def add_map(self, skill: SkillProfile, storey: str, selected: Iterable[str]) -> LiveMap:
        """Plan and fully render the map of ``skill`` on ``storey`` from the selected IRIs."""
        chosen = set(selected)
        plan = plan_map(self.scene, skill, storey, (), margin_m=self.margin_m)
        mask = np.zeros(len(self.scene.elements), dtype=np.bool_)
        mask[self.scene.elements.indices_of(tuple(chosen))] = True
        full = plan.frame.full
        inside = occupancy(self.scene.spaces, plan.spaces, plan, full) if skill.unknown_outside else None
        empty = np.zeros(full.shape, dtype=np.bool_)
        m = LiveMap(plan, mask, {i for i in chosen if i in self._overlay}, empty, inside, empty.view(np.int8))
        m.static = occupancy(self.scene.elements, self._base_ids(m), plan, full)
        m.data = self.render(m, full)
        self.maps[m.key] = m
        return m

    def elements_at(self, key: MapKey, window: Window) -> list[str]:
        """The elements the map ``key`` selects whose own occupancy (before inflation) touches
        ``window``: what makes its cells occupied (what ``twin explain`` answers)."""
        m = self.maps[key]
        f = m.plan.frame
        x0, y0 = f.origin_x + window.col0 * f.resolution_m, f.origin_y + window.row0 * f.resolution_m
        x1, y1 = f.origin_x + window.col1 * f.resolution_m, f.origin_y + window.row1 * f.resolution_m
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

    def remove_skill(self, name: str) -> list[MapKey]:
        gone = [k for k in self.maps if k[1] == name]
        for k in gone:
            del self.maps[k]
        for key in [k for k in self._rasters.cells if k[1][1] == name]:
            del self._rasters.cells[key]
        return gone

    def _member(self, m: LiveMap, iri: str) -> bool:
        if iri in self._overlay:
            return iri in m.overlay
        i = self.scene.elements.index.get(iri)
        return i is not None and bool(m.base_mask[i]) and not bool(self.hidden[i])

    def _base_member(self, m: LiveMap, iri: str) -> bool:
        i = self.scene.elements.index.get(iri)
        return i is not None and bool(m.base_mask[i]) and not bool(self.hidden[i])

    def redraw(
        self,
        geometry: Sequence[GeometryChange],
        membership: Mapping[str, Mapping[str, bool]],
    ) -> list[WindowUpdate]:
        """Take the new geometry and selection of the changed elements; re-render what they touch.

        Args:
            geometry: the elements whose geometry changed (new shape, or None when gone).
            membership: per skill name, the new selection state of every element that changed in any
                way (geometry, class, door state, ...): True if the skill now selects it.

        Returns:
            One update per changed region of each map (the bounding window of its changed cells), each
            bringing that map to its next version.
        """
        touched = {c.iri for c in geometry} | {i for sel in membership.values() for i in sel}
        old_bounds = {i: self.bounds_of(i) for i in touched}
        was = {k: {i for i in touched if self._member(m, i)} for k, m in self.maps.items()}
        was_base = {k: {i for i in touched if self._base_member(m, i)} for k, m in self.maps.items()}
        base = self.scene.elements.index
        for ch in geometry:
            if ch.iri in base:
                self.hidden[base[ch.iri]] = True
            self._rasters.drop(ch.iri)
            if ch.new is None:
                self._overlay.pop(ch.iri, None)
            else:
                self._overlay[ch.iri] = OverlayElement.of(ch.new)
        for m in self.maps.values():
            for iri, selected in membership.get(m.plan.skill.name, {}).items():
                if iri in self._overlay and selected:
                    m.overlay.add(iri)
                else:
                    m.overlay.discard(iri)
                if iri in base:
                    m.base_mask[base[iri]] = selected
        new_bounds = {i: self.bounds_of(i) for i in touched}
        updates = []
        for key, m in self.maps.items():
            # 1. the static cells where a base element left (or came back to) this map: rare
            gone = [
                b
                for i in was_base[key] ^ {i for i in touched if self._base_member(m, i)}
                if (b := old_bounds[i] if i in was_base[key] else new_bounds[i]) is not None
            ]
            if gone:
                ids = self._base_ids(m)
                for win in dirty_windows(m.plan, gone, 1):
                    m.static[win.row0 : win.row1, win.col0 : win.col1] = occupancy(
                        self.scene.elements, ids, m.plan, win
                    )
            # 2. the cells every old and new footprint can change, grown by the inflation
            boxes = [b for i in was[key] if (b := old_bounds[i]) is not None]
            boxes += [b for i in touched if self._member(m, i) and (b := new_bounds[i]) is not None]
            pad = math.ceil(m.plan.inflation_cells) + 1
            windows = dirty_windows(m.plan, boxes, pad)
            source = None
            if len(windows) > 1:  # several changes at once: rasterise them together if they lie close
                u = Window(
                    min(w.row0 for w in windows),
                    min(w.col0 for w in windows),
                    max(w.row1 for w in windows),
                    max(w.col1 for w in windows),
                )
                if u.shape[0] * u.shape[1] <= _AT_ONCE_AREA * sum(w.shape[0] * w.shape[1] for w in windows):
                    grown = grow(u, math.floor(m.plan.inflation_cells + 1e-9)).intersect(m.plan.frame.full)
                    source = (grown, self._occupancy_at_once(m, grown))
            fresh = [(win, self.render(m, win, source=source)) for win in windows]
            for win, cells in fresh:  # all rendered before any is written
                if (update := m.write(win, cells)) is not None:
                    updates.append(update)
        return updates
