"""ROS 2 robots get their maps unchanged: rmw_zenoh and bridge layouts, served by the daemon process to
subscriber processes written from the rmw_zenoh and zenoh-plugin-ros2dds sources, maps decoded by
real rclpy; one robot, several skills on several topics; the storey switched at run time."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import zenoh

from adapters.ros.rmw_zenoh import parse_token, type_hash
from adapters.zenoh.client import TwinClient
from adapters.zenoh.session import client_config
from tests.integration.conftest import Daemon, JsonLinesProcess, start_daemon, twin

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

CONFIG = """
[robots.robot1]
namespace = "/robot1"
storey = "ground-floor"
[robots.robot1.maps]
map = "lab-localization"
navigation_map = "navigation"

[robots.robot2]
namespace = "/robot2"
skill = "lab-localization"
storey = "ground-floor"
ros = ["bridge"]
"""


@pytest.fixture
def ros_daemon(fresh_store: Path, tmp_path: Path) -> Iterator[Daemon]:
    yield from _daemon(fresh_store, tmp_path, "--no-record")


@pytest.fixture
def recording_daemon(fresh_store: Path, tmp_path: Path) -> Iterator[Daemon]:
    yield from _daemon(fresh_store, tmp_path, "--record", str(tmp_path / "run.rrd"))


def _daemon(store: Path, tmp_path: Path, *extra: str) -> Iterator[Daemon]:
    config = tmp_path / "robots.toml"
    config.write_text(CONFIG)
    d = start_daemon(store, *extra, "-v", config=config)  # -v after the command: info logs
    yield d
    d.stop_cleanly()


class RosSubscriber(JsonLinesProcess):
    def __init__(self, d: Daemon, layout: str, ns: str, out: Path, topic: str = "map") -> None:
        out.mkdir(parents=True, exist_ok=True)
        super().__init__("tests.integration.ros_subscriber", d.endpoint, layout, "0", ns, str(out), topic)
        self.out = out
        while "ready" not in self.next():  # a message may come first: the subscriptions start before "ready"
            pass

    def until(self, kind: str, count: int = 1) -> None:
        while sum(1 for ln in self.lines if ln.get("kind") == kind) < count:
            self.next()

    def finish(self) -> np.ndarray:
        self.close_stdin_and_wait()
        return np.load(self.out / "map.npy")


@pytest.mark.parametrize("layout", ["rmw_zenoh", "bridge"])
def test_a_ros_subscriber_gets_the_map_then_only_the_update_and_a_later_joiner_the_current_map_once(
    ros_daemon: Daemon, tmp_path: Path, layout: str
) -> None:
    sub = RosSubscriber(ros_daemon, layout, "/robot1", tmp_path / layout, "navigation_map")
    sub.until("map")  # latched: it joined after the daemon published
    r = twin(
        "observe",
        "--connect",
        ros_daemon.endpoint,
        "--robot",
        "r",
        "--box",
        "16.6,7.0,0.375,0.6,0.6,0.75,0",
        "--class",
        "IfcFurniture",
        "--storey",
        "ground-floor",
    )
    assert r.returncode == 0, r.stderr
    sub.until("update")
    late = RosSubscriber(ros_daemon, layout, "/robot1", tmp_path / f"{layout}-late", "navigation_map")
    late.until("map")  # no full map went out since the change: this one is the history reply
    time.sleep(0.5)
    copy, late_copy = sub.finish(), late.finish()
    with TwinClient.connect([ros_daemon.endpoint]) as client:
        grid, _, _ = client.get_map("ground-floor", "navigation")
    np.testing.assert_array_equal(copy, grid.data)
    np.testing.assert_array_equal(late_copy, grid.data)  # bit for bit, the change included
    maps = [ln for ln in sub.lines if ln.get("kind") == "map"]
    assert len(maps) == 1  # a change costs its changed cells: no full map after it
    late_maps = [ln for ln in late.lines if ln.get("kind") == "map"]
    assert len(late_maps) == 1  # its history and late-publisher queries, answered once
    if layout == "rmw_zenoh":
        assert late_maps[0]["gid"] == maps[0]["gid"] and late_maps[0]["seq"] == maps[0]["seq"] >= 1
        assert all(ln["stamp"] > 0 for ln in (*sub.lines, *late.lines) if "stamp" in ln)


@pytest.mark.parametrize("layout", ["rmw_zenoh", "bridge"])
def test_two_topics_of_one_robot_carry_two_different_maps_each_equal_to_its_skill_map(
    ros_daemon: Daemon, tmp_path: Path, layout: str
) -> None:
    loc_sub = RosSubscriber(ros_daemon, layout, "/robot1", tmp_path / "loc", "map")
    nav_sub = RosSubscriber(ros_daemon, layout, "/robot1", tmp_path / "nav", "navigation_map")
    loc_sub.until("map")
    nav_sub.until("map")
    a, b = loc_sub.finish(), nav_sub.finish()
    with TwinClient.connect([ros_daemon.endpoint]) as client:
        loc, _, _ = client.get_map("ground-floor", "lab-localization")
        nav, _, _ = client.get_map("ground-floor", "navigation")
    np.testing.assert_array_equal(a, loc.data)
    np.testing.assert_array_equal(b, nav.data)
    assert (a != b).any()


def test_the_old_single_skill_key_still_serves_that_skill_on_map(ros_daemon: Daemon, tmp_path: Path) -> None:
    sub = RosSubscriber(ros_daemon, "bridge", "/robot2", tmp_path / "two")
    sub.until("map")
    with TwinClient.connect([ros_daemon.endpoint]) as client:
        loc, _, _ = client.get_map("ground-floor", "lab-localization")
    np.testing.assert_array_equal(sub.finish(), loc.data)


def test_the_daemon_appears_in_the_ros_graph_as_a_map_server_node(ros_daemon: Daemon) -> None:
    with zenoh.open(client_config([ros_daemon.endpoint])) as session:
        time.sleep(0.5)
        keys = [str(r.ok.key_expr) for r in session.liveliness().get("@ros2_lv/0/**", timeout=5) if r.ok]
    tokens = [parse_token(k) for k in keys]
    nodes = {(t.namespace, t.node) for t in tokens if t.kind == "NN"}
    assert ("/robot1", "twin_map_server") in nodes
    assert ("/robot2", "twin_map_server") not in nodes  # bridge only: no rmw graph entry
    pubs = {t.topic: t for t in tokens if t.kind == "MP"}
    assert set(pubs) == {
        "/robot1/map",
        "/robot1/map_updates",
        "/robot1/navigation_map",
        "/robot1/navigation_map_updates",
    }
    m = pubs["/robot1/map"]
    assert m.type_name == "nav_msgs::msg::dds_::OccupancyGrid_"
    assert m.type_hash == type_hash("nav_msgs/msg/OccupancyGrid")
    assert m.qos == {"reliability": None, "durability": 1, "history": None, "depth": 1}
    assert pubs["/robot1/map_updates"].type_name == "map_msgs::msg::dds_::OccupancyGridUpdate_"
    (sub,) = [t for t in tokens if t.kind == "MS"]
    assert (sub.topic, sub.type_name) == ("/robot1/storey", "std_msgs::msg::dds_::String_")
    assert sub.type_hash == type_hash("std_msgs/msg/String")


def test_twin_watch_ros_receives_the_latched_map_like_a_ros_node(ros_daemon: Daemon, tmp_path: Path) -> None:
    for layout in ("rmw_zenoh", "bridge"):
        r = twin("watch", "--connect", ros_daemon.endpoint, "--ros", "/robot1", "--layout", layout,
                 "--count", "1", "--out", tmp_path / layout, timeout=60)  # fmt: skip
        assert r.returncode == 0, r.stderr
        assert "/robot1/map via map" in r.stdout
        yaml = (tmp_path / layout / "robot1__map.yaml").read_text()
        assert "# ROS 2 topic /robot1/map" in yaml and 'storey="robot1"' not in yaml  # no storey to name


class StoreyPublisher(JsonLinesProcess):
    """A ROS 2 node publishing ``/<ns>/storey`` latched (own process, message serialised by rclpy)."""

    def __init__(self, d: Daemon, layout: str, ns: str) -> None:
        super().__init__("tests.integration.ros_storey_publisher", d.endpoint, layout, "0", ns)
        while "ready" not in self.next():  # a message may come first: the subscriptions start before "ready"
            pass

    def send(self, storey: str) -> None:
        assert self.process.stdin is not None
        self.process.stdin.write(storey + "\n")
        self.process.stdin.flush()
        assert self.next() == {"sent": storey}


def wait_for_storey(client: TwinClient, robot: str, storey: str, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while (now := client.robot_storey(robot)) != storey:
        assert time.monotonic() < deadline, f"{robot} still on {now!r}, not {storey!r}"
        time.sleep(0.05)


def recorded_texts(path: Path) -> list[str]:
    import rerun.chunk as rc

    texts: list[str] = []
    for chunk in rc.RrdReader(str(path)).stream().to_chunks():
        if str(chunk.entity_path) == "/events":
            batch = chunk.to_record_batch()
            index = batch.schema.get_field_index("TextLog:text")
            texts += [t for row in batch.column(index).to_pylist() for t in row]
    return texts


def test_a_storey_switch_republishes_every_topic_and_a_late_joiner_gets_the_new_floor(
    recording_daemon: Daemon, tmp_path: Path
) -> None:
    d = recording_daemon
    early = RosSubscriber(d, "rmw_zenoh", "/robot1", tmp_path / "early", "navigation_map")
    early.until("map")
    r = twin("storey", "--connect", d.endpoint, "--robot", "robot1", "first-floor")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "first-floor"
    early.until("map", 2)  # the robot's open subscription gets the new floor too (a full map)
    late = {
        (layout, topic): RosSubscriber(d, layout, "/robot1", tmp_path / f"{layout}-{topic}", topic)
        for layout in ("rmw_zenoh", "bridge")
        for topic in ("map", "navigation_map")
    }
    for sub in late.values():
        sub.until("map")
    with TwinClient.connect([d.endpoint]) as client:
        maps = {
            (storey, topic): client.get_map(storey, skill)[0].data
            for storey in ("ground-floor", "first-floor")
            for topic, skill in (("map", "lab-localization"), ("navigation_map", "navigation"))
        }
        robot = client.status()["robots"]["robot1"]
    for (_, topic), sub in late.items():
        first_line = next(ln for ln in sub.lines if ln.get("kind") == "map")
        assert (first_line["height"], first_line["width"]) == maps[("first-floor", topic)].shape
        np.testing.assert_array_equal(sub.finish(), maps[("first-floor", topic)])
    np.testing.assert_array_equal(early.finish(), maps[("first-floor", "navigation_map")])
    for topic in ("map", "navigation_map"):
        ground, first = maps[("ground-floor", topic)], maps[("first-floor", topic)]
        assert ground.shape != first.shape or (ground != first).any()  # the floors differ
    assert robot["storey"] == "first-floor" and robot["switches"] == 1
    assert robot["topics"] == {"/robot1/map": "lab-localization", "/robot1/navigation_map": "navigation"}
    code, _ = d.stop()
    assert code == 0
    assert any("robot1 is now on storey first-floor" in line for line in d.log)
    texts = recorded_texts(tmp_path / "run.rrd")
    assert "robot1: now on storey first-floor (was ground-floor), via zenoh" in texts


def test_an_unknown_storey_or_robot_is_refused_by_name_and_changes_nothing(ros_daemon: Daemon) -> None:
    r = twin("storey", "--connect", ros_daemon.endpoint, "--robot", "robot1", "basement")
    assert r.returncode == 1
    assert "Unknown storey 'basement' for robot 'robot1'" in r.stderr
    assert "ground-floor, first-floor" in r.stderr
    r = twin("storey", "--connect", ros_daemon.endpoint, "--robot", "ghost", "first-floor")
    assert r.returncode == 1
    assert "Unknown robot 'ghost'" in r.stderr
    with TwinClient.connect([ros_daemon.endpoint]) as client:
        assert client.robot_storey("robot1") == "ground-floor"
        robot = client.status()["robots"]["robot1"]
    assert robot["switches"] == 0
    assert "basement" in robot["refused"]


@pytest.mark.parametrize("case", [
    ("rmw_zenoh", "robot1", "/robot1", "navigation_map"),
    ("bridge", "robot2", "/robot2", "map"),
])  # fmt: skip
def test_a_ros_robot_switches_its_floor_with_a_string_on_its_storey_topic(
    ros_daemon: Daemon, tmp_path: Path, case: tuple[str, str, str, str]
) -> None:
    layout, robot, ns, topic = case
    lift = StoreyPublisher(ros_daemon, layout, ns)
    lift.send("first-floor")
    with TwinClient.connect([ros_daemon.endpoint]) as client:
        wait_for_storey(client, robot, "first-floor")
        skill = client.status()["robots"][robot]["topics"][f"{ns}/{topic}"]
        first, _, _ = client.get_map("first-floor", skill)
        sub = RosSubscriber(ros_daemon, layout, ns, tmp_path / "late", topic)
        sub.until("map")
        np.testing.assert_array_equal(sub.finish(), first.data)
        lift.send("basement")  # refused: the robot stays where it is
        deadline = time.monotonic() + 10
        while "basement" not in (client.status()["robots"][robot]["refused"] or ""):
            assert time.monotonic() < deadline, "the refusal never showed in the status"
            time.sleep(0.05)
        assert client.robot_storey(robot) == "first-floor"
    lift.close_stdin_and_wait()


ZONES = """
[skills.keepout]
kind = "keepout"
resolution_m = 0.05

[robots.robot1]
namespace = "/robot1"
storey = "ground-floor"
[robots.robot1.maps]
map = "lab-localization"
keepout_mask = "keepout"

[robots.operator]
rights = ["create", "dynamic", "doors", "static", "zones"]
"""


def filter_infos(endpoint: str, key: str, timeout_s: float = 10.0) -> list[bytes]:
    """The latched CostmapFilterInfo samples on ``key``, as a late AdvancedSubscriber gets them."""
    got: list[bytes] = []
    with zenoh.open(client_config([endpoint])) as session:
        sub = zenoh.ext.declare_advanced_subscriber(
            session,
            key,
            lambda s: got.append(s.payload.to_bytes()),
            history=zenoh.ext.HistoryConfig(detect_late_publishers=True),
        )
        deadline = time.monotonic() + timeout_s
        while not got and time.monotonic() < deadline:
            time.sleep(0.05)
        sub.undeclare()
    return got


def test_a_keepout_zone_marked_at_run_time_reaches_a_ros_subscriber_as_a_mask_update_and_a_late_joiner(
    fresh_store: Path, tmp_path: Path
) -> None:
    from adapters.ros.cdr import COSTMAP_FILTER_INFO, decode_costmap_filter_info
    from adapters.ros.rmw_zenoh import RosTopic

    config = tmp_path / "zones.toml"
    config.write_text(ZONES)
    d = start_daemon(fresh_store, "--no-record", config=config)
    try:
        early = RosSubscriber(d, "rmw_zenoh", "/robot1", tmp_path / "early", "keepout_mask")
        early.until("map")
        assert next(ln for ln in early.lines if ln.get("kind") == "map")["occupied"] == 0
        zone = tmp_path / "zone.ttl"
        zone.write_text(
            "@prefix twin: <https://w3id.org/building-twin#> .\n"
            '<urn:operator:zone-1> twin:ifcClass "IfcVirtualElement" ; twin:storey "ground-floor" ; '
            'twin:box "16.6 7.0 1.0 1.0 1.0 2.0 0.0" ; twin:keepout true .\n'
        )
        r = twin("observe", "--connect", d.endpoint, "--robot", "operator", "--turtle", zone)
        assert r.returncode == 0, r.stderr
        early.until("update")
        late = {
            layout: RosSubscriber(d, layout, "/robot1", tmp_path / f"late-{layout}", "keepout_mask")
            for layout in ("rmw_zenoh", "bridge")
        }
        for sub in late.values():
            sub.until("map")
        with TwinClient.connect([d.endpoint]) as client:
            mask, _, _ = client.get_map("ground-floor", "keepout")
            loc, _, _ = client.get_map("ground-floor", "lab-localization")
        assert 400 <= int((mask.data == 100).sum()) <= 22 * 22  # the 1 m x 1 m zone at 5 cm
        for sub in (early, *late.values()):
            np.testing.assert_array_equal(sub.finish(), mask.data)
        assert not (loc.data[mask.data == 100] == 100).all()  # a zone is not a wall
        for layout in ("rmw_zenoh", "bridge"):
            topic = RosTopic(0, "/robot1", "keepout_mask_info", COSTMAP_FILTER_INFO)
            infos = filter_infos(d.endpoint, topic.data_key if layout == "rmw_zenoh" else topic.bridge_key)
            assert infos, layout
            assert decode_costmap_filter_info(infos[0]) == (0, "/robot1/keepout_mask", 0.0, 1.0)
        refused = twin(
            "observe", "--connect", d.endpoint, "--robot", "robot1", "--no-keepout", "urn:operator:zone-1"
        )
        assert refused.returncode == 1
        assert (
            "may not lift the keepout zone <urn:operator:zone-1> (it lacks the 'zones' right)"
            in refused.stdout
        )
    finally:
        code, _ = d.stop()
    assert code == 0
