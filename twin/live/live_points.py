"""The live points maps: each (storey, points skill) cloud kept current as the building changes.

Each map keeps, per selected element, the voxels it touches with its own point in each
(:func:`twin.maps.points.voxels_by_element`), and which of them it *wins* (its point is the voxel's: the
nearest the voxel's centre, ties to the smallest point, then normal). A changed element replaces only the
voxels it touched before and touches now: its old voxels are dropped, its new ones computed from its
triangles alone, and the winners of just those voxels are decided again among the elements that touch them
(the rows and their index by voxel: :mod:`twin.live.point_rows`). The cloud (:meth:`PointsMap.cloud`) is
the winners, sorted by voxel: it equals a full rebuild from the triangles voxel for voxel
(:meth:`LivePoints.rebuild` is that reference; the tests hold the two together).

The geometry is the live scene's (:class:`~twin.live.drawing.Drawing`: the imported base less what
robots hid, plus the overlay); selection changes come as the 2D maps get them (per skill name, per
element: selected or not).

Example::

    points = LivePoints(drawing, margin_m=1.0)
    points.add_map(skill, "ground-floor", selected_iris)
    changed = points.redraw({iri}, {skill.name: {iri: True}})     # [(storey, skill, version)]
    publication.flush(points, revision, due_only=True)            # PointsPublished, bounded rate
    cloud = points.clouds[("ground-floor", skill.name)].cloud()
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from twin.live.drawing import Drawing
from twin.live.events import PointsPublished, TwinEvent
from twin.live.overlay import MapKey
from twin.live.point_rows import PointRows
from twin.maps.points import (
    PointCloud,
    PointsPlan,
    Voxels,
    best_per_voxel,
    cloud_of,
    estimate_points,
    plan_points,
    voxels_by_element,
)
from twin.maps.scene import MeshSet
from twin.selection.skills import SkillProfile

__all__ = ["POINTS_INTERVAL_S", "RECENT", "LivePoints", "PointsMap", "PointsPublication"]

log = logging.getLogger(__name__)

RECENT = 256
"""Elements left out whose voxels a points map keeps, in case they come back unchanged."""
POINTS_INTERVAL_S = 1.0
"""A changed cloud is published again at most this often (seconds): clouds are large (24 bytes a point)
and have no update message."""


@dataclass(eq=False, slots=True)
class PointsMap:
    """One (storey, points skill) map as the live twin keeps it."""

    plan: PointsPlan
    base_mask: npt.NDArray[np.bool_]
    """Which base elements the skill selects."""
    overlay: set[str]
    """Which elements robots added (not in the base) the skill selects."""
    rows: PointRows = field(init=False)
    """Each selected element's own voxels (only elements that touch any) and who wins where."""
    version: int = 1
    recent: dict[str, Voxels] = field(default_factory=dict)
    """The voxels of elements left out with their geometry unchanged (doors opened), the latest
    :data:`RECENT` (not in snapshots): selected again unchanged, they need no voxelising."""

    def __post_init__(self) -> None:
        self.rows = PointRows(self.plan.distance)

    @property
    def key(self) -> MapKey:
        return (self.plan.storey.key, self.plan.skill.name)

    @property
    def parts(self) -> Mapping[str, Voxels]:
        """Each selected element's own voxels, by IRI (views: copy what is kept)."""
        return self.rows

    def winners(self) -> Voxels:
        """Every part's winning voxels, one per key (ties between parts hold the same point), sorted."""
        return self.rows.winners()

    def cloud(self) -> PointCloud:
        return cloud_of(self.plan, self.winners())

    def __len__(self) -> int:
        return self.rows.won()

    def packed(self) -> tuple[list[str], dict[str, npt.NDArray[np.generic]]]:
        """The parts as flat arrays (for a snapshot): element IRIs, and per-row ``keys, q, d2, n, wins``
        with each element's row count ``counts`` (base mask and overlay are copied by the caller)."""
        return self.rows.packed()

    @classmethod
    def unpacked(
        cls,
        plan: PointsPlan,
        base_mask: npt.NDArray[np.bool_],
        overlay: set[str],
        *,
        names: list[str],
        arrays: Mapping[str, npt.NDArray[np.generic]],
        version: int,
    ) -> PointsMap:
        """A map from :meth:`packed`'s arrays."""
        try:
            rows = PointRows.unpacked(names, arrays, distance=plan.distance)
        except ValueError as err:
            msg = f"points map {(plan.storey.key, plan.skill.name)}: {err}"
            raise ValueError(msg) from err
        m = cls(plan, base_mask, overlay, version=version)
        m.rows = rows
        return m

    def put_aside(self, iri: str) -> None:
        """Keep (a copy of) the element's voxels in :attr:`recent` before it is left out."""
        part = self.rows.get(iri)
        if part is not None:
            self.recent.pop(iri, None)
            self.recent[iri] = Voxels(part.keys.copy(), part.q.copy(), part.d2.copy(), part.n.copy())
            while len(self.recent) > RECENT:
                del self.recent[next(iter(self.recent))]

    def replace(self, changes: Mapping[str, Voxels | None]) -> bool:
        """Give each changed element its new voxels (None: not in this map any more) and decide the
        winners of the voxels they touched before or touch now; True if the cloud's points changed."""
        return self.rows.replace(changes)


class LivePoints:
    """Every points map over the live scene, kept current. Not thread-safe: one writer (the one that
    changes the :class:`Drawing`)."""

    def __init__(self, drawing: Drawing, *, margin_m: float, max_points: int | None = None) -> None:
        self.drawing = drawing
        self.margin_m = margin_m
        self.max_points = max_points
        """``[maps] max_points_per_storey``: a cloud estimated over it is not built (None: no limit)."""
        self.skipped: dict[MapKey, int] = {}
        """The clouds not built for :attr:`max_points`: their estimated points."""
        self.clouds: dict[MapKey, PointsMap] = {}
        self.pending: dict[MapKey, int] = {}
        """Maps built or changed since :class:`PointsPublication` last published them: their version."""

    def _member(self, m: PointsMap, iri: str) -> bool:
        if self.drawing.shape_of(iri) is None:
            return False
        i = self.drawing.scene.elements.index.get(iri)
        return iri in m.overlay if i is None else bool(m.base_mask[i])

    def _members(self, m: PointsMap) -> tuple[npt.NDArray[np.intp], list[str]]:
        """The selected base elements drawn from the base, and every other selected element (moved or
        reshaped base elements, elements robots added), sorted."""
        scene = self.drawing.scene
        base = np.flatnonzero(m.base_mask & ~self.drawing.hidden).astype(np.intp)
        moved = [scene.elements.iris[int(i)] for i in np.flatnonzero(m.base_mask & self.drawing.hidden)]
        others = sorted({*moved, *m.overlay})
        return base, [i for i in others if self.drawing.shape_of(i) is not None]

    def _voxels(self, m: PointsMap, iri: str, meshes: dict[str, MeshSet] | None = None) -> Voxels:
        """The element's own voxels in ``m`` from its current triangles (``meshes``: the meshes of
        moved or added elements built so far, shared between maps)."""
        scene = self.drawing.scene
        i = scene.elements.index.get(iri)
        if i is not None and not self.drawing.hidden[i]:
            return voxels_by_element(scene.elements, np.array([i], dtype=np.intp), m.plan)[0]
        mesh = None if meshes is None else meshes.get(iri)
        if mesh is None:
            shape = self.drawing.shape_of(iri)
            if shape is None:
                return Voxels.empty()
            mesh = MeshSet.build([(iri, shape[0], shape[1])])
            if meshes is not None:
                meshes[iri] = mesh
        return voxels_by_element(mesh, np.zeros(1, dtype=np.intp), m.plan)[0]

    def _taken_back(self, m: PointsMap, iri: str, meshes: dict[str, MeshSet]) -> Voxels:
        """The voxels of an element selected again with its geometry unchanged."""
        part = m.recent.pop(iri, None)
        return self._voxels(m, iri, meshes) if part is None else part

    def add_map(self, skill: SkillProfile, storey: str, selected: Iterable[str]) -> PointsMap | None:
        """Plan and build the points map of ``skill`` on ``storey`` from the selected IRIs; None when its
        cloud is estimated over :attr:`max_points` (noted in :attr:`skipped`): the twin serves on without
        it."""
        chosen = set(selected)
        scene = self.drawing.scene
        plan = plan_points(scene, skill, storey, (), margin_m=self.margin_m)
        mask = np.zeros(len(scene.elements), dtype=np.bool_)
        mask[scene.elements.indices_of(tuple(chosen))] = True
        if self.max_points is not None:
            estimate = estimate_points(scene, replace(plan, selected=np.flatnonzero(mask)))
            if estimate > self.max_points:
                self.skipped[(storey, skill.name)] = estimate
                return None
        self.skipped.pop((storey, skill.name), None)
        m = PointsMap(plan, mask, {i for i in chosen if i not in scene.elements.index})
        base, others = self._members(m)
        names = [scene.elements.iris[int(i)] for i in base] + others
        parts = voxels_by_element(scene.elements, base, plan) + [self._voxels(m, iri) for iri in others]
        m.rows = PointRows.of(names, parts, distance=plan.distance)
        self.clouds[m.key] = m
        self.pending[m.key] = m.version
        return m

    def add_maps(
        self, skill: SkillProfile, storeys: Iterable[str], selected: Iterable[str]
    ) -> list[PointsMap]:
        """:meth:`add_map` on each storey; the clouds skipped for :attr:`max_points` are named in one
        warning."""
        chosen = set(selected)
        built = [self.add_map(skill, storey, chosen) for storey in storeys]
        over = {k[0]: n for k, n in self.skipped.items() if k[1] == skill.name}
        if over:
            log.warning(
                "Skipping the points clouds of skill %r at resolution_m=%s: about %s, over the limit of "
                "%s points ([maps] max_points_per_storey); the twin serves on without them",
                skill.name,
                skill.resolution_m,
                ", ".join(f"{n:,} points on {k}" for k, n in over.items()),
                f"{self.max_points:,}",
            )
        return [m for m in built if m is not None]

    def remove_skill(self, name: str) -> list[MapKey]:
        gone = [k for k in self.clouds if k[1] == name]
        self.skipped = {k: n for k, n in self.skipped.items() if k[1] != name}
        for k in gone:
            del self.clouds[k]
            self.pending.pop(k, None)
        return gone

    def redraw(
        self,
        touched: Iterable[str],
        membership: Mapping[str, Mapping[str, bool]],
        *,
        moved: Iterable[str] | None = None,
    ) -> list[tuple[str, str, int]]:
        """Bring every map up to the live scene after the elements ``touched`` changed (the drawing has
        their new geometry already; ``membership`` their new selection per skill name; ``moved``: those
        whose geometry changed, by default all).

        An element whose geometry did not change keeps its voxels: a map where its selection did not
        change either is left alone, and one that selects it again (a door closed) takes back the voxels
        it had when it was left out, if it still holds them (:attr:`PointsMap.recent`).

        Returns ``(storey, skill, version)`` of each map whose cloud changed (its next version).
        """
        touched = sorted(set(touched) | {i for sel in membership.values() for i in sel})
        reshaped = set(touched) if moved is None else set(moved)
        base = self.drawing.scene.elements.index
        meshes: dict[str, MeshSet] = {}
        changed = []
        for m in self.clouds.values():
            was = {iri: self._member(m, iri) for iri in touched if iri not in reshaped}
            for iri, selected in membership.get(m.plan.skill.name, {}).items():
                if iri in base:
                    m.base_mask[base[iri]] = selected
                elif selected:
                    m.overlay.add(iri)
                else:
                    m.overlay.discard(iri)
            changes: dict[str, Voxels | None] = {}
            for iri in touched:
                now = self._member(m, iri)
                if iri in reshaped:
                    m.recent.pop(iri, None)
                    changes[iri] = self._voxels(m, iri, meshes) if now else None
                elif now and not was[iri]:  # the same geometry, selected again
                    changes[iri] = self._taken_back(m, iri, meshes)
                elif was[iri] and not now:  # the same geometry, left out
                    m.put_aside(iri)
                    changes[iri] = None
            if changes and m.replace(changes):
                m.version += 1
                changed.append((m.plan.storey.key, m.plan.skill.name, m.version))
                self.pending[m.key] = m.version
        return changed

    def rebuild(self, m: PointsMap) -> PointCloud:
        """The full cloud from scratch from the triangles (the reference a live map equals)."""
        base, others = self._members(m)
        parts = voxels_by_element(self.drawing.scene.elements, base, m.plan)
        parts += [self._voxels(m, iri) for iri in others]
        return cloud_of(m.plan, best_per_voxel(Voxels.concat(parts)))


class PointsPublication:
    """Which clouds went out: every points map once it is built, then each changed one again, at most
    once per ``interval_s``. One writer."""

    def __init__(
        self,
        *,
        emit: Callable[[TwinEvent], None],
        clock: Callable[[], int],
        interval_s: float = POINTS_INTERVAL_S,
    ) -> None:
        self.emit = emit
        self.clock = clock
        self.interval_ns = int(interval_s * 1e9)
        self.latest: dict[MapKey, PointsPublished] = {}
        self._sent_ns: dict[MapKey, int] = {}

    def flush(self, points: LivePoints, revision: int, *, due_only: bool = False) -> None:
        """Publish every changed cloud; with ``due_only``, only those last published ``interval_s`` ago
        or more (the others stay owed)."""
        now = self.clock()
        for key in sorted(points.pending):
            if due_only and now - self._sent_ns.get(key, -math.inf) < self.interval_ns:
                continue
            del points.pending[key]
            m = points.clouds.get(key)
            if m is None:
                continue
            event = PointsPublished(m.cloud(), revision, m.version, now)
            self.latest[key] = event
            self._sent_ns[key] = now
            self.emit(event)

    def drop(self, key: MapKey) -> None:
        self.latest.pop(key, None)
        self._sent_ns.pop(key, None)
