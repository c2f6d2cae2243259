"""Read an IFC file into a :class:`twin.records.BuildingModel` (spatial structure, elements, relations, meshes).

Lengths come out in metres whatever the file's unit: the geometry iterator converts meshes and
placements, and storey elevations are scaled by the file's length unit.

Example::

    model = read_model(Path("lab.ifc"), static_types=("IfcWall", "IfcSlab"))
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import ifcopenshell.util.element
import ifcopenshell.util.placement
import ifcopenshell.util.unit

from adapters.ifc.geometry import DEFAULT_KERNELS, Progress, mesh_products
from adapters.ifc.open_file import open_ifc
from twin.records import Building, BuildingModel, Element, Relation, Site, Space, Storey

log = logging.getLogger(__name__)


def material_names(element: Any) -> tuple[str, ...]:
    """IfcMaterial names of ``element`` (own or inherited from its type), in order, without duplicates."""
    mat = ifcopenshell.util.element.get_material(element, should_skip_usage=True)
    if mat is None:
        return ()
    found: list[Any] = []
    if mat.is_a("IfcMaterial"):
        found = [mat]
    elif mat.is_a("IfcMaterialLayerSet"):
        found = [layer.Material for layer in mat.MaterialLayers or ()]
    elif mat.is_a("IfcMaterialList"):
        found = list(mat.Materials or ())
    elif mat.is_a("IfcMaterialConstituentSet"):
        found = [c.Material for c in mat.MaterialConstituents or ()]
    elif mat.is_a("IfcMaterialProfileSet"):
        found = [p.Material for p in mat.MaterialProfiles or ()]
    names: dict[str, None] = {}
    for m in found:
        if m is not None and m.Name:
            names[str(m.Name)] = None
    return tuple(names)


def _parent(entity: Any) -> Any | None:
    """The whole an element is part of: its aggregate, the host of an opening, the opening it fills."""
    agg = ifcopenshell.util.element.get_aggregate(entity)
    if agg is not None:
        return agg
    for rel in getattr(entity, "VoidsElements", None) or ():
        return rel.RelatingBuildingElement
    for rel in getattr(entity, "FillsVoids", None) or ():
        return rel.RelatingOpeningElement
    return None


def _storey_of(entity: Any, storey_ids: set[int]) -> Any | None:
    seen: set[int] = set()
    node = entity
    while node is not None and node.id() not in seen:
        seen.add(node.id())
        if node.id() in storey_ids:
            return node
        container = ifcopenshell.util.element.get_container(node)
        node = container if container is not None else _parent(node)
    return None


def _elevation_m(storey: Any, scale: float) -> float:
    if storey.ObjectPlacement is not None:
        matrix = ifcopenshell.util.placement.get_local_placement(storey.ObjectPlacement)
        return float(matrix[2, 3]) * scale
    return float(storey.Elevation or 0.0) * scale


def _pairs(rels: Iterable[tuple[Any, Any]], left: set[int], right: set[int]) -> frozenset[Relation]:
    return frozenset(
        Relation(a.GlobalId, b.GlobalId)
        for a, b in rels
        if a is not None and b is not None and a.id() in left and b.id() in right
    )


def read_model(
    path: Path,
    *,
    static_types: Sequence[str] = (),
    kernels: Sequence[str] = DEFAULT_KERNELS,
    threads: int = 2,
    progress: Progress | None = None,
) -> BuildingModel:
    """Read ``path`` into records. Raise :class:`~adapters.ifc.errors.IfcFileError` on a bad file."""
    f, lines = open_ifc(path)
    scale = float(ifcopenshell.util.unit.calculate_unit_scale(f))
    sites = f.by_type("IfcSite")
    buildings = f.by_type("IfcBuilding")
    storeys = f.by_type("IfcBuildingStorey")
    spaces = f.by_type("IfcSpace")
    elements = f.by_type("IfcElement")
    storey_ids = {s.id() for s in storeys}

    meshed = mesh_products(f, [*elements, *spaces], kernels=kernels, threads=threads, progress=progress)
    fallback_kernel = kernels[0] if kernels else ""
    kernel_fallbacks = tuple(
        f.by_id(pid).GlobalId
        for pid, kernel in meshed.kernel_of.items()
        if kernel != fallback_kernel and f.by_id(pid).is_a("IfcElement")
    )
    failures = tuple(f.by_id(pid).GlobalId for pid in meshed.unmeshed if f.by_id(pid).is_a("IfcElement"))

    def agg_guid(entity: Any, kind: str) -> str | None:
        node = ifcopenshell.util.element.get_aggregate(entity)
        while node is not None and not node.is_a(kind):
            node = ifcopenshell.util.element.get_aggregate(node)
        return str(node.GlobalId) if node is not None else None

    def storey_guid(entity: Any) -> str | None:
        st = _storey_of(entity, storey_ids)
        return str(st.GlobalId) if st is not None else None

    statics = tuple(static_types)
    element_records = tuple(
        Element(
            guid=str(e.GlobalId),
            ifc_class=e.is_a(),
            name=str(e.Name or ""),
            materials=material_names(e),
            is_static=any(e.is_a(t) for t in statics),
            storey_guid=storey_guid(e),
            geometry=meshed.geometry.get(e.id()),
        )
        for e in elements
    )
    element_ids = {e.id() for e in elements}
    space_ids = {s.id() for s in spaces}
    structure_ids = space_ids | storey_ids
    adjacent = _pairs(
        ((r.RelatingSpace, r.RelatedBuildingElement) for r in f.by_type("IfcRelSpaceBoundary")),
        space_ids,
        element_ids,
    )
    contained = _pairs(
        (
            (r.RelatingStructure, e)
            for r in f.by_type("IfcRelContainedInSpatialStructure")
            for e in r.RelatedElements or ()
        ),
        structure_ids,
        element_ids,
    )
    decomposed = _pairs(
        [
            *((r.RelatingObject, o) for r in f.by_type("IfcRelAggregates") for o in r.RelatedObjects or ()),
            *((r.RelatingObject, o) for r in f.by_type("IfcRelNests") for o in r.RelatedObjects or ()),
            *((r.RelatingBuildingElement, r.RelatedOpeningElement) for r in f.by_type("IfcRelVoidsElement")),
            *((r.RelatingOpeningElement, r.RelatedBuildingElement) for r in f.by_type("IfcRelFillsElement")),
        ],
        element_ids,
        element_ids,
    )
    return BuildingModel(
        source_name=Path(path).name,
        schema=str(f.schema),
        source_lines=lines,
        sites=tuple(Site(str(s.GlobalId), str(s.Name or "")) for s in sites),
        buildings=tuple(Building(str(b.GlobalId), str(b.Name or ""), agg_guid(b, "IfcSite")) for b in buildings),
        storeys=tuple(
            Storey(str(s.GlobalId), str(s.Name or ""), _elevation_m(s, scale), agg_guid(s, "IfcBuilding"))
            for s in storeys
        ),
        spaces=tuple(
            Space(str(s.GlobalId), str(s.Name or ""), storey_guid(s), meshed.geometry.get(s.id())) for s in spaces
        ),
        elements=element_records,
        adjacent=adjacent,
        contained=contained,
        decomposed=decomposed,
        mesh_failures=failures,
        kernel_fallbacks=kernel_fallbacks,
    )
