"""Skill maps against a reference whose geometry comes straight from the IFC file through OpenCASCADE.

The reference shares nothing with the import but the choice of elements (the skill's SPARQL
selection, element IRIs turned into GlobalIds by the graph) and each map's plan (its storey's z band
and grid frame): every selected element is meshed by ifcopenshell's iterator with the OpenCASCADE
kernel in world coordinates (so placements are checked too), sliced to the band and rasterised cell
by cell with shapely (:mod:`references.slab_maps`). Used by ``tests/adapters/ifc/test_maps_ifc.py`` on the
small shared models and by ``benchmarks/map_reference.py`` on all of them (Janesville is too slow
for the suite), so that the two cannot drift apart.

Example::

    check = compare_model(path, store, scene, [config.skill("navigation")], skip=pinned("FZK.ifc"))
    assert not check.lost and not check.invented and all(m.agrees for m in check.maps)
"""

from __future__ import annotations

import time
from collections.abc import Collection, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import ifcopenshell
import ifcopenshell.geom
import numpy as np

from references.slab_maps import (
    BoolArray,
    CellCheck,
    check_cells,
    is_solid,
    paint,
    rasterize_element,
    slab_geometry,
)
from twin.graph.rdf import literal_value
from twin.graph.store import GraphStore
from twin.maps.grid import OCCUPIED, Window
from twin.maps.render import MapPlan, build_map, dilate_disk, plan_map, render_window
from twin.maps.scene import Scene, SlabBox
from twin.selection.skill_selection import selection_query
from twin.selection.skills import SkillProfile

TOLERANCE_M = 0.01
"""How far our map may legitimately be from the reference, in metres: a cell must be ours if its
square shrunk by this meets the reference's geometry, and may be ours only if its square grown by this
does. Our stored meshes come from another kernel (manifold, for most elements) than the reference's,
and the project accepts two kernels' meshes of one element as the same when their world bounding
boxes are within 1 cm (``adapters.ifc.kernel_check.Tolerance.bbox_m``): curved faces are tessellated
differently, within each kernel's deflection. With 5 cm cells that is a fifth of a cell: a wall off by
a cell, a lost element, a wrong placement or an unfilled solid still show."""

PINNED: dict[tuple[str, str], str] = {}
"""(model file, GlobalId) -> why the element's map differs from the reference. Pinned elements are
left out of both sides; the benchmark reports them."""


def pinned(model: str) -> set[str]:
    """GlobalIds pinned for the model file ``model``."""
    return {guid for (name, guid) in PINNED if name == model}


@dataclass(frozen=True, slots=True)
class OccMesh:
    """One element's OpenCASCADE mesh: world ``vertices (n, 3) float64``, ``faces (m, 3) intp``
    (vertices welded), and whether it encloses a volume (then its section is filled; see
    :func:`references.slab_maps.is_solid`)."""

    guid: str
    ifc_class: str
    vertices: np.ndarray
    faces: np.ndarray
    closed: bool


def occ_meshes(path: Path, guids: Collection[str], *, threads: int = 2) -> dict[str, OccMesh]:
    """The OpenCASCADE mesh of each element of ``guids`` that the kernel meshes, by GlobalId."""
    if not guids:
        return {}
    f: Any = ifcopenshell.open(str(path))
    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)
    settings.set("weld-vertices", True)
    products = [f.by_guid(g) for g in sorted(guids)]
    it = ifcopenshell.geom.iterator(settings, f, threads, include=products, geometry_library="opencascade")
    out: dict[str, OccMesh] = {}
    more = bool(it.initialize())
    while more:
        shape: Any = it.get()
        product = f.by_id(shape.id)
        guid = str(product.GlobalId)
        verts = np.asarray(shape.geometry.verts, dtype=np.float64).reshape(-1, 3)
        faces = np.asarray(shape.geometry.faces, dtype=np.intp).reshape(-1, 3)
        if guid in guids and len(faces):
            # one vertex per position over the whole element (the kernel welds per representation item)
            verts, inverse = np.unique(verts, axis=0, return_inverse=True)
            faces = inverse.reshape(-1)[faces]
            out[guid] = OccMesh(guid, str(product.is_a()), verts, faces, is_solid(verts, faces))
        more = bool(it.next())
    return out


def selected(store: GraphStore, skill: SkillProfile) -> list[str]:
    """IRIs of the elements ``skill`` selects (with or without geometry)."""
    return [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]


def element_ids(store: GraphStore) -> dict[str, tuple[str, str]]:
    """``iri -> (GlobalId, IFC class)`` of every element, as the graph records them."""
    rows = store.select(
        "SELECT ?e ?g ?c WHERE { ?e a bot:Element ; props:globalIdIfcRoot_attribute_simple ?g ; "
        "twin:ifcClass ?c }"
    )
    return {
        literal_value(r["e"]) or "": (literal_value(r["g"]) or "", literal_value(r["c"]) or "") for r in rows
    }


@dataclass(frozen=True, slots=True)
class Culprit:
    """An element behind disagreeing cells: ``side`` is ``missed`` (a reference element the map
    lacks there) or ``extra`` (an element of ours drawing cells the reference does not have)."""

    guid: str
    ifc_class: str
    side: str
    cells: int


@dataclass(frozen=True, slots=True)
class MapComparison:
    """One (storey, skill) map against the reference: the cells, the seconds both sides took, and
    the elements behind the disagreeing cells, if any."""

    storey: str
    skill: str
    check: CellCheck
    seconds: float
    culprits: tuple[Culprit, ...] = ()

    @property
    def agrees(self) -> bool:
        return self.check.agrees

    def describe(self) -> str:
        c = self.check
        head = (
            f"{self.storey}/{self.skill}: {c.missed.sum()} missed, {c.extra.sum()} extra of {c.cells} cells"
        )
        return "; ".join([head, *(f"{x.side} {x.cells} by {x.guid} {x.ifc_class}" for x in self.culprits)])


@dataclass(slots=True)
class ModelComparison:
    """Every map of a model against the reference, and the selected elements only one side meshes
    (``lost``: OpenCASCADE meshes it, our scene has no mesh; ``invented``: the reverse), as
    ``(GlobalId, IFC class)``. ``elements``: selected elements OpenCASCADE meshed."""

    elements: int
    mesh_seconds: float
    lost: list[tuple[str, str]] = field(default_factory=list)
    invented: list[tuple[str, str]] = field(default_factory=list)
    maps: list[MapComparison] = field(default_factory=list)


def one_sided(
    scene: Scene, guid_of: dict[str, str], occ: dict[str, OccMesh], ids: dict[str, tuple[str, str]]
) -> tuple[list[tuple[str, str]], list[tuple[str, str]]]:
    """``(lost, invented)`` among the elements ``guid_of`` (iri -> GlobalId): meshed by OpenCASCADE
    and without triangles in ``scene``, and the reverse."""
    ms = scene.elements
    ours = {i for i in guid_of if i in ms.index and ms.start[ms.index[i] + 1] > ms.start[ms.index[i]]}
    lost, invented = [], []
    for iri, guid in sorted(guid_of.items(), key=lambda kv: kv[1]):
        if guid in occ and iri not in ours:
            lost.append((guid, ids[iri][1]))
        elif guid not in occ and iri in ours:
            invented.append((guid, ids[iri][1]))
    return lost, invented


def _missed_by(
    missed: BoolArray, strict: list[tuple[OccMesh, tuple[Window, BoolArray] | None]]
) -> Iterator[Culprit]:
    for mesh, item in strict:
        if item is not None:
            w, hit = item
            n = int((missed[w.row0 : w.row1, w.col0 : w.col1] & hit).sum())
            if n:
                yield Culprit(mesh.guid, mesh.ifc_class, "missed", n)


def _extra_by(
    extra: BoolArray, scene: Scene, plan: MapPlan, ids: dict[str, tuple[str, str]]
) -> Iterator[Culprit]:
    """Our elements whose own map (alone, same plan) draws some of the ``extra`` cells."""
    rows, cols = np.nonzero(extra)
    w = Window(int(rows.min()), int(cols.min()), int(rows.max()) + 1, int(cols.max()) + 1)
    f, res = plan.frame, plan.frame.resolution_m
    box = SlabBox(
        xmin=f.origin_x + w.col0 * res,
        ymin=f.origin_y + w.row0 * res,
        xmax=f.origin_x + w.col1 * res,
        ymax=f.origin_y + w.row1 * res,
        z_lo=plan.z_lo,
        z_hi=plan.z_hi,
    )
    inside = extra[w.row0 : w.row1, w.col0 : w.col1]
    for k in scene.elements.overlapping(plan.selected, box):
        iri = scene.elements.iris[k]
        alone = plan_map(scene, plan.skill, plan.storey.key, [iri])
        n = int(((render_window(scene, alone, w) == OCCUPIED) & inside).sum())
        if n:
            guid, ifc_class = ids.get(iri, (iri, "?"))
            yield Culprit(guid, ifc_class, "extra", n)


def compare_map(
    scene: Scene,
    plan: MapPlan,
    meshes: Sequence[OccMesh],
    *,
    ids: dict[str, tuple[str, str]],
    tolerance_m: float = TOLERANCE_M,
) -> MapComparison:
    """Our full map of ``plan`` against the reference rasterised from ``meshes`` (the plan's elements
    as OpenCASCADE meshes them). An inflated skill's reference is dilated by the same disk; cells a
    skill marks unknown outside the spaces are never occupied ones, so occupancy is compared as is."""
    t0 = time.perf_counter()
    ours = build_map(scene, plan).occupied()
    strict_items, loose_items = [], []
    for mesh in meshes:
        geometry = slab_geometry(mesh.vertices, mesh.faces, mesh.closed, plan.z_lo, plan.z_hi)
        strict_items.append((mesh, rasterize_element(geometry, plan.frame, grow=-tolerance_m)))
        loose_items.append(rasterize_element(geometry, plan.frame, grow=+tolerance_m))
    strict = paint(plan.frame.shape, (item for _, item in strict_items))
    loose = paint(plan.frame.shape, loose_items)
    if plan.inflation_cells:
        strict, loose = dilate_disk(strict, plan.inflation_cells), dilate_disk(loose, plan.inflation_cells)
    check = check_cells(ours, strict, loose)
    seconds = time.perf_counter() - t0
    culprits: list[Culprit] = []
    if check.missed.any():
        culprits.extend(_missed_by(check.missed, strict_items))
    if check.extra.any():
        culprits.extend(_extra_by(check.extra, scene, plan, ids))
    return MapComparison(plan.storey.key, plan.skill.name, check, seconds, tuple(culprits))


def compare_model(
    path: Path,
    store: GraphStore,
    scene: Scene,
    skills: Sequence[SkillProfile],
    *,
    skip: Collection[str] = (),
    tolerance_m: float = TOLERANCE_M,
    threads: int = 2,
) -> ModelComparison:
    """Every storey's map of every skill in ``skills`` against the OpenCASCADE reference of ``path``
    (the file ``store`` and ``scene`` were imported from), and the elements only one side meshes.

    ``skip``: GlobalIds left out of both sides (known disagreements, see :data:`PINNED`).
    """
    ids = element_ids(store)
    chosen = {s.name: [i for i in selected(store, s) if ids[i][0] not in skip] for s in skills}
    guid_of = {iri: ids[iri][0] for iris in chosen.values() for iri in iris}
    t0 = time.perf_counter()
    occ = occ_meshes(path, set(guid_of.values()), threads=threads)
    out = ModelComparison(elements=len(occ), mesh_seconds=time.perf_counter() - t0)
    out.lost, out.invented = one_sided(scene, guid_of, occ, ids)
    for skill in skills:
        iris = chosen[skill.name]
        meshes = [occ[guid_of[i]] for i in iris if guid_of[i] in occ]
        for storey in scene.storeys:
            plan = plan_map(scene, skill, storey.key, iris)
            out.maps.append(compare_map(scene, plan, meshes, ids=ids, tolerance_m=tolerance_m))
    return out
