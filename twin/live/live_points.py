"""The live points maps: each (storey, points skill) cloud kept current as the building changes.

Each map keeps, per selected element, the voxels it touches with its own point in each
(:func:`twin.maps.points.voxels_by_element`), and which of them it *wins* (its point is the voxel's: the
nearest the voxel's centre, ties to the smallest point). A changed element replaces only the voxels it
touched before and touches now: its old voxels are dropped, its new ones computed from its triangles
alone, and the winners of just those voxels are decided again among the elements that touch them. The
cloud (:meth:`PointsMap.cloud`) is the winners, sorted by voxel: it equals a full rebuild from the
triangles voxel for voxel (:meth:`LivePoints.rebuild` is that reference; the tests hold the two
together).

The geometry is the live scene's (:class:`~twin.live.drawing.Drawing`: the imported base less what
robots hid, plus the overlay); selection changes come as the 2D maps get them (per skill name, per
element: selected or not).

Example::

    points = LivePoints(drawing)
    points.add_map(skill, "ground-floor", selected_iris)
    changed = points.redraw({iri}, {skill.name: {iri: True}})     # [(storey, skill, version)]
    publication.flush(points, revision, due_only=True)            # PointsPublished, bounded rate
    cloud = points.maps[("ground-floor", skill.name)].cloud()
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from twin.live.drawing import Drawing
from twin.live.events import PointsPublished, TwinEvent
from twin.live.overlay import MapKey
from twin.maps.points import (
    PointCloud,
    PointsPlan,
    Voxels,
    best_per_voxel,
    cloud_of,
    plan_points,
    voxels_by_element,
)
from twin.maps.scene import MeshSet
from twin.maps.voxels import IntArray
from twin.selection.skills import SkillProfile

__all__ = ["POINTS_INTERVAL_S", "LivePoints", "PointsMap", "PointsPublication"]

POINTS_INTERVAL_S = 1.0
"""A changed cloud is published again at most this often (seconds): clouds are large (12 bytes a point)
and have no update message."""


@dataclass(eq=False, slots=True)
class PointsMap:
    """One (storey, points skill) map as the live twin keeps it."""

    plan: PointsPlan
    base_mask: npt.NDArray[np.bool_]
    """Which base elements the skill selects."""
    overlay: set[str]
    """Which elements robots added (not in the base) the skill selects."""
    parts: dict[str, Voxels] = field(default_factory=dict)
    """Each selected element's own voxels (only elements that touch any)."""
    wins: dict[str, npt.NDArray[np.bool_]] = field(default_factory=dict)
    """Per part: which of its voxels hold its point."""
    span: dict[str, IntArray] = field(default_factory=dict)
    """Per part: its smallest and largest voxel ``(i, j, k)`` (which parts a change can concern)."""
    version: int = 1
    _spans: tuple[list[str], IntArray] | None = None
    """``span`` as one array (made when needed, dropped when a part changes)."""

    @property
    def key(self) -> MapKey:
        return (self.plan.storey.key, self.plan.skill.name)

    def winners(self) -> Voxels:
        """Every part's winning voxels, one per key (ties between parts hold the same point), sorted."""
        parts = [self.parts[i].take(self.wins[i]) for i in sorted(self.parts)]
        merged = Voxels.concat(parts)
        if not len(merged):
            return merged
        order = np.argsort(merged.keys, kind="stable")
        keys = merged.keys[order]
        first = np.ones(len(keys), dtype=np.bool_)
        first[1:] = keys[1:] != keys[:-1]
        return merged.take(order[first])

    def cloud(self) -> PointCloud:
        return cloud_of(self.plan, self.winners())

    def __len__(self) -> int:
        return sum(int(w.sum()) for w in self.wins.values())

    def packed(self) -> tuple[list[str], dict[str, npt.NDArray[np.generic]]]:
        """The parts as flat arrays (for a snapshot): element IRIs, and per-row ``keys, q, d2, wins``
        with each element's row count ``counts`` (base mask and overlay are copied by the caller)."""
        names = sorted(self.parts)
        parts = [self.parts[n] for n in names]
        flat = Voxels.concat(parts)
        wins = np.concatenate([self.wins[n] for n in names]) if names else np.zeros(0, dtype=np.bool_)
        counts = np.array([len(p) for p in parts], dtype=np.int64)
        return names, {"keys": flat.keys, "q": flat.q, "d2": flat.d2, "wins": wins, "counts": counts}

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
        m = cls(plan, base_mask, overlay, version=version)
        counts = np.asarray(arrays["counts"], dtype=np.int64)
        if len(counts) != len(names) or int(counts.sum()) != len(arrays["keys"]):
            n = len(arrays["keys"])
            msg = f"points map {m.key}: {len(names)} parts and {len(counts)} counts of {n} rows"
            raise ValueError(msg)
        start = np.concatenate([[0], np.cumsum(counts)])
        keys = np.asarray(arrays["keys"], dtype=np.int64)
        q = np.asarray(arrays["q"], dtype=np.float64)
        d2 = np.asarray(arrays["d2"], dtype=np.float64)
        wins = np.asarray(arrays["wins"], dtype=np.bool_)
        for i, name in enumerate(names):
            rows = slice(int(start[i]), int(start[i + 1]))
            m._set(name, Voxels(keys[rows], q[rows], d2[rows]))
            m.wins[name] = wins[rows].copy()
        return m

    def _set(self, iri: str, part: Voxels) -> None:
        self.parts[iri] = part
        self.wins[iri] = np.zeros(len(part), dtype=np.bool_)
        ijk = self.plan.ijk(part.keys)
        self.span[iri] = np.concatenate([ijk.min(axis=0), ijk.max(axis=0)])
        self._spans = None

    def _drop(self, iri: str) -> Voxels | None:
        """Remove a part; its voxels that held its point, or None if it had none."""
        wins = self.wins.pop(iri, None)
        self.span.pop(iri, None)
        self._spans = None
        part = self.parts.pop(iri, None)
        return None if part is None or wins is None else part.take(wins)

    def _near(self, lo: IntArray, hi: IntArray) -> list[str]:
        """The parts whose voxels' box meets ``[lo, hi]`` (voxel indices)."""
        if self._spans is None:
            names = list(self.span)
            self._spans = (names, np.array([self.span[n] for n in names]).reshape(-1, 6))
        names, spans = self._spans
        apart = (spans[:, :3] > hi).any(axis=1) | (spans[:, 3:] < lo).any(axis=1)
        return [names[i] for i in np.flatnonzero(~apart)]

    def decide(self, keys: IntArray, gone: Iterable[Voxels] = ()) -> bool:
        """Decide the winners of voxels ``keys`` (sorted, unique) among the parts; True if the cloud's
        points there changed (``gone``: the winning voxels of parts dropped since they were decided)."""
        if not len(keys):
            return False
        ijk = self.plan.ijk(keys)
        lo, hi = ijk.min(axis=0), ijk.max(axis=0)
        names, rows = [], []
        before = [g.take(np.isin(g.keys, keys)) for g in gone]
        for iri in self._near(lo, hi):
            part = self.parts[iri]
            at = np.searchsorted(keys, part.keys)
            at = np.minimum(at, len(keys) - 1)
            hit = np.flatnonzero(keys[at] == part.keys)
            if len(hit):
                names.append(iri)
                rows.append(hit)
                before.append(part.take(hit[self.wins[iri][hit]]))
        old = best_per_voxel(Voxels.concat(before))
        if not names:
            return len(old) > 0
        cand = Voxels.concat([self.parts[n].take(r) for n, r in zip(names, rows, strict=True)])
        best = best_per_voxel(cand)
        at = np.searchsorted(best.keys, cand.keys)
        win = (best.d2[at] == cand.d2) & (best.q[at] == cand.q).all(axis=1)
        start = 0
        for n, r in zip(names, rows, strict=True):
            self.wins[n][r] = win[start : start + len(r)]
            start += len(r)
        return not (
            np.array_equal(old.keys, best.keys)
            and np.array_equal(old.q, best.q)
            and np.array_equal(old.d2, best.d2)
        )


class LivePoints:
    """Every points map over the live scene, kept current. Not thread-safe: one writer (the one that
    changes the :class:`Drawing`)."""

    def __init__(self, drawing: Drawing, *, margin_m: float) -> None:
        self.drawing = drawing
        self.margin_m = margin_m
        self.maps: dict[MapKey, PointsMap] = {}
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

    def _voxels(self, m: PointsMap, iri: str) -> Voxels:
        """The element's own voxels in ``m`` from its current triangles."""
        scene = self.drawing.scene
        i = scene.elements.index.get(iri)
        if i is not None and not self.drawing.hidden[i]:
            return voxels_by_element(scene.elements, np.array([i], dtype=np.intp), m.plan)[0]
        shape = self.drawing.shape_of(iri)
        if shape is None:
            return Voxels.empty()
        meshes = MeshSet.build([(iri, shape[0], shape[1])])
        return voxels_by_element(meshes, np.zeros(1, dtype=np.intp), m.plan)[0]

    @staticmethod
    def _part_keys(m: PointsMap, iri: str) -> IntArray | None:
        part = m.parts.get(iri)
        return None if part is None else part.keys

    def add_map(self, skill: SkillProfile, storey: str, selected: Iterable[str]) -> PointsMap:
        """Plan and build the points map of ``skill`` on ``storey`` from the selected IRIs."""
        chosen = set(selected)
        scene = self.drawing.scene
        plan = plan_points(scene, skill, storey, (), margin_m=self.margin_m)
        mask = np.zeros(len(scene.elements), dtype=np.bool_)
        mask[scene.elements.indices_of(tuple(chosen))] = True
        m = PointsMap(plan, mask, {i for i in chosen if i not in scene.elements.index})
        base, others = self._members(m)
        for i, part in zip(base, voxels_by_element(scene.elements, base, plan), strict=True):
            if len(part):
                m._set(scene.elements.iris[int(i)], part)
        for iri in others:
            part = self._voxels(m, iri)
            if len(part):
                m._set(iri, part)
        everything = Voxels.concat(list(m.parts.values()))
        m.decide(np.unique(everything.keys))
        self.maps[m.key] = m
        self.pending[m.key] = m.version
        return m

    def remove_skill(self, name: str) -> list[MapKey]:
        gone = [k for k in self.maps if k[1] == name]
        for k in gone:
            del self.maps[k]
            self.pending.pop(k, None)
        return gone

    def redraw(
        self, touched: Iterable[str], membership: Mapping[str, Mapping[str, bool]]
    ) -> list[tuple[str, str, int]]:
        """Bring every map up to the live scene after the elements ``touched`` changed (the drawing has
        their new geometry already; ``membership`` their new selection per skill name).

        Returns ``(storey, skill, version)`` of each map whose cloud changed (its next version).
        """
        touched = sorted(set(touched) | {i for sel in membership.values() for i in sel})
        base = self.drawing.scene.elements.index
        changed = []
        for m in self.maps.values():
            for iri, selected in membership.get(m.plan.skill.name, {}).items():
                if iri in base:
                    m.base_mask[base[iri]] = selected
                elif selected:
                    m.overlay.add(iri)
                else:
                    m.overlay.discard(iri)
            keys, gone = [], []
            for iri in touched:
                old = self._part_keys(m, iri)
                won = m._drop(iri)
                if old is not None:
                    keys.append(old)
                if won is not None:
                    gone.append(won)
                if self._member(m, iri):
                    part = self._voxels(m, iri)
                    if len(part):
                        m._set(iri, part)
                        keys.append(part.keys)
            if keys and m.decide(np.unique(np.concatenate(keys)), gone):
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
            m = points.maps.get(key)
            if m is None:
                continue
            event = PointsPublished(m.cloud(), revision, m.version, now)
            self.latest[key] = event
            self._sent_ns[key] = now
            self.emit(event)

    def drop(self, key: MapKey) -> None:
        self.latest.pop(key, None)
        self._sent_ns.pop(key, None)
