"""Route graph files: `twin map --skill <routes skill>` on a generated two-storey lab with a lift,
read back the way Open-RMF's fleet adapter and nav2's route server read them."""

from __future__ import annotations

import math
from pathlib import Path

import ifcopenshell
import ifcopenshell.api.geometry
import ifcopenshell.api.root
import ifcopenshell.api.spatial
import numpy as np
import pytest
from ifcopenshell.util.shape_builder import ShapeBuilder

from adapters.cli.app import main
from adapters.ifc.sample_lab import build_lab
from adapters.ros.routes import MAX_GEOJSON_ID, nav_graph, route_geojson
from adapters.ros.settings import LevelConfig
from tests.adapters.ros.route_readers import read_nav2_geojson, read_rmf_nav_graph
from twin.errors import RouteError, TwinError
from twin.routes.graph import Lift, RouteGraph, RouteLane, RouteVertex, StoreyRoutes
from twin.samples.lab_plan import GROUND_FLOOR

LIFT_BOX = (19.0, 7.0, 20.4, 8.4, 5.6)
"""The lift's car and shaft: x, y from/to (world, metres) and height from the ground floor."""

CONFIG = """
[site]
name = "lab"
[skills.nav25]
kind = "navigation"
robot_height_m = 0.5
inflation_radius_m = 0.25
exclude_types = ["IfcOpeningElement"]
[skills.nav45]
kind = "navigation"
robot_height_m = 0.5
inflation_radius_m = 0.45
exclude_types = ["IfcOpeningElement"]
[skills.small]
kind = "routes"
navigation = "nav25"
speed_m_s = 0.6
waypoints.charger = { storey = "first-floor", x = 13.0, y = 7.0, charger = true, dock = "charger_dock" }
[skills.big]
kind = "routes"
navigation = "nav45"
open_door_operations = true
[ros]
frame_id = "lab_map"
[sources.doors]
kind = "rmf_doors"
doors = { main_door = "Door A" }
levels.L1 = { storey = "ground-floor", x = 10.0, y = 5.0 }
levels.L2 = { storey = "first-floor", x = 10.0, y = 5.0 }
"""


def write_lab_with_lift(path: Path) -> None:
    """The two-storey sample lab and a lift (``IfcTransportElement``, ELEVATOR) in Room B and the
    hall above: its car and shaft one extruded solid through both storeys."""
    model, _ = build_lab(storeys=2)
    ground = next(s for s in model.by_type("IfcBuildingStorey") if s.Name == GROUND_FLOOR.name)
    lift = ifcopenshell.api.root.create_entity(
        model, ifc_class="IfcTransportElement", predefined_type="ELEVATOR", name="Lift 1"
    )
    x0, y0, x1, y1, height = LIFT_BOX
    matrix = np.eye(4)
    matrix[:3, 3] = (x0, y0, 0.0)
    ifcopenshell.api.geometry.edit_object_placement(model, product=lift, matrix=matrix, is_si=True)
    shapes = ShapeBuilder(model)
    body = next(
        c for c in model.by_type("IfcGeometricRepresentationSubContext") if c.ContextIdentifier == "Body"
    )
    solid = shapes.extrude(shapes.profile(shapes.rectangle(size=(x1 - x0, y1 - y0))), magnitude=height)
    ifcopenshell.api.geometry.assign_representation(
        model, product=lift, representation=shapes.get_representation(body, [solid])
    )
    ifcopenshell.api.spatial.assign_container(model, products=[lift], relating_structure=ground)
    model.write(str(path))


@pytest.fixture(scope="module")
def route_files(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("routes")
    write_lab_with_lift(root / "lab.ifc")
    (root / "site.toml").write_text(CONFIG)
    cfg = str(root / "site.toml")
    assert main(["--config", cfg, "import", str(root / "lab.ifc"), "--store", str(root / "store")]) == 0
    out = root / "out"
    code = main(
        [
            "--config",
            cfg,
            "map",
            "--skill",
            "small",
            "--skill",
            "big",
            "--store",
            str(root / "store"),
            "--out",
            str(out),
        ]
    )
    assert code == 0
    return out


def test_map_writes_a_nav_graph_and_a_geojson_per_storey_for_each_routes_skill(route_files: Path) -> None:
    names = sorted(p.name for p in route_files.iterdir())
    assert names == [
        "big.nav_graph.yaml",
        "first-floor__big.geojson",
        "first-floor__small.geojson",
        "ground-floor__big.geojson",
        "ground-floor__small.geojson",
        "small.nav_graph.yaml",
    ]


def test_the_fleet_adapters_reader_takes_the_nav_graph_with_its_levels_lift_and_door(
    route_files: Path,
) -> None:
    graph = read_rmf_nav_graph(route_files / "small.nav_graph.yaml")
    assert set(graph.lifts) == {"Lift_1"}
    assert graph.doors["main_door"][2] == "L1"
    assert {wp.map_name for wp in graph.waypoints} == {"L1", "L2"}
    lift_stops = [wp for wp in graph.waypoints if wp.lift == "Lift_1"]
    assert sorted(wp.map_name for wp in lift_stops) == ["L1", "L2"]
    assert {"L1_Room_A", "L1_Room_B", "L1_Corridor", "L2_Hall", "L1_Lift_1", "L2_Lift_1", "charger"} <= set(
        graph.keys
    )
    # lanes are directed: every lane has its reverse; door lanes open and close the door
    pairs = {(lane.begin, lane.end) for lane in graph.lanes}
    assert all((b, a) in pairs for a, b in pairs)
    door_lanes = [lane for lane in graph.lanes if "DoorOpen:main_door" in lane.entry]
    assert len(door_lanes) == 2 and all(lane.exit == ("DoorClose:main_door",) for lane in door_lanes)
    assert any(e.startswith("LiftSessionBegin:Lift_1") for lane in graph.lanes for e in lane.entry)
    assert any(e.startswith("LiftMove:Lift_1") for lane in graph.lanes for e in lane.entry)
    assert {
        lane.speed_limit for lane in graph.lanes if not lane.entry or "LiftMove" not in lane.entry[0]
    } == {0.6}
    charger = graph.waypoints[graph.keys["charger"]]
    assert charger.charger and charger.map_name == "L2"
    assert any(
        "Dock:charger_dock" in lane.entry and lane.end == graph.keys["charger"] for lane in graph.lanes
    )


def test_the_nav_graph_is_in_each_levels_frame(route_files: Path) -> None:
    graph = read_rmf_nav_graph(route_files / "small.nav_graph.yaml")
    lift = graph.lifts["Lift_1"]  # the twin's (19.7, 7.7) in the levels' frame, 10 m and 5 m off
    assert (lift[0], lift[1], lift[3], lift[4]) == pytest.approx((9.7, 2.7, 1.4, 1.4))
    for key in ("L1_Lift_1", "L2_Lift_1"):
        assert (graph.waypoints[graph.keys[key]].x, graph.waypoints[graph.keys[key]].y) == pytest.approx(
            (9.7, 2.7)
        )
    assert graph.doors["main_door"][:2] == ((1.55, -0.1), (2.45, -0.1))


def test_levels_placed_so_that_a_lift_misaligns_are_refused() -> None:
    lift = Lift("Lift_1", "urn:lift", 1.0, 1.0, 0.0, 1.0, 1.0, ("g", "f"))
    storeys = tuple(
        StoreyRoutes(k, 0.0, (RouteVertex(1.0, 1.0, lift="Lift_1", kind="lift"),), ()) for k in ("g", "f")
    )
    graph = RouteGraph("s", "f", "s", "b", 0.5, 0.2, storeys, lifts=(lift,))
    levels = {"g": ("L1", LevelConfig("g")), "f": ("L2", LevelConfig("f", yaw_rad=math.pi / 2))}
    with pytest.raises(RouteError, match=r"lift 'Lift_1' lies 2.00 m apart in the frames of levels L1, L2"):
        nav_graph(graph, levels)


def test_the_route_servers_reader_takes_each_storeys_geojson(route_files: Path) -> None:
    for path in sorted(route_files.glob("*__small.geojson")):
        g = read_nav2_geojson(path)
        ids = [*g.nodes, *g.edges]
        assert len(ids) == len(set(ids)) and max(ids) <= MAX_GEOJSON_ID
        assert {frame for _, _, frame, _ in g.nodes.values()} == {"lab_map"}
        pairs = {(s, e) for s, e, _, _, _ in g.edges.values()}
        assert all((e, s) in pairs for s, e in pairs)
        for start, end, cost, meta, operations in g.edges.values():
            (x0, y0, _, _), (x1, y1, _, _) = g.nodes[start], g.nodes[end]
            assert cost == pytest.approx(math.hypot(x1 - x0, y1 - y0), abs=1e-5)
            assert isinstance(meta["speed_limit"], float) and meta["abs_speed_limit"] == 0.6
            assert operations == []
    ground = read_nav2_geojson(route_files / "ground-floor__small.geojson")
    assert sum(meta.get("door") == "main_door" for _, _, _, meta, _ in ground.edges.values()) == 2


def test_a_robot_too_wide_for_door_a_has_no_door_lane_in_either_file(route_files: Path) -> None:
    graph = read_rmf_nav_graph(route_files / "big.nav_graph.yaml")
    assert not any(e.startswith("DoorOpen") for lane in graph.lanes for e in lane.entry)
    assert "main_door" in graph.doors  # RMF still knows the door
    ground = read_nav2_geojson(route_files / "ground-floor__big.geojson")
    assert not any("door" in meta or ops for _, _, _, meta, ops in ground.edges.values())


def test_door_edges_carry_open_door_operations_only_when_configured() -> None:
    v = (RouteVertex(0.0, 0.0), RouteVertex(1.0, 0.0))
    storey = StoreyRoutes("g", 0.0, v, (RouteLane(0, 1, "d1"),))
    graph = RouteGraph("s", "f", "s", "b", 0.5, 0.2, (storey,))
    plain = route_geojson(graph, storey)
    with_ops = route_geojson(graph, storey, open_door_operations=True)
    assert all("operations" not in f["properties"] for f in plain["features"])
    ops = [
        f["properties"]["operations"]["open_door"]
        for f in with_ops["features"]
        if "startid" in f["properties"]
    ]
    assert ops == [{"type": "open_door", "trigger": "ON_ENTER", "metadata": {"door_id": "d1"}}] * 2


def test_a_graph_too_big_for_nav2s_ids_is_refused() -> None:
    n = MAX_GEOJSON_ID // 2
    vertices = tuple(RouteVertex(float(i), 0.0) for i in range(n))
    storey = StoreyRoutes("g", 0.0, vertices, tuple(RouteLane(i, i + 1) for i in range(n - 1)))
    graph = RouteGraph("s", "f", "s", "b", 0.5, 0.2, (storey,))
    with pytest.raises(RouteError, match=r"ids beyond nav2's 65535"):
        route_geojson(graph, storey)


def test_a_routes_skill_that_cannot_make_a_graph_is_a_one_line_error(
    route_files: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "wide.toml"
    config.write_text(
        CONFIG + '[skills.wide]\nkind = "navigation"\nrobot_height_m = 0.5\ninflation_radius_m = 0.6\n'
        '[skills.huge]\nkind = "routes"\nnavigation = "wide"\n'
    )
    store = route_files.parent / "store"
    code = main(
        ["--config", str(config), "map", "--skill", "huge", "--store", str(store), "--out", str(tmp_path)]
    )
    err = capsys.readouterr().err
    assert code != 0
    assert "fits through none of the model's 1 doors" in err and "Traceback" not in err
    assert issubclass(RouteError, TwinError)
