"""Writing the snapshot: the writer copies the live state between two commits (:func:`capture`), and the
copy is compressed and written on another thread (:class:`Snapshots`).

Example::

    snapshots = Snapshots(snapshot_path(store_dir), every_s=300)
    snapshots.save_in_background(live)     # on the writer's thread: a copy, then a thread writes it
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin.live.snapshots.keys import skill_digest
from twin.live.state import ElementState, LiveState
from twin.maps.scene import Scene
from twin.maps.snapshot import AnyArray, write_snapshot
from twin.records import Mesh, Shape

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False, slots=True)
class _MapCopy:
    storey: str
    skill: str
    skill_digest: str
    version: int
    overlay: tuple[str, ...]
    base_mask: AnyArray
    static: AnyArray
    data: AnyArray
    inside: AnyArray | None


@dataclass(frozen=True, eq=False, slots=True)
class _PointsCopy:
    storey: str
    skill: str
    skill_digest: str
    version: int
    overlay: tuple[str, ...]
    base_mask: AnyArray
    names: list[str]
    arrays: dict[str, AnyArray]


@dataclass(frozen=True, eq=False, slots=True)
class Captured:
    """The live maps at one revision, copied (what changes) or shared (what never does: the scene)."""

    revision: int
    keys: dict[str, Any]
    scene: Scene
    hidden: AnyArray
    overlay: dict[str, Shape]
    maps: tuple[_MapCopy, ...]
    states: dict[str, ElementState]
    points: tuple[_PointsCopy, ...] = ()
    fusion: dict[str, Any] | None = None
    """Fusion's memory (:meth:`twin.fusion.memory.FusionMemory.to_json`): sightings, misses, clocks."""


def capture(live: LiveState, keys: dict[str, Any]) -> Captured:
    """Copy what the writer changes (on the writer's thread, between two commits: a few memcpys)."""
    maps = tuple(
        _MapCopy(
            m.plan.storey.key,
            m.plan.skill.name,
            skill_digest(m.plan.skill),
            m.version,
            tuple(sorted(m.overlay)),
            m.base_mask.copy(),
            m.static.copy(),
            m.data.copy(),
            None if m.inside is None else m.inside.copy(),
        )
        for m in live.maps.skill_maps.values()
    )
    points = []
    for p in live.maps.points.clouds.values():
        names, arrays = p.packed()  # new arrays: a copy
        points.append(
            _PointsCopy(
                p.plan.storey.key,
                p.plan.skill.name,
                skill_digest(p.plan.skill),
                p.version,
                tuple(sorted(p.overlay)),
                p.base_mask.copy(),
                names,
                arrays,
            )
        )
    return Captured(
        live.revision,
        keys,
        live.maps.scene,
        live.maps.hidden.copy(),
        live.maps.overlay_shapes(),
        maps,
        dict(live.states),  # the states themselves are immutable
        tuple(points),
        live.fusion.to_json(),  # new values: a copy
    )


def _state_json(s: ElementState) -> list[Any]:
    sets = (s.classes, s.labels, s.materials, s.facing_materials)
    head = [s.iri, s.ifc_class, list(s.ifc_types), s.is_static, s.name, s.storey, s.is_open, s.removed]
    return [*head, s.keepout, s.speed_limit, *(sorted(x) for x in sets), s.sensed_ns]


def _pool(shapes: Sequence[Shape]) -> tuple[dict[str, AnyArray], AnyArray, AnyArray]:
    """Distinct meshes (shared ones once) packed into arrays; each shape's mesh index and placement."""
    ids: dict[int, int] = {}
    meshes: list[Mesh] = []
    which = np.empty(len(shapes), dtype=np.int64)
    for i, (mesh, _) in enumerate(shapes):
        k = ids.get(id(mesh))
        if k is None:
            k = ids[id(mesh)] = len(meshes)
            meshes.append(mesh)
        which[i] = k
    vstart = np.zeros(len(meshes) + 1, dtype=np.int64)
    np.cumsum([len(m.vertices) for m in meshes], out=vstart[1:])
    fstart = np.zeros(len(meshes) + 1, dtype=np.int64)
    np.cumsum([len(m.faces) for m in meshes], out=fstart[1:])
    pool = {
        "vertices": np.concatenate([m.vertices for m in meshes]) if meshes else np.empty((0, 3)),
        "faces": np.concatenate([m.faces for m in meshes]) if meshes else np.empty((0, 3), np.int32),
        "vstart": vstart,
        "fstart": fstart,
        "closed": np.array([m.closed for m in meshes], dtype=np.bool_),
        "solid": np.array([m.solid for m in meshes], dtype=np.bool_),
    }
    placements = np.array([p for _, p in shapes], dtype=np.float64).reshape(len(shapes), 4, 4)
    return pool, which, placements


def save(path: Path, snap: Captured) -> int:
    """Write ``snap`` to ``path`` (atomically); the file's size in bytes."""
    scene = snap.scene
    els = scene.elements
    shapes = [scene.shapes[iri] for iri in els.iris]
    over = sorted(snap.overlay)
    pool, which, placements = _pool([*shapes, *(snap.overlay[i] for i in over)])
    arrays: dict[str, AnyArray] = {f"pool_{k}": a for k, a in pool.items()}
    arrays["el_mesh"], arrays["el_placement"] = which[: len(shapes)], placements[: len(shapes)]
    arrays["el_bounds"] = els.bounds
    arrays["ov_mesh"], arrays["ov_placement"] = which[len(shapes) :], placements[len(shapes) :]
    sp = scene.spaces
    arrays |= {
        "sp_triangles": sp.triangles,
        "sp_start": sp.start.astype(np.int64),
        "sp_closed": sp.closed,
        "sp_solid": sp.solid,
        "sp_bounds": sp.bounds,
        "sp_triangle_bounds": sp.triangle_bounds,
        "hidden": snap.hidden,
    }
    maps = []
    for j, m in enumerate(snap.maps):
        arrays |= {f"m{j}_mask": m.base_mask, f"m{j}_static": m.static, f"m{j}_data": m.data}
        if m.inside is not None:
            arrays[f"m{j}_inside"] = m.inside
        maps.append(
            {
                "storey": m.storey,
                "skill": m.skill,
                "skill_digest": m.skill_digest,
                "version": m.version,
                "overlay": list(m.overlay),
            }
        )
    points = []
    for j, p in enumerate(snap.points):
        arrays[f"p{j}_mask"] = p.base_mask
        arrays |= {f"p{j}_{name}": a for name, a in p.arrays.items()}
        points.append(
            {
                "storey": p.storey,
                "skill": p.skill,
                "skill_digest": p.skill_digest,
                "version": p.version,
                "overlay": list(p.overlay),
                "names": p.names,
            }
        )
    header = {
        "kind": "building-twin live maps",
        "revision": snap.revision,
        "keys": snap.keys,
        "written_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "elements": list(els.iris),
        "spaces": list(sp.iris),
        "storeys": [[s.iri, s.key, s.name, s.elevation_m, list(s.extent)] for s in scene.storeys],
        "space_storey": scene.space_storey,
        "overlay": over,
        "maps": maps,
        "points": points,
        "states": [_state_json(st) for st in snap.states.values()],
        "fusion": snap.fusion,
    }
    return write_snapshot(path, header, arrays)


# --- restore -----------------------------------------------------------------------------------------


# --- when and where ---------------------------------------------------------------------------------


def snapshot_path(store: Path) -> Path:
    """Where the snapshot of the embedded store at ``store`` (a directory) lives: ``<store>.snapshot``."""
    return store.with_name(f"{store.name}.snapshot")


class Snapshots:
    """The snapshot file of one store, and when to write it: :meth:`save` (a clean stop),
    :meth:`save_in_background` (every ``every_s`` while anything changed, and after a rebuild)."""

    def __init__(self, path: Path, *, every_s: float = 300.0) -> None:
        self.path = path
        self.every_s = every_s
        self.saved_revision = -1
        self._saved_at = time.monotonic()
        self._thread: threading.Thread | None = None
        self.keys: dict[str, Any] = {}

    def due(self, revision: int) -> bool:
        return revision != self.saved_revision and time.monotonic() - self._saved_at >= self.every_s

    def _write(self, snap: Captured) -> None:
        t0 = time.perf_counter()
        try:
            size = save(self.path, snap)
        except Exception:  # a snapshot is an optimisation: never worth the daemon
            log.exception("Could not write the snapshot %s", self.path)
            return
        log.info(
            "Snapshot of revision %d written to %s (%.1f MB) in %.2f s",
            snap.revision,
            self.path,
            size / 1e6,
            time.perf_counter() - t0,
        )

    def save(self, live: LiveState) -> None:
        """Write the snapshot of ``live`` now (waiting for a background write first)."""
        self.join()
        self._write(capture(live, self.keys))
        self.saved_revision, self._saved_at = live.revision, time.monotonic()

    def save_in_background(self, live: LiveState) -> None:
        """Copy ``live`` now (the caller is the writer), write it on a thread; skipped while one runs."""
        if self._thread is not None and self._thread.is_alive():
            return
        snap = capture(live, self.keys)
        self.saved_revision, self._saved_at = live.revision, time.monotonic()
        self._thread = threading.Thread(target=self._write, args=(snap,), name="twin-snapshot", daemon=True)
        self._thread.start()

    def join(self) -> None:
        if self._thread is not None:
            self._thread.join()
            self._thread = None
