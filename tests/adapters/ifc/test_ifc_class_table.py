"""The core's IFC class table (twin/graph/ifc_classes.json) matches ifcopenshell's schemas."""

from __future__ import annotations

import ifcopenshell.ifcopenshell_wrapper as w
import pytest

from twin.graph.ifc_classes import element_classes, supertypes


@pytest.mark.parametrize(
    ("schema", "name"), [("IFC2X3", "IFC2X3"), ("IFC4", "IFC4"), ("IFC4X3", "IFC4X3_ADD2")]
)
def test_the_class_table_matches_the_schema(schema: str, name: str) -> None:
    decls = {d.name(): d for d in w.schema_by_name(name).declarations() if hasattr(d, "supertype")}
    expected = {}
    for cls, d in decls.items():
        chain, x = [], d
        while x is not None:
            chain.append(x.name())
            x = x.supertype()
        if "IfcElement" in chain:
            expected[cls] = tuple(chain)
    assert set(element_classes(schema)) == set(expected)
    for cls, chain in expected.items():
        assert supertypes(schema, cls) == chain
