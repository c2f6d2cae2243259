"""Reading the snapshot back: the scene and the maps as they were (:func:`restore`), and the elements
changed since brought up to date through the incremental path (:func:`replay`).

Example::

    restored = restore(path, keys=keys, revision=store_revision, skills=skills, margin_m=1.0)
    replay(store, live, since=restored.revision)
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from twin.errors import SnapshotError, TwinError
from twin.graph.meshcodec import decode_mesh, decode_placement
from twin.graph.store import GraphStore
from twin.live.live_map import LiveMap
from twin.live.live_maps import LiveMaps
from twin.live.live_points import PointsMap
from twin.live.membership import membership
from twin.live.snapshots.keys import skill_digest
from twin.live.state import ElementState, LiveState, load_states
from twin.maps.points import plan_points
from twin.maps.render import plan_map
from twin.maps.scene import MeshSet, Scene, StoreyInfo, placed_normals
from twin.maps.snapshot import AnyArray, read_snapshot
from twin.records import FloatArray, GeometryChange, Mesh, Shape, to_world
from twin.selection.skills import SkillProfile

log = logging.getLogger(__name__)


def _state(row: list[Any]) -> ElementState:
    iri, cls, types, static, name, storey, is_open, removed, keepout, speed, *sets, sensed = row
    classes, labels, materials, facing = (frozenset(str(v) for v in x) for x in sets)
    return ElementState(
        iri=str(iri),
        ifc_class=str(cls),
        ifc_types=tuple(str(t) for t in types),
        is_static=bool(static),
        name=str(name),
        storey=None if storey is None else str(storey),
        is_open=None if is_open is None else bool(is_open),
        removed=bool(removed),
        keepout=bool(keepout),
        speed_limit=int(speed),
        classes=classes,
        labels=labels,
        materials=materials,
        facing_materials=facing,
        sensed_ns=int(sensed),
    )


def _unpool(arrays: dict[str, AnyArray], prefix: str) -> list[Mesh]:
    v, f = arrays[f"{prefix}vertices"], arrays[f"{prefix}faces"]
    vs, fs, closed = arrays[f"{prefix}vstart"], arrays[f"{prefix}fstart"], arrays[f"{prefix}closed"]
    solid = arrays[f"{prefix}solid"]
    return [
        Mesh(v[vs[k] : vs[k + 1]], f[fs[k] : fs[k + 1]], bool(closed[k]), bool(solid[k]))
        for k in range(len(closed))
    ]


@dataclass(eq=False, slots=True)
class Restored:
    """Live maps read from a snapshot taken at ``revision``, with the maps of ``skills`` (by name).

    Their scene starts without the elements' world triangles (their arrays allocated but not written:
    the bounds are enough to publish maps). :meth:`fill_near` computes those of the elements around
    some boxes (what a replay re-renders), :meth:`complete` all of them, bit for bit as
    :meth:`MeshSet.build` would."""

    maps: LiveMaps
    revision: int
    skills: frozenset[str]
    items: list[tuple[str, Mesh, FloatArray]]
    states: dict[str, ElementState]
    filled: AnyArray = field(default_factory=lambda: np.zeros(0, dtype=np.bool_))
    fusion: dict[str, Any] | None = None
    """Fusion's memory as the snapshot kept it (:meth:`twin.fusion.memory.FusionMemory.from_json`)."""

    def _fill(self, ids: AnyArray) -> None:
        els = self.maps.scene.elements
        b = els.bounds[~np.isnan(els.bounds).any(axis=1)]
        pad = 1e-3 + 1e-6 * float(np.abs(b).max(initial=0.0))  # as MeshSet.build: the largest coordinate
        for i in ids:
            lo_row, hi_row = int(els.start[i]), int(els.start[i + 1])
            self.filled[i] = True
            if lo_row == hi_row:
                continue
            _, mesh, placement = self.items[i]
            world = to_world(mesh.vertices, placement)
            t = els.triangles[lo_row:hi_row]
            t[...] = world[mesh.faces]
            lo = np.minimum(np.minimum(t[:, 0], t[:, 1]), t[:, 2])
            hi = np.maximum(np.maximum(t[:, 0], t[:, 1]), t[:, 2])
            els.triangle_bounds[lo_row:hi_row, :3] = lo - pad
            els.triangle_bounds[lo_row:hi_row, 3:] = hi + pad
            if els.normals is not None:
                els.normals[lo_row:hi_row] = placed_normals(mesh, placement)

    def fill_near(self, boxes: Sequence[FloatArray]) -> None:
        """Compute the triangles of every element whose XY bounds come within two cells (and half a
        metre) of one of ``boxes`` (world AABBs): all that re-rendering their cells reads."""
        b = self.maps.scene.elements.bounds
        res = max((m.plan.frame.resolution_m for m in self.maps.skill_maps.values()), default=0.05)
        margin = 0.5 + 2 * res
        need = np.zeros(len(b), dtype=np.bool_)
        for box in boxes:
            need |= (
                (b[:, 0] <= box[3] + margin)
                & (b[:, 3] >= box[0] - margin)
                & (b[:, 1] <= box[4] + margin)
                & (b[:, 4] >= box[1] - margin)
            )
        self._fill(np.flatnonzero(need & ~self.filled))

    def complete(self) -> None:
        """Compute the triangles of every element not computed yet (then the scene is whole)."""
        if not self.items:
            return
        if not self.filled.any():  # nothing yet: all at once
            self.maps.scene = replace(self.maps.scene, elements=MeshSet.build(self.items))
        else:
            self._fill(np.flatnonzero(~self.filled))
        self.items = []


def _extent(e: Sequence[float]) -> tuple[float, float, float, float]:
    return (float(e[0]), float(e[1]), float(e[2]), float(e[3]))


def _skeleton(items: list[tuple[str, Mesh, FloatArray]], bounds: AnyArray) -> MeshSet:
    """The mesh set of ``items`` with its triangle arrays zeroed, not computed (see :class:`Restored`):
    zeroed pages cost nothing until written."""
    iris = tuple(i for i, _, _ in items)
    start = np.zeros(len(items) + 1, dtype=np.intp)
    np.cumsum([m.triangle_count for _, m, _ in items], out=start[1:])
    closed = np.array([m.closed for _, m, _ in items], dtype=np.bool_)
    solid = np.array([m.solid for _, m, _ in items], dtype=np.bool_)
    if bounds.shape != (len(items), 6):
        msg = f"its element bounds are {bounds.shape} for {len(items)} elements"
        raise SnapshotError(msg)
    n = int(start[-1])
    triangles, triangle_bounds = np.zeros((n, 3, 3)), np.zeros((n, 6), dtype=np.float32)
    normals = np.zeros((n, 3), dtype=np.float32)
    return MeshSet(
        iris,
        {iri: i for i, iri in enumerate(iris)},
        triangles,
        start,
        closed,
        solid,
        bounds,
        triangle_bounds,
        normals,
    )


def _scene(
    header: dict[str, Any], arrays: dict[str, AnyArray]
) -> tuple[Scene, dict[str, Shape], list[tuple[str, Mesh, FloatArray]]]:
    meshes = _unpool(arrays, "pool_")
    iris = [str(i) for i in header["elements"]]
    which, placements = arrays["el_mesh"], arrays["el_placement"]
    items = [(iri, meshes[int(which[i])], placements[i]) for i, iri in enumerate(iris)]
    elements = _skeleton(items, arrays["el_bounds"])
    sp_iris = tuple(str(i) for i in header["spaces"])
    spaces = MeshSet(
        sp_iris,
        {iri: i for i, iri in enumerate(sp_iris)},
        arrays["sp_triangles"],
        arrays["sp_start"].astype(np.intp),
        arrays["sp_closed"],
        arrays["sp_solid"],
        arrays["sp_bounds"],
        arrays["sp_triangle_bounds"],
    )
    if len(spaces.start) != len(sp_iris) + 1 or len(elements) != len(arrays["hidden"]):
        msg = "its spaces or elements do not match their arrays"
        raise SnapshotError(msg)
    storeys = tuple(
        StoreyInfo(str(iri), str(key), str(name), float(elev), _extent(e))
        for iri, key, name, elev, e in header["storeys"]
    )
    scene = Scene(elements, spaces, storeys, dict(header["space_storey"]), {i: (m, p) for i, m, p in items})
    ov_which, ov_place = arrays["ov_mesh"], arrays["ov_placement"]
    overlay = {str(iri): (meshes[int(ov_which[i])], ov_place[i]) for i, iri in enumerate(header["overlay"])}
    return scene, overlay, items


def restore(
    path: Path, *, keys: dict[str, Any], revision: int, skills: dict[str, SkillProfile], margin_m: float
) -> Restored:
    """The live maps of the snapshot at ``path`` if it verifies and matches ``keys`` and is not ahead of
    ``revision``; SnapshotError says why not (missing, damaged, stale keys, ahead of the store)."""
    header, arrays = read_snapshot(path)
    if header.get("kind") != "building-twin live maps":
        msg = f"The snapshot {path} is not of the live maps ({header.get('kind')!r})."
        raise SnapshotError(msg)
    theirs = header.get("keys", {})
    for name, ours in keys.items():
        if theirs.get(name) != ours:
            msg = f"The snapshot {path} is of another {name}: {theirs.get(name)!r}, the store's is {ours!r}."
            raise SnapshotError(msg)
    at = int(header["revision"])
    if at > revision:
        msg = f"The snapshot {path} is ahead of the store (revision {at} > {revision}): was it replaced?"
        raise SnapshotError(msg)
    try:
        scene, overlay, items = _scene(header, arrays)
        states = {st.iri: st for st in map(_state, header["states"])}
        maps: list[LiveMap] = []
        for j, entry in enumerate(header["maps"]):
            skill = skills.get(str(entry["skill"]))
            if skill is None or skill_digest(skill) != entry["skill_digest"]:
                continue
            plan = plan_map(scene, skill, str(entry["storey"]), (), margin_m=margin_m)
            static, data = arrays[f"m{j}_static"], arrays[f"m{j}_data"]
            inside = arrays.get(f"m{j}_inside")
            shape = (plan.frame.height, plan.frame.width)
            if static.shape != shape or data.shape != shape or (inside is None) == skill.unknown_outside:
                msg = f"its map {entry['storey']}/{entry['skill']} is {static.shape}, the grid {shape}"
                raise SnapshotError(msg)
            maps.append(
                LiveMap(
                    plan,
                    arrays[f"m{j}_mask"],
                    {str(i) for i in entry["overlay"]},
                    static,
                    inside,
                    data,
                    int(entry["version"]),
                )
            )
        points: list[PointsMap] = []
        for j, entry in enumerate(header.get("points", [])):
            skill = skills.get(str(entry["skill"]))
            if skill is None or skill.kind != "points" or skill_digest(skill) != entry["skill_digest"]:
                continue
            cloud_plan = plan_points(scene, skill, str(entry["storey"]), (), margin_m=margin_m)
            parts = {n: arrays[f"p{j}_{n}"] for n in ("keys", "q", "d2", "n", "wins", "counts")}
            points.append(
                PointsMap.unpacked(
                    cloud_plan,
                    arrays[f"p{j}_mask"],
                    {str(i) for i in entry["overlay"]},
                    names=[str(n) for n in entry["names"]],
                    arrays=parts,
                    version=int(entry["version"]),
                )
            )
    except SnapshotError as err:
        msg = f"The snapshot {path} is inconsistent: {err}."
        raise SnapshotError(msg) from err
    except (KeyError, TypeError, ValueError, IndexError, TwinError) as err:
        msg = f"The snapshot {path} is inconsistent: {type(err).__name__}: {err}."
        raise SnapshotError(msg) from err
    live = LiveMaps.restored(scene, margin_m=margin_m, hidden=arrays["hidden"], overlay=overlay, maps=maps)
    for p in points:
        live.points.clouds[p.key] = p
        live.points.pending[p.key] = p.version  # published at the first flush
    filled = np.zeros(len(items), dtype=np.bool_)
    names = frozenset(m.plan.skill.name for m in maps) | frozenset(p.plan.skill.name for p in points)
    fusion = header.get("fusion")
    return Restored(live, at, names, items, states, filled, fusion if isinstance(fusion, dict) else None)


# --- replay ------------------------------------------------------------------------------------------

_SHAPES = """SELECT ?node ?ply ?placement WHERE {{
  VALUES ?node {{ {iris} }}
  ?node omg:hasGeometry ?g .
  ?g fog:asPly_v1.0-binaryLE ?ply ; twin:placement ?placement ; twin:closedMesh ?closed .
}}"""


def _same(a: Shape | None, b: Shape | None) -> bool:
    if a is None or b is None:
        return a is b
    return (
        a[0].closed == b[0].closed
        and a[0].solid == b[0].solid
        and np.array_equal(a[0].vertices, b[0].vertices)
        and np.array_equal(a[0].faces, b[0].faces)
        and np.array_equal(a[1], b[1])
    )


def replay(
    store: GraphStore,
    live: LiveState,
    since: int,
    *,
    before_base: Callable[[list[FloatArray]], None] = lambda boxes: None,
) -> int:
    """Bring maps restored at revision ``since`` up to the store's: every element whose
    ``twin:revision`` is newer takes its stored geometry and selection through
    :meth:`LiveMaps.redraw`, and its state is read again from the store. ``before_base`` runs first
    with the old and new bounds of the imported elements among them, if any (the static rasters are
    patched around them: :meth:`Restored.fill_near`).
    Returns how many."""
    rows = store.select(f"SELECT DISTINCT ?e WHERE {{ ?e twin:revision ?r . FILTER(?r > {int(since)}) }}")
    changed = [i for r in rows if (i := r["e"] or "") != live.site.model_iri]
    if not changed:
        return 0
    fresh = load_states(store, changed)
    live.states.update(fresh)
    iris = sorted(fresh)
    stored: dict[str, Shape | None] = dict.fromkeys(iris)
    for k in range(0, len(iris), 500):
        values = " ".join(f"<{i}>" for i in iris[k : k + 500])
        for r in store.select(_SHAPES.format(iris=values)):
            stored[r["node"] or ""] = (decode_mesh(r["ply"] or ""), decode_placement(r["placement"] or ""))
    geometry = [GeometryChange(i, stored[i]) for i in iris if not _same(live.maps.shape_of(i), stored[i])]
    base = live.maps.scene.elements
    boxes = [base.bounds[base.index[i]] for i in iris if i in base.index]
    for g in geometry:
        if g.iri in base.index and g.new is not None and len(g.new[0].faces):
            mesh, placement = g.new
            world = to_world(mesh.vertices, placement)[mesh.faces.ravel()]
            boxes.append(np.concatenate([world.min(axis=0), world.max(axis=0)]))
    boxes = [b for b in boxes if not np.isnan(b).any()]
    if boxes:
        before_base(boxes)
    chosen = membership(store, live.skills, live.states, iris, lambda i: stored[i] is not None)
    live.maps.redraw(geometry, chosen)
    return len(iris)
