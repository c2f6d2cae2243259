""" "Made of glass": judged by words on the materials a sensor faces, on generated IFC2X3 and IFC4 models."""

from __future__ import annotations

from pathlib import Path

import pytest

from adapters.ifc import read_model
from adapters.ifc.materials import facing_material_names, material_names
from tests.adapters.generated import Generated
from tests.conftest import imported
from twin.graph.rdf import literal_value
from twin.graph.store import GraphStore
from twin.maps.grid import OCCUPIED
from twin.maps.render import build_map, plan_map
from twin.maps.scene import load_scene
from twin.selection.skill_selection import selection_query
from twin.selection.skills import parse_skill

KEPT = {"brick-fiberglass-plaster", "brick-glasswool-brick", "typed-brick-fiberglass", "glass-in-the-middle"}
GONE = {"glass-outer-layer", "glass-inner-face", "glass-plate", "window", "listed-window", "typed-glass"}


def _write(path: Path, schema: str) -> Path:
    g = Generated(schema)
    storey = g.storey("Ground", 0.0)
    walls = {}
    for i, name in enumerate(sorted(KEPT | GONE)):
        cls = {"glass-plate": "IfcPlate", "window": "IfcWindow", "listed-window": "IfcWindow"}.get(
            name, "IfcWall"
        )
        walls[name] = g.box(cls, name, (float(i) * 2.0, 0.0, 0.0), (1.5, 0.3, 2.5), container=storey)
    g.layers(walls["brick-fiberglass-plaster"], ["Brick", "Fiberglass Batt", "Plaster"])
    g.layers(walls["brick-glasswool-brick"], ["Brick", "Glass wool", "Brick"])
    g.layers(walls["glass-in-the-middle"], ["Plaster", "Glass", "Concrete"])
    g.layers(walls["glass-outer-layer"], ["Glass - Clear", "Concrete"])
    g.layers(walls["glass-inner-face"], ["Concrete", "Insulation", "glazing_glass"])
    g.single(walls["glass-plate"], "Glass")
    if schema == "IFC2X3":  # no constituent sets in IFC2X3: a material list
        g.material_list(walls["window"], ["Glass", "Aluminium frame"])
    else:
        g.constituents(walls["window"], ["Glass", "Aluminium frame"])
    g.material_list(walls["listed-window"], ["Timber", "GLASS"])
    g.typed_layers(walls["typed-glass"], "IfcWallType", ["Glass", "Steel"])
    g.typed_layers(walls["typed-brick-fiberglass"], "IfcWallType", ["Brick", "Fiberglass", "Brick"])
    return g.write(path / f"materials-{schema}.ifc")


@pytest.fixture(scope="module", params=["IFC2X3", "IFC4"])
def material_model(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> tuple[Path, GraphStore]:
    path = _write(tmp_path_factory.mktemp("materials"), request.param)
    return path, imported(read_model(path))


def _names(store: GraphStore, sparql: str) -> set[str]:
    return {literal_value(r["n"]) or "" for r in store.select(sparql)}


def test_only_elements_facing_glass_are_excluded_and_insulation_inside_is_not(material_model) -> None:
    _, store = material_model
    skill = parse_skill("lidar", {"kind": "localization", "exclude_materials": ["glass"]})
    rows = store.select(f"SELECT ?n WHERE {{ {{ {selection_query(skill)} }} ?element rdfs:label ?n }}")
    assert {literal_value(r["n"]) for r in rows} == KEPT


def test_every_material_stays_in_the_graph_and_the_facing_ones_are_marked(material_model) -> None:
    _, store = material_model
    label = "brick-fiberglass-plaster"
    every = _names(store, f'SELECT ?n WHERE {{ ?e rdfs:label "{label}" ; twin:material ?n }}')
    facing = _names(store, f'SELECT ?n WHERE {{ ?e rdfs:label "{label}" ; twin:facingMaterial ?n }}')
    assert every == {"Brick", "Fiberglass Batt", "Plaster"}
    assert facing == {"Brick", "Plaster"}
    typed = _names(store, 'SELECT ?n WHERE { ?e rdfs:label "typed-glass" ; twin:facingMaterial ?n }')
    assert typed == {"Glass", "Steel"}


def test_a_brick_wall_with_fiberglass_inside_stays_in_the_localization_map(material_model) -> None:
    _, store = material_model
    skill = parse_skill(
        "lidar", {"kind": "localization", "lidar_height_m": 1.0, "exclude_materials": ["glass"]}
    )
    scene = load_scene(store)
    iris = [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]
    grid = build_map(scene, plan_map(scene, skill, scene.storeys[0].key, iris))
    order = sorted(KEPT | GONE)
    for name in ("brick-fiberglass-plaster", "glass-plate"):
        x = order.index(name) * 2.0 + 0.75  # centre of the element
        w = grid.frame.window_for(x - 0.1, 0.1, x + 0.1, 0.2)
        cells = grid.data[w.row0 : w.row1, w.col0 : w.col1]
        assert (cells == OCCUPIED).all() == (name in KEPT), name


@pytest.mark.parametrize("word", ["Glass", "glass", "GLASS"])
def test_material_words_are_matched_case_insensitively(material_model, word: str) -> None:
    _, store = material_model
    skill = parse_skill("x", {"kind": "navigation", "exclude_materials": [word]})
    got = {literal_value(r["element"]) for r in store.select(selection_query(skill))}
    assert len(got) == len(KEPT)


def test_facing_materials_of_a_layer_set_are_its_first_and_last_layer(tmp_path: Path) -> None:
    g = Generated("IFC4")
    storey = g.storey("Ground", 0.0)
    wall = g.box("IfcWall", "w", (0.0, 0.0, 0.0), (2.0, 0.3, 2.0), container=storey)
    g.layers(wall, ["Stone", "Air", "Fiberglass Batt", "Render"])
    assert material_names(wall) == ("Stone", "Air", "Fiberglass Batt", "Render")
    assert facing_material_names(wall) == ("Stone", "Render")
