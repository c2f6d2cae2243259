"""The box lab (two storeys) with a lift in Room B and the hall above, Door A a right-hand swing
door: a core test model."""

from __future__ import annotations

from dataclasses import replace

from tests.twin.box_lab import _boxes_geometry, box_lab
from twin.graph.ifc_classes import supertypes
from twin.records import BuildingModel, Element, Relation
from twin.samples.lab_plan import Box

LIFT = Box(19.0, 7.0, 0.0, 20.4, 8.4, 5.6)
"""A lift's car (the shaft's extent, both storeys) in Room B and the hall above, world metres."""


def lift_lab(*, lift_type: str = "ELEVATOR", door_operation: str = "SINGLE_SWING_RIGHT") -> BuildingModel:
    """The lab, its lift's ``IfcTransportElement`` of predefined type ``lift_type``, Door A's
    operation type ``door_operation``."""
    model = box_lab(storeys=2)
    lift = Element(
        guid="2LiftCar000000000000AA",
        ifc_class="IfcTransportElement",
        name="Lift 1",
        materials=("Steel",),
        is_static=True,
        geometry=_boxes_geometry((LIFT,)),
        ifc_types=supertypes("IFC4", "IfcTransportElement"),
        predefined_type=lift_type,
    )
    elements = tuple(
        replace(e, operation_type=door_operation) if e.name == "Door A" else e for e in model.elements
    )
    ground = model.storeys[0].guid
    return replace(
        model, elements=(*elements, lift), contained=model.contained | {Relation(ground, lift.guid)}
    )
