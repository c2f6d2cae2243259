"""The incremental map engine: the twin's geometry as it changes, and every skill map kept current.

The imported elements form a frozen base (:class:`~twin.scene.MeshSet`); what robots changed lives in
an overlay keyed by element IRI (a new element, a moved or reshaped one); a base element that was
moved, reshaped or removed is hidden in the base. Each (storey, skill) map keeps its selected elements
as a mask over the base plus a set of overlay IRIs, its current cells and its version.

After a change, only the cells that the changed elements' old and new footprints touch (grown by the
skill's inflation) are re-rendered, and only for the maps whose height band and selection the element
is or was in. The result equals a full rebuild bit for bit: every window is computed from only the
elements overlapping it, exactly as the full map is (see :mod:`twin.maps`).

Example::

    engine = MapEngine(scene, margin_m=1.0)
    engine.add_map(skill, "ground-floor", selected_iris)
    changes = engine.apply([GeometryChange(iri, new=(mesh, placement))], {skill.name: {iri: True}})
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from twin.grid import GridData, OccupancyGrid, Window
from twin.maps import Layer, MapPlan, plan_map, render_layers
from twin.records import FloatArray, Mesh
from twin.scene import IndexArray, MeshSet, Scene
from twin.skills import SkillProfile

log = logging.getLogger(__name__)

Shape = tuple[Mesh, FloatArray]
"""A local mesh and its ``(4, 4)`` placement."""


@dataclass(frozen=True, eq=False, slots=True)
class GeometryChange:
    """An element's geometry changed: ``new`` is its mesh and placement now, None if it has none."""

    iri: str
    new: Shape | None


@dataclass(frozen=True, eq=False, slots=True)
class WindowUpdate:
    """New cells of one map: ``data`` holds the values of ``window``; the map is now at ``version``."""

    storey: str
    skill: str
    window: Window
    data: GridData
    version: int


@dataclass(eq=False, slots=True)
class LiveMap:
    """One (storey, skill) map as the engine keeps it."""

    plan: MapPlan
    base_mask: npt.NDArray[np.bool_]
    overlay: set[str]
    data: GridData
    version: int = 1

    @property
    def key(self) -> tuple[str, str]:
        return (self.plan.storey.key, self.plan.skill.name)

    def grid(self) -> OccupancyGrid:
        return OccupancyGrid(
            frame=self.plan.frame,
            data=self.data.copy(),
            storey=self.plan.storey.key,
            skill=self.plan.skill.name,
            elevation_m=self.plan.storey.elevation_m,
        )


@dataclass(eq=False, slots=True)
class _Overlay:
    shapes: dict[str, Shape] = field(default_factory=dict)
    meshes: MeshSet = field(default_factory=lambda: MeshSet.build([]))

    def rebuild(self) -> None:
        self.meshes = MeshSet.build([(iri, m, p) for iri, (m, p) in sorted(self.shapes.items())])


class MapEngine:
    """The live scene (base + overlay) and every map over it. Not thread-safe: one writer."""

    def __init__(self, scene: Scene, *, margin_m: float) -> None:
        self.scene = scene
        self.margin_m = margin_m
        self.hidden = np.zeros(len(scene.elements), dtype=np.bool_)
        self._overlay = _Overlay()
        self.maps: dict[tuple[str, str], LiveMap] = {}

    # --- geometry ----------------------------------------------------------------------------------
    def bounds_of(self, iri: str) -> FloatArray | None:
        """``(6,)`` world AABB of the element's current geometry, None if it has none."""
        ov = self._overlay.meshes
        if iri in ov.index:
            b = ov.bounds[ov.index[iri]]
        elif iri in self.scene.elements.index and not self.hidden[self.scene.elements.index[iri]]:
            b = self.scene.elements.bounds[self.scene.elements.index[iri]]
        else:
            return None
        return None if np.isnan(b).any() else b

    def shape_of(self, iri: str) -> Shape | None:
        """The element's current local mesh and placement, None if it has none."""
        if iri in self._overlay.shapes:
            return self._overlay.shapes[iri]
        i = self.scene.elements.index.get(iri)
        if i is None or self.hidden[i]:
            return None
        return self.scene.shapes.get(iri)

    def _set_geometry(self, changes: Sequence[GeometryChange]) -> None:
        base = self.scene.elements.index
        for ch in changes:
            if ch.iri in base:
                self.hidden[base[ch.iri]] = True
            if ch.new is None:
                self._overlay.shapes.pop(ch.iri, None)
            else:
                self._overlay.shapes[ch.iri] = ch.new
        if changes:
            self._overlay.rebuild()

    # --- maps ---------------------------------------------------------------------------------------
    def _layers(self, m: LiveMap) -> list[Layer]:
        base_ids: IndexArray = np.flatnonzero(m.base_mask & ~self.hidden).astype(np.intp)
        ov = self._overlay.meshes
        over_ids = np.array(sorted(ov.index[i] for i in m.overlay if i in ov.index), dtype=np.intp)
        return [(self.scene.elements, base_ids), (ov, over_ids)]

    def render(self, m: LiveMap, window: Window) -> GridData:
        return render_layers(self._layers(m), m.plan, window, spaces=self.scene.spaces)

    def add_map(self, skill: SkillProfile, storey: str, selected: Iterable[str]) -> LiveMap:
        """Plan and fully render the map of ``skill`` on ``storey`` from the selected IRIs."""
        chosen = set(selected)
        plan = plan_map(self.scene, skill, storey, (), margin_m=self.margin_m)
        mask = np.zeros(len(self.scene.elements), dtype=np.bool_)
        mask[self.scene.elements.indices_of(tuple(chosen))] = True
        m = LiveMap(plan, mask, {i for i in chosen if i in self._overlay.shapes}, np.empty(0, np.int8))
        m.data = self.render(m, plan.frame.full)
        self.maps[m.key] = m
        return m

    def remove_skill(self, name: str) -> list[tuple[str, str]]:
        gone = [k for k in self.maps if k[1] == name]
        for k in gone:
            del self.maps[k]
        return gone

    def _dirty(self, m: LiveMap, boxes: Sequence[FloatArray]) -> list[Window]:
        """The disjoint windows of ``m`` that ``boxes`` (world AABBs) can change, grown by inflation.

        Each box gives its own window (a table moved across a storey dirties two small windows, not
        the rectangle between them); windows that touch are merged.
        """
        p = m.plan
        pad = math.ceil(p.inflation_cells) + 1
        windows = []
        for b in boxes:
            if b[2] > p.z_hi or b[5] < p.z_lo:
                continue
            w = p.frame.window_for(b[0], b[1], b[3], b[4])
            grown = Window(w.row0 - pad, w.col0 - pad, w.row1 + pad, w.col1 + pad).intersect(p.frame.full)
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

    def apply(
        self,
        geometry: Sequence[GeometryChange],
        membership: Mapping[str, Mapping[str, bool]],
    ) -> list[WindowUpdate]:
        """Apply geometry changes and selection changes; re-render what they touch.

        Args:
            geometry: the elements whose geometry changed (new shape, or None when gone).
            membership: per skill name, the new selection state of every element that changed in any
                way (geometry, class, door state, ...): True if the skill now selects it.

        Returns:
            One update per changed region of each map (the bounding window of its changed cells), each
            bringing that map to its next version.
        """
        touched = set(c.iri for c in geometry) | {i for sel in membership.values() for i in sel}
        old_bounds = {i: self.bounds_of(i) for i in touched}
        was = {k: {i for i in touched if self._member(m, i)} for k, m in self.maps.items()}
        self._set_geometry(geometry)
        base = self.scene.elements.index
        for m in self.maps.values():
            for iri, selected in membership.get(m.plan.skill.name, {}).items():
                if iri in self._overlay.shapes:
                    m.overlay.add(iri) if selected else m.overlay.discard(iri)
                else:
                    m.overlay.discard(iri)
                if iri in base:
                    m.base_mask[base[iri]] = selected
        new_bounds = {i: self.bounds_of(i) for i in touched}
        updates = []
        for key, m in self.maps.items():
            boxes = [old_bounds[i] for i in was[key] if old_bounds[i] is not None]
            boxes += [b for i in touched if self._member(m, i) and (b := new_bounds[i]) is not None]
            windows = self._dirty(m, boxes)  # type: ignore[arg-type]
            fresh = [(win, self.render(m, win)) for win in windows]  # all rendered before any is written
            for win, cells in fresh:
                old = m.data[win.row0 : win.row1, win.col0 : win.col1]
                diff = np.argwhere(cells != old)
                if not len(diff):
                    continue
                (r0, c0), (r1, c1) = diff.min(axis=0), diff.max(axis=0) + 1
                changed = Window(
                    win.row0 + int(r0), win.col0 + int(c0), win.row0 + int(r1), win.col0 + int(c1)
                )
                old[...] = cells
                m.version += 1
                data = m.data[changed.row0 : changed.row1, changed.col0 : changed.col1].copy()
                updates.append(WindowUpdate(m.plan.storey.key, m.plan.skill.name, changed, data, m.version))
        return updates

    def _member(self, m: LiveMap, iri: str) -> bool:
        if iri in self._overlay.shapes:
            return iri in m.overlay
        i = self.scene.elements.index.get(iri)
        return i is not None and bool(m.base_mask[i]) and not bool(self.hidden[i])

    def rebuild(self, m: LiveMap) -> GridData:
        """The full map rendered from scratch (to check the incremental one against)."""
        return self.render(m, m.plan.frame.full)
