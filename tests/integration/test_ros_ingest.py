"""ROS 2 robots and Open-RMF report to the daemon process in their own messages, on both layouts: a
table detected in a camera frame two TF hops from the map appears in the navigation map at its cells,
the same array again is a confirmation (no revision), an RMF DoorState OPEN makes the door passable, an
RMF obstacle expires after its lifetime, and messages of the wrong type or malformed (and a burst of
truncated and random ones on every topic) are refused and counted while the daemon keeps serving and
the twin does not change.

The robot is its own process (``ros_report_publisher``) publishing on rmw_zenoh's keys with the rmw
attachment, or on the bridge's keys. Detection3DArray, TFMessage, DoorState and Obstacles have no
wheel: their bytes are written from the CDR rules (``tests/adapters/ros_reports.py``, checked against
rclpy's Header and Pose and against the upstream definitions); the wrong-type message is a real
rclpy-serialised ``std_msgs/msg/String``.
"""

from __future__ import annotations

import json
import random
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zenoh
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from adapters.ros.interfaces import DETECTION_3D_ARRAY, DOOR_STATE, OBSTACLES, TF_MESSAGE
from adapters.ros.rmw_zenoh import parse_token
from adapters.zenoh.client import TwinClient
from adapters.zenoh.session import client_config
from tests.adapters.ros_reports import (
    OPTICAL,
    Det,
    Obstacle,
    Tf,
    cdr_detections,
    cdr_door_state,
    cdr_obstacles,
    cdr_tf,
)
from tests.integration.conftest import Daemon, JsonLinesProcess, start_daemon
from tests.integration.settled import settled_map
from twin.maps.grid import OccupancyGrid

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

OCCUPIED = 100
TABLE = (16.6, 7.0, 0.6, 0.6)  # centre x, y and sizes in the map: free floor of the lab's ground floor


def config(layout: str) -> str:
    return f"""
[robots.robot1]
namespace = "/robot1"
storey = "ground-floor"
ros = ["{layout}"]
[robots.robot1.detections]
classes = {{ table = "IfcFurniture" }}
fov_deg = 87
range_m = 6.0
optical = true

[sources.doors]
kind = "rmf_doors"
ros = ["{layout}"]
doors = {{ lab_door_a = "Door A" }}

[sources.obstacles]
kind = "rmf_obstacles"
ros = ["{layout}"]
classes = {{ human = "IfcBuildingElementProxy" }}
levels.L1 = {{ storey = "ground-floor" }}
"""


@pytest.fixture(params=["rmw_zenoh", "bridge"])
def layout_daemon(
    request: pytest.FixtureRequest, fresh_store: Path, tmp_path: Path
) -> Iterator[tuple[str, Daemon]]:
    path = tmp_path / "robots.toml"
    path.write_text(config(request.param))
    d = start_daemon(fresh_store, "--no-record", "-v", config=path)
    yield request.param, d
    d.stop_cleanly()


class Publisher(JsonLinesProcess):
    def __init__(self, d: Daemon, layout: str) -> None:
        super().__init__("tests.integration.ros_report_publisher", d.endpoint, layout, "0")
        while "ready" not in self.next():  # a message may come first: the subscriptions start before "ready"
            pass

    def send(
        self, topic: str, type_name: str, payload: bytes, *, latched: bool = False, type_key: str = ""
    ) -> None:
        assert self.process.stdin is not None
        line = {
            "topic": topic,
            "type": type_name,
            "hex": payload.hex(),
            "latched": latched,
            "type_key": type_key,
        }
        self.process.stdin.write(json.dumps(line) + "\n")
        self.process.stdin.flush()
        self.next()


def wait_until(
    client: TwinClient, test: Callable[[dict[str, Any]], bool], timeout_s: float = 20.0
) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while True:
        status = client.status()
        if test(status):
            return status
        assert time.monotonic() < deadline, json.dumps(status.get("ros_ingest"), indent=1)
        time.sleep(0.1)


def counts(status: dict[str, Any], owner: str) -> dict[str, Any]:
    c: dict[str, Any] = status["ros_ingest"]["counts"][owner]
    return c


def cells(grid: OccupancyGrid, x: float, y: float, sx: float, sy: float, *, grow: float) -> np.ndarray:
    """Cells whose centres lie within the axis-aligned rectangle grown by ``grow`` (negative: shrunk)."""
    f = grid.frame
    cx = f.origin_x + (np.arange(f.width) + 0.5) * f.resolution_m
    cy = f.origin_y + (np.arange(f.height) + 0.5) * f.resolution_m
    inside_x = np.abs(cx - x) <= sx / 2 + grow
    inside_y = np.abs(cy - y) <= sy / 2 + grow
    return inside_y[:, None] & inside_x[None, :]


def test_detections_doors_and_obstacles_from_ros_reach_the_navigation_map(
    layout_daemon: tuple[str, Daemon],
) -> None:
    layout, daemon = layout_daemon
    robot = Publisher(daemon, layout)
    stamp = time.time_ns()
    with TwinClient.connect([daemon.endpoint]) as client:
        before = settled_map(client)
        revision0 = client.status()["revision"]
        # TF: map -> base_link (robot at x = 14 +- 1 m around the stamp) -> camera_link -> optical frame
        robot.send(
            "/robot1/tf_static",
            TF_MESSAGE,
            cdr_tf(
                [
                    Tf("base_link", "camera_link", (0.2, 0.0, 1.0)),
                    Tf("camera_link", "camera_optical_frame", (0, 0, 0), OPTICAL),
                ]
            ),
            latched=True,
        )
        robot.send(
            "/robot1/tf",
            TF_MESSAGE,
            cdr_tf(
                [
                    Tf("map", "base_link", (13.0, 7.0, 0.0), stamp_ns=stamp - 10**8),
                    Tf("map", "base_link", (15.0, 7.0, 0.0), stamp_ns=stamp + 10**8),
                ]
            ),
        )
        time.sleep(0.3)
        table = Det(
            (("table", 0.93),), (0.0, 0.625, 2.4), (0.6, 0.6, 0.75), (0.5, -0.5, 0.5, 0.5), id="track-7"
        )
        array = cdr_detections(stamp, "camera_optical_frame", [table])
        robot.send("/robot1/detections", DETECTION_3D_ARRAY, array)
        status = wait_until(client, lambda s: counts(s, "robot1")["accepted"] == 1)
        after = settled_map(client)
        inner = cells(after, *TABLE, grow=-after.frame.resolution_m)
        assert (after.data[inner] == OCCUPIED).all() and (before.data[inner] != OCCUPIED).all()
        changed = after.data != before.data
        assert not (changed & ~cells(after, *TABLE, grow=after.frame.resolution_m)).any()  # nowhere else
        revision1 = status["revision"]
        assert revision1 == revision0 + 1

        # the same array again: a confirmation, no revision
        robot.send("/robot1/detections", DETECTION_3D_ARRAY, array)
        status = wait_until(client, lambda s: counts(s, "robot1")["unchanged"] == 1)
        assert status["revision"] == revision1

        # then arrays without the table, the robot in room B looking back (-x) through the doorway at
        # the table's place (from x = 14 the arch hides it): removed by absence
        back = (0.0, 0.0, 1.0, 0.0)  # yaw pi
        for _ in range(4):
            time.sleep(0.6)
            t = time.time_ns() - 10**8
            robot.send(
                "/robot1/tf",
                TF_MESSAGE,
                cdr_tf(
                    [
                        Tf("map", "base_link", (19.5, 7.0, 0.0), back, stamp_ns=t - 10**8),
                        Tf("map", "base_link", (19.5, 7.0, 0.0), back, stamp_ns=t + 10**8),
                    ]
                ),
            )
            robot.send(
                "/robot1/detections", DETECTION_3D_ARRAY, cdr_detections(t, "camera_optical_frame", [])
            )
        status = wait_until(client, lambda s: s["revision"] == revision1 + 1)
        gone = settled_map(client)
        np.testing.assert_array_equal(gone.data, before.data)
        assert status["fusion"]["stale"] == 0
        with TwinClient.connect([daemon.endpoint]) as other:
            why = other.sparql("SELECT ?why WHERE { ?e twin:removedBecause ?why }")
        assert isinstance(why, dict) and "absent" in why["results"]["bindings"][0]["why"]["value"]
        revision1 = status["revision"]
        after = gone

        # an RMF door state OPEN makes the door passable
        robot.send("/door_states", DOOR_STATE, cdr_door_state(stamp, "lab_door_a", 1))  # MOVING: nothing
        robot.send("/door_states", DOOR_STATE, cdr_door_state(stamp, "lab_door_a", 2))
        status = wait_until(client, lambda s: counts(s, "doors")["accepted"] == 1)
        assert counts(status, "doors")["ignored"] == {"mode_moving": 1}
        opened = settled_map(client)
        freed = (after.data == OCCUPIED) & (opened.data != OCCUPIED)
        assert freed.sum() > 10 and not ((opened.data == OCCUPIED) & (after.data != OCCUPIED)).any()

        # an RMF obstacle for 1.5 s: in the map, then gone
        person = Obstacle(
            4, "lobby_cam", "L1", "human", (10.0, 7.0, 0.9), (0.5, 0.5, 1.8), lifetime_ns=1_500_000_000
        )
        robot.send("/rmf_obstacles", OBSTACLES, cdr_obstacles(stamp, [person]))
        wait_until(client, lambda s: counts(s, "obstacles")["accepted"] == 1)
        with_person = settled_map(client)
        spot = cells(with_person, 10.0, 7.0, 0.5, 0.5, grow=-with_person.frame.resolution_m)
        assert (with_person.data[spot] == OCCUPIED).all()
        wait_until(client, lambda s: counts(s, "obstacles")["accepted"] == 2)  # the removal at expiry
        np.testing.assert_array_equal(settled_map(client).data, opened.data)

        # hostile input: refused, counted, and the daemon keeps serving
        robot.send("/robot1/detections", DETECTION_3D_ARRAY, b"\x00\x01\x00\x00\x07garbage")
        wrong = serialize_message(String(data="not a detection"))
        robot.send("/robot1/detections", DETECTION_3D_ARRAY, wrong, type_key="std_msgs/msg/String")
        future = cdr_detections(stamp + 3600 * 10**9, "camera_optical_frame", [table])
        robot.send("/robot1/detections", DETECTION_3D_ARRAY, future)
        robot.send("/robot1/detections", DETECTION_3D_ARRAY, cdr_detections(stamp, "lidar_link", [table]))
        expected = (
            {"malformed": 2, "future": 1, "unknown_frame": 1}
            if layout == "bridge"
            else {"malformed": 1, "wrong_type": 1, "future": 1, "unknown_frame": 1}
        )
        status = wait_until(client, lambda s: counts(s, "robot1")["refused"] == expected)
        assert status["revision"] == revision1 + 3  # the door, the obstacle and its expiry: nothing else

        # a burst of broken messages on every topic: truncated and random bytes; none changes the twin
        rng = random.Random(31)
        valid = {
            ("/robot1/detections", DETECTION_3D_ARRAY): array,
            ("/robot1/tf", TF_MESSAGE): cdr_tf([Tf("map", "base_link", (14.0, 7.0, 0.0), stamp_ns=stamp)]),
            ("/door_states", DOOR_STATE): cdr_door_state(stamp, "lab_door_a", 0),
            ("/rmf_obstacles", OBSTACLES): cdr_obstacles(stamp, [person]),
        }
        before_burst = {
            owner: counts(status, owner)["received"] for owner in ("robot1", "doors", "obstacles")
        }
        for n in range(60):
            (topic, type_name), payload = rng.choice(sorted(valid.items()))
            broken = (
                payload[: rng.randrange(4, len(payload) - 4)] if n % 2 else rng.randbytes(rng.randrange(64))
            )
            robot.send(topic, type_name, broken)
        status = wait_until(
            client, lambda s: sum(counts(s, o)["received"] - before_burst[o] for o in before_burst) == 60
        )
        assert status["revision"] == revision1 + 3
        assert all(
            counts(status, o)["accepted"] == n for o, n in (("robot1", 2), ("doors", 1), ("obstacles", 2))
        )
        assert np.array_equal(settled_map(client).data, opened.data)  # still serving, the map unchanged
    robot.close_stdin_and_wait()
    if layout == "rmw_zenoh":  # the daemon is a subscriber of these topics in the robot's ROS graph
        with zenoh.open(client_config([daemon.endpoint])) as session:
            keys = [str(r.ok.key_expr) for r in session.liveliness().get("@ros2_lv/0/**", timeout=5) if r.ok]
        tokens = [parse_token(k) for k in keys]
        nodes = [(t.namespace, t.node) for t in tokens if t.kind == "NN"]
        assert ("/robot1", "twin_ingest") in nodes
        assert {"twin_ingest_doors", "twin_ingest_obstacles"} <= {node for _, node in nodes}  # a name each
        assert len(nodes) == len(set(nodes))  # no duplicate node names in the ROS graph
        subscribed = {
            (t.topic, t.type_name) for t in tokens if t.kind == "MS" and t.node.startswith("twin_ingest")
        }
        assert {
            ("/robot1/detections", "vision_msgs::msg::dds_::Detection3DArray_"),
            ("/robot1/tf", "tf2_msgs::msg::dds_::TFMessage_"),
            ("/robot1/tf_static", "tf2_msgs::msg::dds_::TFMessage_"),
            ("/door_states", "rmf_door_msgs::msg::dds_::DoorState_"),
            ("/rmf_obstacles", "rmf_obstacle_msgs::msg::dds_::Obstacles_"),
        } <= subscribed
