"""The materials found for every element in one pass over the file equal what
``ifcopenshell.util.element.get_material`` finds element by element, awkward files included."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import ifcopenshell
import ifcopenshell.api.classification
import ifcopenshell.api.material
import ifcopenshell.api.root
import ifcopenshell.api.type
import pytest

from adapters.ifc.materials import Materials, facing_material_names, material_names
from tests.adapters.generated import Generated
from tests.conftest import SHARED_MODELS, shared_model


def _outcome(read: Callable[[], Any]) -> tuple[str, Any]:
    try:
        return "value", read()
    except Exception as err:  # the error is the outcome compared
        return type(err).__name__, str(err)


def _assert_same_as_get_material(f: Any) -> int:
    materials = Materials(f)
    elements = f.by_type("IfcElement")
    for e in elements:
        fast = _outcome(lambda e=e: materials.names_of(e))
        slow = _outcome(lambda e=e: (material_names(e), facing_material_names(e)))
        assert fast == slow, (e, fast, slow)
    return len(elements)


def _awkward(schema: str) -> Any:
    g = Generated(schema)
    f = g.file
    storey = g.storey("Ground", 0.0)
    at = iter(range(1000))

    def element(name: str, ifc_class: str = "IfcWall") -> Any:
        return g.box(ifc_class, name, (float(next(at)), 0.0, 0.0), (0.5, 0.3, 2.0), container=storey)

    def wall_type(names: list[str], name: str = "T") -> Any:
        t = ifcopenshell.api.root.create_entity(f, ifc_class="IfcWallType", name=name)
        ifcopenshell.api.material.assign_material(
            f, products=[t], type="IfcMaterialLayerSet", material=g.layer_set(names)
        )
        return t

    def typed(e: Any, t: Any) -> None:
        ifcopenshell.api.type.assign_type(f, related_objects=[e], relating_type=t)

    element("nothing")
    g.single(element("single"), "Concrete")
    g.layers(element("layer set usage"), ["Brick", "Insulation", "Brick"])
    g.material_list(element("list", "IfcWindow"), ["Glass", "Frame"])
    if schema != "IFC2X3":
        g.constituents(element("constituents", "IfcWindow"), ["Glass", "Frame"])
    shared = wall_type(["Stone", "Render"])
    for name in ("typed a", "typed b"):
        typed(element(name), shared)
    own_and_typed = element("own and typed")
    typed(own_and_typed, wall_type(["Timber"]))  # the API gives it a usage of the type's set
    f.createIfcRelAssociatesMaterial(
        ifcopenshell.guid.new(), None, None, None, [element("own only")], g.material("Steel")
    )
    # Two material associations on one element: the first one (in the file's order) counts.
    twice = element("two associations")
    for name in ("Copper", "Zinc"):
        f.createIfcRelAssociatesMaterial(ifcopenshell.guid.new(), None, None, None, [twice], g.material(name))
    # An element typed by two types, a type with two associations, a type with none.
    two_types = element("two types")
    for t in (wall_type(["Lead"]), wall_type(["Tin"])):
        f.createIfcRelDefinesByType(ifcopenshell.guid.new(), None, None, None, [two_types], t)
    busy_type = wall_type(["Iron"])
    f.createIfcRelAssociatesMaterial(
        ifcopenshell.guid.new(), None, None, None, [busy_type], g.material("Gold")
    )
    typed(element("type with two associations"), busy_type)
    bare_type = ifcopenshell.api.root.create_entity(f, ifc_class="IfcWallType", name="bare")
    typed(element("type without material"), bare_type)
    # A type that has an association, but no material one.
    system = ifcopenshell.api.classification.add_classification(f, classification="Uniclass")
    classified = ifcopenshell.api.root.create_entity(f, ifc_class="IfcWallType", name="classified")
    ifcopenshell.api.classification.add_reference(
        f, products=[classified], identification="X", name="x", classification=system
    )
    typed(element("type with a classification only"), classified)
    # One layer of a set assigned directly, and an association whose material is missing.
    layer = g.layer_set(["Glass", "Air"]).MaterialLayers[0]
    f.createIfcRelAssociatesMaterial(ifcopenshell.guid.new(), None, None, None, [element("one layer")], layer)
    dangling = f.createIfcRelAssociatesMaterial(
        ifcopenshell.guid.new(), None, None, None, [element("missing material")], g.material("Ghost")
    )
    dangling.RelatingMaterial = None
    return f


@pytest.mark.parametrize("schema", ["IFC2X3", "IFC4"])
def test_materials_in_one_pass_equal_get_material_element_by_element(schema: str) -> None:
    f = _awkward(schema)
    assert _assert_same_as_get_material(f) >= 14
    names = {
        e.Name: Materials(f).names_of(e) for e in f.by_type("IfcElement") if e.Name != "missing material"
    }
    assert names["typed b"] == (("Stone", "Render"), ("Stone", "Render"))
    assert names["own and typed"] == (("Timber",), ("Timber",))
    assert names["own only"] == (("Steel",), ("Steel",))
    assert names["layer set usage"] == (("Brick", "Insulation"), ("Brick",))
    assert names["type without material"] == ((), ())


def test_an_association_without_a_material_raises_what_get_material_raises() -> None:
    f = _awkward("IFC4")
    e = next(e for e in f.by_type("IfcElement") if e.Name == "missing material")
    with pytest.raises(AttributeError, match="NoneType"):
        Materials(f).names_of(e)


@pytest.mark.slow
@pytest.mark.parametrize("name", SHARED_MODELS)
def test_materials_in_one_pass_equal_get_material_on_the_shared_models(name: str) -> None:
    assert _assert_same_as_get_material(ifcopenshell.open(str(shared_model(name)))) > 0
