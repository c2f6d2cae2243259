"""Solid or surface, from the representation: what decides whether an element's open mesh is filled."""

from __future__ import annotations

from typing import Any

import ifcopenshell.api.geometry
import ifcopenshell.api.root
import ifcopenshell.api.spatial
import pytest

from adapters.ifc.body_kind import BodyKind
from tests.adapters.generated import Generated, box_faces


def _element_with(g: Generated, items: list[Any], kind: str, storey: Any) -> Any:
    f = g.file
    element = ifcopenshell.api.root.create_entity(f, ifc_class="IfcBuildingElementProxy", name=kind)
    ifcopenshell.api.spatial.assign_container(f, products=[element], relating_structure=storey)
    body = f.createIfcShapeRepresentation(g.body, "Body", kind, items)
    ifcopenshell.api.geometry.assign_representation(f, product=element, representation=body)
    return element


def _faces(g: Generated, closed: bool | None) -> Any:
    f = g.file
    points = f.createIfcCartesianPointList3D(
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    )
    return f.createIfcTriangulatedFaceSet(points, None, closed, [[1, 3, 2], [1, 2, 4], [2, 3, 4], [3, 1, 4]])


@pytest.fixture(scope="module")
def model() -> tuple[Generated, dict[str, Any]]:
    g = Generated("IFC4")
    storey = g.storey("Ground", 0.0)
    f = g.file
    brep = g.faceted_brep(box_faces((0.0, 0.0, 0.0), (1.0, 1.0, 1.0)))
    shell = f.createIfcOpenShell([f.createIfcFace(list(face.Bounds)) for face in brep.Outer.CfsFaces[:3]])
    surface = f.createIfcShellBasedSurfaceModel([shell])
    elements = {
        "extrusion": g.box("IfcWall", "W", (0.0, 0.0, 0.0), (4.0, 0.3, 3.0), container=storey),
        "brep": g.brep_element("IfcColumn", "C", (0.0, 0.0, 0.0), [brep], container=storey),
        "mapped brep": g.brep_element(
            "IfcTransportElement", "Lift", (0.0, 0.0, 0.0), [brep], container=storey, mapped=True
        ),
        "surface model": _element_with(g, [surface], "SurfaceModel", storey),
        "closed tessellation": _element_with(g, [_faces(g, True)], "Tessellation", storey),
        "open tessellation": _element_with(g, [_faces(g, None)], "Tessellation", storey),
        "solid and surface": _element_with(g, [brep, surface], "SolidModel", storey),
        "no body": ifcopenshell.api.root.create_entity(f, ifc_class="IfcFurniture", name="Ghost"),
    }
    return g, elements


@pytest.mark.parametrize(
    ("name", "solid"),
    [
        ("extrusion", True),
        ("brep", True),
        ("mapped brep", True),
        ("surface model", False),
        ("closed tessellation", True),
        ("open tessellation", False),
        ("solid and surface", False),
        ("no body", False),
    ],
)
def test_a_body_is_solid_only_when_every_item_is_a_solid(
    model: tuple[Generated, dict[str, Any]], name: str, solid: bool
) -> None:
    _, elements = model
    assert BodyKind().is_solid(elements[name]) is solid
