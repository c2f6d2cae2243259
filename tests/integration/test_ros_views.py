"""Views that saw it, through the ROS adapter against the daemon process: a robot in a storage room of
20 boxes in rows detects the front four, and the 16 behind them collect no misses (a box in plain
view that is gone is removed); a camera pitched down in a z-forward frame not named ``optical``
(``optical = true`` in its configuration), whose fields of view come from its
``sensor_msgs/msg/CameraInfo``, does not claim the floor under its frame: a box in its blind zone
stays, one in its view that is gone is removed.

The robots are one process (``ros_report_publisher``) publishing on rmw_zenoh's keys; the boxes are
seeded over Zenoh by another identity before the robots look.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from rclpy.serialization import serialize_message
from sensor_msgs.msg import CameraInfo

from adapters.ros.interfaces import CAMERA_INFO, DETECTION_3D_ARRAY, TF_MESSAGE
from adapters.zenoh.client import TwinClient
from tests.adapters.ros_reports import OPTICAL, Det, Tf, cdr_detections, cdr_tf
from tests.integration.conftest import Daemon, start_daemon
from tests.integration.test_ros_ingest import Publisher, counts, wait_until

pytestmark = pytest.mark.slow  # a daemon and a robot process

CONFIG = """
[robots.store]
namespace = "/store"
storey = "ground-floor"
ros = ["rmw_zenoh"]
[robots.store.detections]
classes = { box = "IfcFurniture" }
fov_deg = 87
range_m = 6.0
optical = false                   # camera_link: x forward

[robots.pitched]
namespace = "/pitched"
storey = "ground-floor"
ros = ["rmw_zenoh"]
[robots.pitched.detections]
classes = { box = "IfcFurniture" }
range_m = 6.0
optical = true                    # front_cam looks along +z, whatever its name
heights_m = [0.1, 0.5]
camera_info = "front_cam/camera_info"   # 60 x 50 deg: the fields of view it publishes
"""

ROWS_X = (19.6, 20.1, 20.6, 21.1, 21.6)  # Room B (x 18..22, y 5..9): five rows of four 0.5 m boxes
COLUMNS_Y = (6.25, 6.75, 7.25, 7.75)
STORE_BASE = (18.3, 7.0)  # the storage robot, camera 1 m up, looking +x at the rows
IN_FRONT = (19.0, 7.0)  # a small box before the rows, in plain view: gone
PITCHED_BASE = (10.5, 6.0)  # in Room A, looking +x, camera 1.2 m up pitched 35 deg down
BLIND = (10.9, 6.0)  # 0.4 m ahead: under its frame (the band is in frame from 0.64 m)
SEEN = (12.5, 6.0)  # 2 m ahead: in its view: gone


def box(iri: str, x: float, y: float, size: float, height: float) -> str:
    return (
        f'<{iri}> twin:ifcClass "IfcFurniture" ; twin:storey "ground-floor" ; '
        f'twin:box "{x} {y} {height / 2} {size} {size} {height} 0" .\n'
    )


def quaternion_product(a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, float, float, float]:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


@pytest.fixture
def views_daemon(fresh_store: Path, tmp_path: Path) -> Iterator[Daemon]:
    path = tmp_path / "robots.toml"
    path.write_text(CONFIG)
    d = start_daemon(fresh_store, "--no-record", config=path)
    yield d
    if d.process.poll() is None:
        d.process.kill()
        d.process.wait(timeout=10)


def removed(client: TwinClient) -> set[str]:
    rows: Any = client.sparql("SELECT ?e WHERE { ?e twin:removedBecause ?why }")
    return {b["e"]["value"] for b in rows["results"]["bindings"]}


def look(robot: Publisher, ns: str, base: tuple[float, float], frame: str, dets: list[Det]) -> None:
    t = time.time_ns() - 10**8
    tf = [
        Tf("map", "base_link", (*base, 0.0), stamp_ns=t - 10**8),
        Tf("map", "base_link", (*base, 0.0), stamp_ns=t + 10**8),
    ]
    robot.send(f"/{ns}/tf", TF_MESSAGE, cdr_tf(tf))
    robot.send(f"/{ns}/detections", DETECTION_3D_ARRAY, cdr_detections(t, frame, dets))


def test_boxes_behind_the_front_row_and_under_a_pitched_camera_s_frame_are_not_missed(
    views_daemon: Daemon,
) -> None:
    robot = Publisher(views_daemon, "rmw_zenoh")
    boxes = {f"urn:seed:box-{r}-{c}": (x, y) for r, x in enumerate(ROWS_X) for c, y in enumerate(COLUMNS_Y)}
    seed = "@prefix twin: <https://w3id.org/building-twin#> .\n" + "".join(
        box(iri, x, y, 0.5, 1.2) for iri, (x, y) in boxes.items()
    )
    seed += box("urn:seed:in-front", *IN_FRONT, 0.3, 0.3)
    seed += box("urn:seed:blind", *BLIND, 0.3, 0.4) + box("urn:seed:seen", *SEEN, 0.3, 0.4)
    pitch = math.radians(35)
    down = quaternion_product((0.0, math.sin(pitch / 2), 0.0, math.cos(pitch / 2)), OPTICAL)
    robot.send(
        "/store/tf_static",
        TF_MESSAGE,
        cdr_tf([Tf("base_link", "camera_link", (0.0, 0.0, 1.0))]),
        latched=True,
    )
    robot.send(
        "/pitched/tf_static", TF_MESSAGE, cdr_tf([Tf("base_link", "front_cam", (0.0, 0.0, 1.2), down)]),
        latched=True,
    )  # fmt: skip
    info = CameraInfo(width=640, height=480)
    info.k = [
        320 / math.tan(math.radians(30)),
        0.0,
        320.0,
        0.0,
        240 / math.tan(math.radians(25)),
        240.0,
        0,
        0,
        1,
    ]
    robot.send("/pitched/front_cam/camera_info", CAMERA_INFO, serialize_message(info), latched=True)
    with TwinClient.connect([views_daemon.endpoint]) as client:
        wait_until(client, lambda s: counts(s, "pitched")["messages"].get("camera_info") == 1)
        ack = client.observe("seeder", seed)
        assert ack["ok"] and len(ack["upserted"]) == 23, ack
        front = [  # the front row in camera_link (x forward, y left, z up), tracked
            Det((("box", 0.9),), (ROWS_X[0] - STORE_BASE[0], y - STORE_BASE[1], 0.6 - 1.0), (0.5, 0.5, 1.2),
                id=f"front-{c}")
            for c, y in enumerate(COLUMNS_Y)
        ]  # fmt: skip
        for _ in range(6):  # over 3 s: three misses over a second remove what a view should have seen
            look(robot, "store", STORE_BASE, "camera_link", front)
            look(robot, "pitched", PITCHED_BASE, "front_cam", [])
            time.sleep(0.5)
        wait_until(
            client, lambda s: counts(s, "store")["received"] >= 6 and counts(s, "pitched")["received"] >= 6
        )
        deadline = time.monotonic() + 10
        while removed(client) != {"urn:seed:in-front", "urn:seed:seen"} and time.monotonic() < deadline:
            time.sleep(0.2)
        status = client.status()
        assert removed(client) == {"urn:seed:in-front", "urn:seed:seen"}, status.get("ros_ingest")
        assert counts(status, "store")["refused"] == {} and counts(status, "pitched")["refused"] == {}
        # the front four were confirmed (resolved to the seeded boxes), never created again
        alive: Any = client.sparql(
            'SELECT (COUNT(?e) AS ?n) WHERE { ?e twin:ifcClass "IfcFurniture" . '
            "FILTER NOT EXISTS { ?e twin:removedBecause ?why } }"
        )
        assert int(alive["results"]["bindings"][0]["n"]["value"]) == 21  # the 20 and the blind one
    robot.close_stdin_and_wait()
