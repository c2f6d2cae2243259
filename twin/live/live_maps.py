"""The live maps: the twin's geometry as it changes, and every skill map kept current, fast.

The imported elements form a frozen base (:class:`~twin.maps.scene.MeshSet`); what robots changed lives in
an overlay (:mod:`twin.live.overlay`: a new element, a moved or reshaped one); a base element that was
moved, reshaped or removed is hidden in the base. One map's cells and versions: :mod:`twin.live.live_map`.

Each (storey, skill) map keeps, besides its cells:

- ``static``: the occupancy (before inflation) of its selected, visible base elements over the whole
  grid, rendered once at start and patched only when a base element changes (a door opened, a wall
  removed: rare);
- the occupancy of each selected overlay element in its own small window (cached per element and map,
  dropped when the element changes); an upright box (``twin:box``) crossing the band is drawn straight
  from its footprint (:mod:`twin.maps.raster.boxes`), once for all the maps of one grid frame.

A map is the union of its elements' maps, so a window is re-rendered (:mod:`twin.live.drawing`) by
OR-ing the static cells with the overlay elements that overlap it, then inflating; moving a table
costs one rasterisation of the table, not of the walls around it. The result equals a full rebuild
from the triangles bit for bit (:meth:`LiveMaps.rebuild` is that reference, and the tests hold the
two together).

Example::

    maps = LiveMaps(scene, margin_m=1.0)
    maps.add_map(skill, "ground-floor", selected_iris)
    updates = maps.redraw([GeometryChange(iri, new=(mesh, placement))], {skill.name: {iri: True}})
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from twin.live.drawing import Drawing
from twin.live.live_map import LiveMap, WindowUpdate
from twin.live.live_points import LivePoints
from twin.live.overlay import (
    MapKey,
    OverlayElement,
    dirty_windows,
    grow,
)
from twin.maps.grid import Window
from twin.maps.raster import BoolArray
from twin.maps.render import occupancy, plan_map
from twin.maps.scene import Scene
from twin.records import GeometryChange, Shape
from twin.selection.skills import SkillProfile

_AT_ONCE_AREA = 4
"""Windows changed together are rendered in one pass over their bounding window, and sent as one update
of the bounding window of their changed cells, when it is at most this many times their total area
(else each alone)."""


class LiveMaps(Drawing):
    """The live scene (base + overlay, drawn as :class:`~twin.live.drawing.Drawing` draws it) and every
    map over it, kept current. Not thread-safe: one writer."""

    def __init__(self, scene: Scene, *, margin_m: float, max_points: int | None = None) -> None:
        super().__init__(scene)
        self.margin_m = margin_m
        self.points = LivePoints(self, margin_m=margin_m, max_points=max_points)
        """The ``points`` skills' clouds over the same live scene (kept current by :meth:`redraw`)."""

    @classmethod
    def restored(
        cls,
        scene: Scene,
        *,
        margin_m: float,
        hidden: BoolArray,
        overlay: Mapping[str, Shape],
        maps: Iterable[LiveMap],
    ) -> LiveMaps:
        """Live maps as they were saved (:mod:`twin.live.snapshots`): which base elements are hidden,
        the overlay elements' shapes, and maps whose cells are already rendered."""
        out = cls(scene, margin_m=margin_m)
        out.hidden = hidden
        out._overlay = {iri: OverlayElement.of(shape) for iri, shape in overlay.items()}
        out.skill_maps = {m.key: m for m in maps}
        return out

    def overlay_shapes(self) -> dict[str, Shape]:
        """Every overlay element's shape (what robots added, moved or reshaped since the base)."""
        return {iri: el.shape for iri, el in self._overlay.items()}

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
        self.skill_maps[m.key] = m
        return m

    def remove_skill(self, name: str) -> list[MapKey]:
        gone = [k for k in self.skill_maps if k[1] == name]
        for k in gone:
            del self.skill_maps[k]
        for key in [k for k in self._rasters.cells if k[1][1] == name]:
            del self._rasters.cells[key]
        return gone + self.points.remove_skill(name)

    def _member(self, m: LiveMap, iri: str) -> bool:
        if iri in self._overlay:
            return iri in m.overlay
        i = self.scene.elements.index.get(iri)
        return i is not None and bool(m.base_mask[i]) and not bool(self.hidden[i])

    def _members(self, m: LiveMap, iris: set[str]) -> set[str]:
        """Those of ``iris`` that ``m`` shows (:meth:`_member` of each)."""
        overlay = self._overlay
        return {i for i in iris if (i in m.overlay if i in overlay else self._base_member(m, i))}

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
            bringing that map to its next version; changes that lie close (their bounding window at most
            :data:`_AT_ONCE_AREA` times their windows' area) are one region.
        """
        touched = {c.iri for c in geometry} | {i for sel in membership.values() for i in sel}
        base = self.scene.elements.index
        in_base = [i for i in touched if i in base]  # most changes are of robots' own elements: none
        old_bounds = {i: self.bounds_of(i) for i in touched}
        was = {k: self._members(m, touched) for k, m in self.skill_maps.items()}
        was_base = {k: {i for i in in_base if self._base_member(m, i)} for k, m in self.skill_maps.items()}
        for ch in geometry:
            if ch.iri in base:
                self.hidden[base[ch.iri]] = True
            self._rasters.drop(ch.iri)
            if ch.new is None:
                self._overlay.pop(ch.iri, None)
            else:
                self._overlay[ch.iri] = OverlayElement.of(ch.new, previous=self._overlay.get(ch.iri))
        for m in self.skill_maps.values():
            for iri, selected in membership.get(m.plan.skill.name, {}).items():
                if iri in self._overlay and selected:
                    m.overlay.add(iri)
                else:
                    m.overlay.discard(iri)
                if iri in base:
                    m.base_mask[base[iri]] = selected
        new_bounds = {i: self.bounds_of(i) for i in touched}
        updates = []
        for key, m in self.skill_maps.items():
            now = self._members(m, touched)
            now_base = {i for i in in_base if self._base_member(m, i)}
            if not (now or now_base or was[key] or was_base[key]):
                continue  # none of the changed elements is (or was) in this map
            # 1. the static cells where a base element left (or came back to) this map: rare
            gone = [
                b
                for i in was_base[key] ^ now_base
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
            boxes += [b for i in touched if i in now and (b := new_bounds[i]) is not None]
            pad = math.ceil(m.plan.inflation_cells) + 1
            windows = dirty_windows(m.plan, boxes, pad)
            if len(windows) > 1:  # several changes at once: rasterise them together if they lie close
                u = Window(
                    min(w.row0 for w in windows),
                    min(w.col0 for w in windows),
                    max(w.row1 for w in windows),
                    max(w.col1 for w in windows),
                )
                if u.shape[0] * u.shape[1] <= _AT_ONCE_AREA * sum(w.shape[0] * w.shape[1] for w in windows):
                    # one rendering of their bounding window (its other cells come out as they are),
                    # one update (a send, a version) for all
                    grown = grow(u, m.plan.inflation_pad).intersect(m.plan.frame.full)
                    source = (grown, self._occupancy_at_once(m, grown))
                    if (update := m.write(u, self.render(m, u, source=source))) is not None:
                        updates.append(update)
                    continue
            fresh = [(win, self.render(m, win)) for win in windows]
            for win, cells in fresh:  # all rendered before any is written
                if (update := m.write(win, cells)) is not None:
                    updates.append(update)
        if self.points.clouds:
            self.points.redraw(touched, membership, moved={c.iri for c in geometry})
        return updates
