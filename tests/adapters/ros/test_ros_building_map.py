"""Open-RMF's BuildingMap of the route graphs: its bytes decode field by field with the registered
(rosidl-checked) types, and ``/map`` is latched on both ROS 2 layouts for late joiners."""

from __future__ import annotations

import math
import threading
from dataclasses import replace
from pathlib import Path

import pytest
import zenoh

from adapters.ros.building_map import (
    DOOR_MOTION_RANGE_DEG,
    decode_building_map,
    door_type,
    encode_building_map,
)
from adapters.ros.building_map_msgs import BUILDING_MAP
from adapters.ros.rmw_zenoh import RosTopic, parse_attachment
from adapters.ros.settings import LevelConfig, ros_robots
from adapters.zenoh.latched import declare_latched_subscriber
from adapters.zenoh.ros_building_map import RosBuildingMap
from adapters.zenoh.session import client_config, session_config
from adapters.zenoh.settings import ZenohSettings
from tests.conftest import imported
from tests.integration.conftest import free_port
from tests.twin.routes.lift_lab import lift_lab
from twin.config import load_config
from twin.config.routes import parse_routes
from twin.errors import ConfigError
from twin.graph.rdf import literal_value
from twin.maps.grid import OccupancyGrid
from twin.maps.render import build_map, plan_map
from twin.maps.scene import load_scene
from twin.routes.build import build_routes
from twin.routes.graph import RouteGraph
from twin.selection.skill_selection import selection_query

LEVELS = {
    "ground-floor": ("L1", LevelConfig("ground-floor", 10.0, 5.0)),
    "first-floor": ("L2", LevelConfig("first-floor", 10.0, 5.0)),
}


@pytest.fixture(scope="module")
def building() -> tuple[list[RouteGraph], dict[str, OccupancyGrid]]:
    cfg = load_config()
    store = imported(lift_lab())
    scene = load_scene(store)
    nav = replace(cfg.skills["lab-navigation"], name="nav", inflation_radius_m=0.25)
    skills = {**cfg.skills, "nav": nav}
    graphs = [
        build_routes(
            store, scene, parse_routes(name, {"kind": "routes", "navigation": "nav", **keys}), skills
        )
        for name, keys in (("cleaners", {"speed_m_s": 0.6}), ("movers", {"storeys": ["first-floor"]}))
    ]
    iris = [literal_value(r["element"]) or "" for r in store.select(selection_query(nav))]
    maps = {s.key: build_map(scene, plan_map(scene, nav, s.key, iris)) for s in scene.storeys}
    return graphs, maps


def test_the_building_maps_bytes_decode_field_by_field(
    building: tuple[list[RouteGraph], dict[str, OccupancyGrid]],
) -> None:
    graphs, maps = building
    msg = decode_building_map(encode_building_map(graphs, maps, building="Lab", levels=LEVELS))
    assert msg.name == "Lab"
    l1, l2 = msg.levels
    assert (l1.name, l1.elevation, l2.name, l2.elevation) == ("L1", 0.0, "L2", 3.0)
    (image,) = l1.images
    grid = maps["ground-floor"]
    assert image.encoding == "png" and bytes(image.data[:8]) == b"\x89PNG\r\n\x1a\n"
    assert image.scale == pytest.approx(grid.frame.resolution_m)
    assert (image.x_offset, image.y_offset) == pytest.approx(
        (grid.frame.origin_x - 10.0, grid.frame.origin_y - 5.0)
    )
    (door,) = l1.doors
    assert door.name == "Door_A" and door.door_type == 5 and door.motion_range == DOOR_MOTION_RANGE_DEG
    # a right-hand swing door along +x: hinged at its +x end, swinging clockwise towards -x, +y
    assert (door.v1_x, door.v1_y, door.v2_x, door.v2_y) == pytest.approx((2.45, -0.1, 1.55, -0.1))
    assert door.motion_direction == 1
    assert [g.name for g in l1.nav_graphs] == ["cleaners"] and [g.name for g in l2.nav_graphs] == [
        "cleaners",
        "movers",
    ]
    cleaners = graphs[0].storey("ground-floor")
    g1 = l1.nav_graphs[0]
    assert len(g1.vertices) == len(cleaners.vertices) and len(g1.edges) == len(cleaners.lanes)
    names = {v.name for v in g1.vertices if v.name}
    assert {"ground_floor_Room_A", "ground_floor_Lift_1"} <= names
    door_edges = [
        e for e in g1.edges if any(p.name == "door_name" and p.value_string == "Door_A" for p in e.params)
    ]
    assert len(door_edges) == 1 and door_edges[0].edge_type == 0  # one two-way lane
    speeds = {p.value_float for e in g1.edges for p in e.params if p.name == "speed_limit"}
    assert sorted(speeds) == pytest.approx([0.6])  # float32
    lift_vertex = next(v for v in g1.vertices if v.name == "ground_floor_Lift_1")
    assert any(p.name == "lift" and p.value_string == "Lift_1" for p in lift_vertex.params)
    (lift,) = msg.lifts
    assert (lift.name, list(lift.levels)) == ("Lift_1", ["L1", "L2"])
    assert (lift.ref_x, lift.ref_y, lift.width, lift.depth) == pytest.approx((9.7, 2.7, 1.4, 1.4))
    assert math.isclose(lift.ref_yaw, 0.0)


def test_map_is_latched_for_late_joiners_on_both_layouts(
    building: tuple[list[RouteGraph], dict[str, OccupancyGrid]],
) -> None:
    graphs, maps = building
    payload = encode_building_map(graphs, maps, building="Lab", levels=LEVELS)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    daemon = zenoh.open(session_config(ZenohSettings(), mode="peer", listen=[endpoint], connect=[]))
    robot = zenoh.open(client_config([endpoint]))
    out = RosBuildingMap(daemon, payload)
    topic = RosTopic(0, "/", "map", BUILDING_MAP)
    try:
        for key, rmw in (("map", False), (topic.data_key, True)):  # joined after the put
            got: list[zenoh.Sample] = []
            arrived = threading.Event()

            def on_sample(
                sample: zenoh.Sample, got: list[zenoh.Sample] = got, arrived: threading.Event = arrived
            ) -> None:
                got.append(sample)
                arrived.set()

            sub = declare_latched_subscriber(robot, key, on_sample)
            try:
                assert arrived.wait(10.0), key
                assert got[0].payload.to_bytes() == payload
                if rmw:
                    sequence, _, gid = parse_attachment(got[0].attachment.to_bytes())
                    assert sequence == 1 and len(gid) == 16
            finally:
                sub.undeclare()
        tokens = [str(r.ok.key_expr) for r in robot.liveliness().get("@ros2_lv/0/**", timeout=5.0) if r.ok]
        assert any("/MP/" in t and "%map/" in t and "BuildingMap" in t for t in tokens)
    finally:
        out.close()
        robot.close()
        daemon.close()


def test_robots_cannot_take_the_building_maps_topic(tmp_path: Path) -> None:
    (tmp_path / "site.toml").write_text('[robots.r1]\nnamespace = "/"\nstorey = "ground-floor"\n')
    with pytest.raises(ConfigError, match="namespace: expected a ROS namespace such as \"/robot1\", got '/'"):
        ros_robots(load_config(tmp_path / "site.toml"))


@pytest.mark.parametrize(
    ("operation", "kind"),
    [
        ("", 5),
        ("NOTDEFINED", 5),
        ("SINGLE_SWING_LEFT", 5),
        ("DOUBLE_SWING_RIGHT", 5),
        ("DOUBLE_DOOR_SINGLE_SWING", 6),
        ("DOUBLE_DOOR_DOUBLE_SWING", 6),
        ("SLIDING_TO_LEFT", 1),
        ("DOUBLE_DOOR_SLIDING", 2),
        ("REVOLVING", 0),
        ("FOLDING_TO_RIGHT", 0),
        ("ROLLINGUP", 0),
    ],
)
def test_a_doors_rmf_type_follows_its_ifc_operation_type(operation: str, kind: int) -> None:
    assert door_type(operation) == kind
