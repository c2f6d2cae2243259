"""Reading attributes by a remembered index gives what ``getattr`` gives, errors included; the router
and the body kind read representations once between them and answer as each did alone."""

from __future__ import annotations

from typing import Any

import pytest

from adapters.ifc.attributes import Attributes, Representations
from adapters.ifc.body_kind import BodyKind
from adapters.ifc.kernel_choice import KernelChoice
from tests.adapters.generated import Generated


@pytest.fixture(scope="module")
def generated() -> tuple[Generated, Any]:
    g = Generated("IFC4")
    storey = g.storey("Ground", 0.0)
    wall = g.box("IfcWall", "W", (0.0, 0.0, 0.0), (4.0, 0.3, 3.0), container=storey)
    g.layers(wall, ["Brick", "Plaster"])
    return g, wall


def _outcome(read: Any) -> tuple[str, Any]:
    try:
        return "value", read()
    except Exception as err:  # the error is the outcome compared
        return type(err).__name__, str(err)


@pytest.mark.parametrize(
    "name", ["GlobalId", "Name", "Representation", "ObjectPlacement", "HasAssociations", "NoSuchAttribute"]
)
def test_a_read_gives_what_getattr_gives(generated: tuple[Generated, Any], name: str) -> None:
    _, wall = generated
    attributes = Attributes()
    for _ in range(2):  # the first read finds the index, the second uses it
        assert _outcome(lambda: attributes.get(wall, name)) == _outcome(lambda: getattr(wall, name))
        assert attributes.get_or_none(wall, name) == getattr(wall, name, None)


def test_a_derived_attribute_and_a_missing_entity_read_as_getattr_reads_them(
    generated: tuple[Generated, Any],
) -> None:
    g, _ = generated
    unit = g.file.by_type("IfcSIUnit")[0]
    attributes = Attributes()
    assert tuple(attributes.get(unit, "Dimensions")) == tuple(unit.Dimensions)  # derived: from the rules
    assert _outcome(lambda: attributes.get(None, "Items")) == _outcome(lambda: None.Items)  # type: ignore[attr-defined]
    assert attributes.get_or_none(None, "Items") is None


def _profile_element(g: Generated, storey: Any, profile: Any) -> Any:
    wall = g.box("IfcMember", "profiled", (0.0, 0.0, 0.0), (1.0, 1.0, 1.0), container=storey)
    wall.Representation.Representations[0].Items[0].SweptArea = profile
    return wall


def test_a_profile_with_a_fillet_is_routed_and_one_without_is_not() -> None:
    g = Generated("IFC4")
    storey = g.storey("Ground", 0.0)
    f = g.file

    def i_shape(fillet: float | None) -> Any:
        return f.createIfcIShapeProfileDef("AREA", None, None, 0.2, 0.3, 0.01, 0.015, fillet)

    filleted = _profile_element(g, storey, i_shape(0.01))
    sharp = _profile_element(g, storey, i_shape(None))
    zero = _profile_element(g, storey, i_shape(0.0))
    round_bar = _profile_element(g, storey, f.createIfcCircleProfileDef("AREA", None, None, 0.1))
    router = KernelChoice()
    assert router.reason(filleted) == "curved profile"
    assert router.reason(sharp) is None
    assert router.reason(zero) is None
    assert router.reason(round_bar) == "curved profile"


def test_routing_and_body_kind_sharing_what_they_read_answer_as_each_alone() -> None:
    g = Generated("IFC4")
    storey = g.storey("Ground", 0.0)
    f = g.file
    brep = g.faceted_brep([[(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]])
    products = [
        g.box("IfcWall", "W", (0.0, 0.0, 0.0), (1.0, 1.0, 1.0), container=storey),
        g.brep_element("IfcColumn", "C", (0.0, 0.0, 0.0), [brep], container=storey),
        g.brep_element("IfcTransportElement", "L", (0.0, 0.0, 0.0), [brep], container=storey, mapped=True),
    ]
    broken = g.box("IfcSlab", "S", (0.0, 0.0, 0.0), (1.0, 1.0, 1.0), container=storey)
    broken.Representation.Representations[0].Items = [f.createIfcCartesianPoint((0.0, 0.0, 0.0))]
    products.append(broken)
    shared = Representations()
    router, kind = KernelChoice(shared), BodyKind(shared)
    for p in products:
        assert _outcome(lambda p=p: router.reason(p)) == _outcome(lambda p=p: KernelChoice().reason(p))
        assert _outcome(lambda p=p: kind.is_solid(p)) == _outcome(lambda p=p: BodyKind().is_solid(p))
    assert kind.is_solid(products[2]) is True
    assert kind.is_solid(broken) is False
