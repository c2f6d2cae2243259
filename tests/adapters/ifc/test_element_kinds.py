"""Predefined and operation types read from IFC: what tells a lift from an escalator and a sliding
door from a swing door, on the element or its type object, in IFC4 and IFC2X3."""

from __future__ import annotations

from pathlib import Path

import ifcopenshell.api.geometry
import ifcopenshell.api.root
import ifcopenshell.api.type
import numpy as np
import pytest

from adapters.ifc import read_model
from tests.adapters.generated import Generated
from tests.conftest import imported
from twin.graph.rdf import literal_value
from twin.maps.scene import load_scene
from twin.routes.build import _door_shapes, _elements


def _typed(g: Generated, element: object, type_class: str, **attributes: str) -> None:
    element_type = ifcopenshell.api.root.create_entity(
        g.file, ifc_class=type_class, name=f"{type_class} type"
    )
    for key, value in attributes.items():
        setattr(element_type, key, value)
    ifcopenshell.api.type.assign_type(g.file, related_objects=[element], relating_type=element_type)


def test_ifc4_lifts_escalators_doors_and_slabs_keep_their_kinds(tmp_path: Path) -> None:
    g = Generated("IFC4")
    st = g.storey("Ground", 0.0)
    g.box("IfcTransportElement", "Lift", (0, 0, 0), (2, 2, 6), container=st).PredefinedType = "ELEVATOR"
    g.box("IfcTransportElement", "Escalator", (3, 0, 0), (1, 4, 3), container=st).PredefinedType = "ESCALATOR"
    typed_lift = g.box("IfcTransportElement", "Typed lift", (6, 0, 0), (2, 2, 6), container=st)
    _typed(g, typed_lift, "IfcTransportElementType", PredefinedType="ELEVATOR")
    door = g.box("IfcDoor", "Slider", (0, 5, 0), (1.8, 0.05, 2.1), container=st)
    door.OperationType = "DOUBLE_DOOR_SLIDING"
    typed_door = g.box("IfcDoor", "Typed door", (3, 5, 0), (0.9, 0.05, 2.1), container=st)
    _typed(g, typed_door, "IfcDoorType", PredefinedType="DOOR", OperationType="SINGLE_SWING_LEFT")
    g.box("IfcDoor", "Plain door", (5, 5, 0), (0.9, 0.05, 2.1), container=st)
    g.box("IfcSlab", "Roof", (0, 0, 3), (9, 6, 0.2), container=st).PredefinedType = "ROOF"
    g.box("IfcWall", "Wall", (0, 6, 0), (9, 0.2, 3), container=st)
    model = read_model(g.write(tmp_path / "kinds.ifc"))
    kinds = {e.name: (e.predefined_type, e.operation_type) for e in model.elements}
    assert kinds == {
        "Lift": ("ELEVATOR", ""),
        "Escalator": ("ESCALATOR", ""),
        "Typed lift": ("ELEVATOR", ""),
        "Slider": ("", "DOUBLE_DOOR_SLIDING"),
        "Typed door": ("DOOR", "SINGLE_SWING_LEFT"),
        "Plain door": ("", ""),
        "Roof": ("ROOF", ""),
        "Wall": ("", ""),  # other classes: not read
    }
    rows = imported(model).select(
        "SELECT ?name ?p ?o WHERE { ?e rdfs:label ?name . "
        "{ ?e twin:predefinedType ?o BIND('p' AS ?p) } UNION { ?e twin:operationType ?o BIND('o' AS ?p) } }"
    )
    triples = {(literal_value(r["name"]), literal_value(r["p"]), literal_value(r["o"])) for r in rows}
    assert ("Escalator", "p", "ESCALATOR") in triples and ("Slider", "o", "DOUBLE_DOOR_SLIDING") in triples
    assert not any(name in ("Plain door", "Wall") for name, _, _ in triples)


def test_ifc2x3_takes_a_lifts_kind_from_operation_type_and_a_doors_from_its_style(tmp_path: Path) -> None:
    g = Generated("IFC2X3")
    st = g.storey("Ground", 0.0)
    g.box("IfcTransportElement", "Lift", (0, 0, 0), (2, 2, 6), container=st).OperationType = "ELEVATOR"
    door = g.box("IfcDoor", "Door", (0, 5, 0), (0.9, 0.05, 2.1), container=st)
    _typed(g, door, "IfcDoorStyle", OperationType="SLIDING_TO_RIGHT", ConstructionType="WOOD")
    model = read_model(g.write(tmp_path / "kinds2x3.ifc"))
    kinds = {e.name: (e.predefined_type, e.operation_type) for e in model.elements}
    assert kinds == {"Lift": ("ELEVATOR", ""), "Door": ("", "SLIDING_TO_RIGHT")}


def test_a_left_hand_doors_hinge_and_swing_are_read_in_its_placement(tmp_path: Path) -> None:
    g = Generated("IFC4")
    st = g.storey("Ground", 0.0)
    door = g.box("IfcDoor", "Door", (0, 0, 0), (0.9, 0.05, 2.1), container=st)
    door.OperationType = "SINGLE_SWING_LEFT"
    matrix = np.eye(4)
    matrix[:3, 0], matrix[:3, 1], matrix[:3, 3] = (0, 1, 0), (-1, 0, 0), (5, 5, 0)  # local x: world +y
    ifcopenshell.api.geometry.edit_object_placement(g.file, product=door, matrix=matrix, is_si=True)
    store = imported(read_model(g.write(tmp_path / "door.ifc")))
    ((_, shape),) = _door_shapes(load_scene(store), _elements(store, "IfcDoor"), {})
    # hinged at its local -x end (world y 5.0), opening towards local +y (world -x): anticlockwise
    assert np.array(shape.endpoints) == pytest.approx(np.array([[4.975, 5.0], [4.975, 5.9]]))
    assert (shape.operation, shape.swing) == ("SINGLE_SWING_LEFT", -1)
