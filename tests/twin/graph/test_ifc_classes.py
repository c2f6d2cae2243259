"""The IFC class table the core uses for observed elements (no ifcopenshell needed)."""

from __future__ import annotations

from twin.graph.ifc_classes import element_classes, schema_family, supertypes


def test_observed_classes_get_their_supertypes_like_imported_ones() -> None:
    chain = supertypes("IFC4", "IfcFurniture")
    assert chain is not None
    assert chain[:2] == ("IfcFurniture", "IfcFurnishingElement")
    assert "IfcElement" in chain


def test_a_class_of_a_newer_schema_is_accepted_in_an_older_building() -> None:
    assert "IfcFurniture" not in element_classes("IFC2X3")
    assert supertypes("IFC2X3", "IfcFurniture") == supertypes("IFC4X3", "IfcFurniture")
    assert supertypes("IFC2X3", "ifcwallstandardcase") == supertypes("IFC2X3", "IfcWallStandardCase")


def test_non_element_classes_are_unknown() -> None:
    assert supertypes("IFC4", "IfcSpace") is None
    assert supertypes("IFC4", "IfcSpaceship") is None
    assert schema_family("IFC4X3_ADD2") == "IFC4X3"
