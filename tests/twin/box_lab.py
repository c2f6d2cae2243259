"""The paper's lab as core records built from boxes: no IFC, no ifcopenshell (the core's own tests).

The lab is ``twin.samples.lab_layout`` (the layout ``adapters.ifc.sample_lab`` writes as IFC), so the core's
tests and the IFC tests see the same building: same names, classes, materials, GlobalIds and world
boxes (the building at x 10.., y 5..), ground floor only unless ``storeys=2``. Each element's mesh is
its box, or the boxes left of it once its openings are cut (Wall A south, with Door A's opening); a
slab is its bounding box (the ground floor's is H-shaped in the IFC file, under the map heights
either way). Relations are the file's: space boundaries, containment (the table in Room A, the
opening in no spatial structure) and decomposition (wall -> opening -> door).
"""

from __future__ import annotations

import numpy as np

from twin.graph.ifc_classes import supertypes
from twin.graph.vocab import entity_iri
from twin.maps.shapes import box_mesh, box_placement
from twin.records import Building, BuildingModel, Element, Geometry, Mesh, Relation, Site, Space, Storey
from twin.samples.lab_layout import LabElement, LabLayout, lab_layout
from twin.samples.lab_plan import BUILDING, BUILDING_OFFSET, SITE, Box

OX, OY = BUILDING_OFFSET[0], BUILDING_OFFSET[1]
BASE = "https://example.org/test#"
STATIC = ("IfcWall", "IfcDoor", "IfcOpeningElement", "IfcSlab")
"""The classes of the lab that ``[import] static_types`` of the default configuration lists."""

LAB: LabLayout = lab_layout(storeys=2)
GROUND: tuple[LabElement, ...] = tuple(e for e in LAB.elements if e.storey == LAB.storeys[0].name)
FIRST: tuple[LabElement, ...] = tuple(e for e in LAB.elements if e.storey == LAB.storeys[1].name)


def element_iri(element: LabElement) -> str:
    return entity_iri(BASE, element.ifc_class, element.global_id)


def spec(name: str) -> LabElement:
    """The lab's element ``name`` (world box, GlobalId, class, material)."""
    return LAB.element(name)


def _boxes_geometry(boxes: tuple[Box, ...]) -> Geometry:
    """One closed mesh of the disjoint world ``boxes``, its local origin at the first box's centre (as
    ``twin.maps.shapes`` places a box: a single box's mesh is centred)."""
    centres = np.array([[(b[i] + b[i + 3]) / 2 for i in range(3)] for b in boxes])
    vertices, faces, count = [], [], 0
    for b, centre in zip(boxes, centres - centres[0], strict=True):
        mesh = box_mesh(b.xmax - b.xmin, b.ymax - b.ymin, b.zmax - b.zmin)
        vertices.append(mesh.vertices + centre)
        faces.append(mesh.faces + count)
        count += len(mesh.vertices)
    mesh = Mesh(np.concatenate(vertices), np.concatenate(faces).astype(np.int32), closed=True)
    return Geometry(mesh, box_placement(*centres[0]))


def _element(e: LabElement) -> Element:
    materials = () if e.material is None else (e.material,)
    types = supertypes("IFC4", e.ifc_class)
    assert types is not None, e.ifc_class
    return Element(
        guid=e.global_id,
        ifc_class=e.ifc_class,
        name=e.name,
        materials=materials,
        facing_materials=materials,
        is_static=e.ifc_class in STATIC,
        geometry=_boxes_geometry(LAB.solid(e.name)),
        ifc_types=types,
    )


def box_lab(*, storeys: int = 1) -> BuildingModel:
    """The lab as a :class:`BuildingModel` (one or two storeys), ready for ``import_model``."""
    lab = lab_layout(storeys=2 if storeys == 2 else 1)
    site = Site(lab.site_guid, SITE)
    building = Building(lab.building_guid, BUILDING, site.guid)
    storey_of = {s.name: Storey(s.global_id, s.name, s.elevation_m, building.guid) for s in lab.storeys}
    spaces = {
        s.name: Space(s.global_id, s.name, storey_of[s.storey].guid, _boxes_geometry((s.box,)))
        for s in lab.spaces
    }
    by_name = {e.name: e for e in lab.elements}
    structure = {name: s.guid for name, s in (*storey_of.items(), *spaces.items())}
    contained = {
        Relation(structure[e.container], e.global_id) for e in lab.elements if e.container in structure
    }
    decomposed = {
        Relation(by_name[e.container].global_id, e.global_id) for e in lab.elements if e.container in by_name
    } | {Relation(by_name[e.fills].global_id, e.global_id) for e in lab.elements if e.fills is not None}
    adjacent = {Relation(spaces[s.name].guid, by_name[n].global_id) for s in lab.spaces for n in s.bounded_by}
    return BuildingModel(
        source_name="box-lab",
        schema="IFC4",
        source_lines=0,
        sites=(site,),
        buildings=(building,),
        storeys=tuple(storey_of.values()),
        spaces=tuple(spaces.values()),
        elements=tuple(_element(e) for e in lab.elements),
        adjacent=frozenset(adjacent),
        contained=frozenset(contained),
        decomposed=frozenset(decomposed),
    )
