"""Buildings without IfcSpace (halls, barns, scan-to-BIM) import and map; storeys are physical bands."""

from __future__ import annotations

from pathlib import Path

import pytest

from adapters.ifc import read_model
from adapters.ifc.read_model import BUILDING_WIDE_STOREY
from tests.adapters.generated import Generated
from tests.conftest import imported
from twin.config import Config
from twin.errors import MapError
from twin.graph.rdf import literal_value
from twin.graph.store import GraphStore
from twin.maps.grid import OCCUPIED, OccupancyGrid
from twin.maps.render import build_map, plan_map
from twin.maps.scene import Scene, load_scene
from twin.selection.skill_selection import selection_query
from twin.selection.skills import SkillProfile, parse_skill

COLUMNS = [(float(x), float(y)) for x in (0, 10) for y in (0, 8)]


def _hall(path: Path, *, with_storey: bool) -> Path:
    """A 10 m x 8 m hall: four columns, a curtain wall on one side, a roof at 6 m, a floor slab."""
    g = Generated("IFC4")
    container = g.storey("Hall floor", 0.0) if with_storey else g.building
    for i, (x, y) in enumerate(COLUMNS):
        g.box("IfcColumn", f"Column {i}", (x, y, 0.0), (0.4, 0.4, 6.0), container=container)
    curtain = g.box("IfcCurtainWall", "Curtain wall", (0.4, 0.0, 0.0), (9.6, 0.1, 6.0), container=container)
    g.single(curtain, "Glass")
    g.box("IfcRoof", "Roof", (0.0, 0.0, 6.0), (10.4, 8.4, 0.3), container=container)
    g.box("IfcSlab", "Floor", (0.0, 0.0, -0.3), (10.4, 8.4, 0.3), container=container)
    return g.write(path)


@pytest.fixture(scope="module", params=["in-a-storey", "in-the-building"])
def hall(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> tuple[str, GraphStore, Scene]:
    path = _hall(tmp_path_factory.mktemp("hall") / "hall.ifc", with_storey=request.param == "in-a-storey")
    store = imported(read_model(path))
    return request.param, store, load_scene(store)


def _map(store: GraphStore, scene: Scene, skill: SkillProfile) -> OccupancyGrid:
    iris = [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]
    return build_map(scene, plan_map(scene, skill, scene.storeys[0].key, iris))


def _cell(grid: OccupancyGrid, x: float, y: float) -> int:
    w = grid.frame.window_for(x, y, x + 1e-3, y + 1e-3)
    return int(grid.data[w.row0, w.col0])


def test_a_hall_without_spaces_imports_its_elements_storey_and_meshes(hall) -> None:
    kind, store, scene = hall
    n = store.select("SELECT (COUNT(?e) AS ?n) WHERE { ?e a bot:Element ; omg:hasGeometry ?g }")[0]["n"]
    assert int(literal_value(n) or 0) == len(COLUMNS) + 3
    assert not store.ask("ASK { ?s a bot:Space }")
    assert not store.ask("ASK { ?s bot:adjacentElement ?e }")
    assert len(scene.storeys) == 1
    if kind == "in-the-building":
        assert scene.storeys[0].name == BUILDING_WIDE_STOREY
        assert store.ask(
            "ASK { ?b a bot:Building ; bot:hasStorey ?s ; bot:containsElement ?e . ?e a beo:Column }"
        )
    else:
        assert store.ask("ASK { ?s a bot:Storey ; bot:containsElement ?e . ?e a beo:Column }")


def test_every_default_map_of_a_hall_shows_its_columns_and_not_its_roof(hall, config: Config) -> None:
    _, store, scene = hall
    for name in ("localization", "navigation", "lab-localization", "lab-navigation"):
        grid = _map(store, scene, config.skill(name))
        if name != "lab-localization":  # walls only: a hall has none
            assert all(_cell(grid, x + 0.2, y + 0.2) == OCCUPIED for x, y in COLUMNS), name
        assert _cell(grid, 5.0, 4.0) != OCCUPIED, f"{name}: the roof at 6 m is above every band"
    nav = _map(store, scene, config.skill("navigation"))
    loc = _map(store, scene, config.skill("localization"))
    assert _cell(nav, 5.0, 0.05) == OCCUPIED
    assert _cell(loc, 5.0, 0.05) != OCCUPIED, "the curtain wall faces glass: not in the lidar's map"


def test_unknown_outside_on_a_model_without_spaces_is_an_error_naming_why(hall) -> None:
    _, store, scene = hall
    skill = parse_skill("u", {"kind": "navigation", "unknown_outside": True})
    with pytest.raises(MapError, match="'u' sets unknown_outside, but this model has no spaces"):
        _map(store, scene, skill)


def test_a_wall_assigned_to_one_storey_but_standing_through_the_next_is_in_the_next_storeys_maps(
    tmp_path: Path, config: Config
) -> None:
    g = Generated("IFC4")
    ground, upper = g.storey("Ground", 0.0), g.storey("Upper", 3.0)
    g.box("IfcWall", "Tall wall", (0.0, 0.0, 0.0), (4.0, 0.3, 6.0), container=ground)
    g.box("IfcWall", "Short wall", (0.0, 3.0, 0.0), (4.0, 0.3, 2.5), container=ground)
    g.box("IfcSlab", "Upper floor", (0.0, 0.0, 2.8), (4.0, 4.0, 0.2), container=upper)
    store = imported(read_model(g.write(tmp_path / "tall.ifc")))
    scene = load_scene(store)
    key = next(s.key for s in scene.storeys if s.name == "Upper")
    for name in ("localization", "navigation"):
        skill = config.skill(name)
        iris = [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]
        grid = build_map(scene, plan_map(scene, skill, key, iris))
        assert _cell(grid, 2.0, 0.15) == OCCUPIED, f"{name}: the tall wall is in the upper band"
        assert _cell(grid, 2.0, 3.15) != OCCUPIED, f"{name}: the short wall ends below the upper band"
