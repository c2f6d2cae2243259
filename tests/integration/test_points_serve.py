"""``twin serve`` with a points skill: each storey's cloud is latched on ``<prefix>/points/<storey>/<skill>``
as a CDR PointCloud2 (a ``get`` answers the latest), a door opened republishes the cloud without the door's
voxels, and a ROS 2 robot
gets its storey's cloud on ``/<ns>/points_map`` in both layouts, decoded by real rclpy (a real daemon
process on loopback; the subscriber is this process's own Zenoh session)."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import PointCloud2 as RosPointCloud2

from adapters.ros.pcd import POINT_CLOUD2, decode_point_cloud2
from adapters.ros.rmw_zenoh import RosTopic
from adapters.zenoh.client import TwinClient
from adapters.zenoh.errors import DaemonTimeoutError
from adapters.zenoh.latched import declare_latched_subscriber
from adapters.zenoh.points import points_key
from tests.integration.conftest import start_daemon
from tests.integration.test_daemon import TWIN, door_of

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

CONFIG = """
[skills.lidar3d]
kind = "points"
resolution_m = 0.2
exclude_types = ["IfcOpeningElement", "IfcFurnishingElement"]
exclude_materials = ["glass"]
"""


def test_the_daemon_latches_each_storeys_cloud_and_republishes_it_when_a_door_opens(
    fresh_store: Path, tmp_path: Path
) -> None:
    config = tmp_path / "points.toml"
    config.write_text(CONFIG)
    d = start_daemon(fresh_store, "--no-record", config=config)
    try:
        with TwinClient.connect([d.endpoint]) as client:
            got: list[tuple[np.ndarray, dict[str, int]]] = []
            arrived = threading.Condition()

            def on_sample(sample: object) -> None:
                xyz, _, frame_id = decode_point_cloud2(bytes(sample.payload))  # type: ignore[attr-defined]
                assert frame_id == "map"
                meta = json.loads(bytes(sample.attachment))  # type: ignore[attr-defined]
                with arrived:
                    got.append((xyz, meta))
                    arrived.notify_all()

            def wait_for(n: int) -> None:
                deadline = time.monotonic() + 30
                with arrived:
                    while len(got) < n and time.monotonic() < deadline:
                        arrived.wait(0.5)
                assert len(got) >= n, f"{len(got)} clouds after 30 s"

            key = points_key(client.keys.prefix, "ground-floor", "lidar3d")
            sub = declare_latched_subscriber(client.session, key, on_sample)  # a late joiner: history
            wait_for(1)
            first, meta = got[0]
            assert len(first) > 1000 and meta["version"] == 1
            assert first[:, 2].min() >= -0.05 - 1e-6  # z above the storey, from just below the floor's top
            ack = client.observe("robot1", f"<{door_of(client)}> <{TWIN}isOpen> true .")
            assert ack["ok"]
            wait_for(2)  # within the second the twin bounds republication to
            after, meta2 = got[1]
            assert meta2["version"] == 2 and meta2["revision"] > meta["revision"]
            assert 0 < len(first) - len(after) < len(first) // 10  # voxels only the door touched
            # every point that changed (gone, or the wall's now where the door's was) is at the door
            old, new = {tuple(p) for p in first.tolist()}, {tuple(p) for p in after.tolist()}
            changed = np.array(sorted(old ^ new))
            extent = changed[:, :2].max(axis=0) - changed[:, :2].min(axis=0)
            assert extent.max() < 1.6, extent  # a 0.9 m door, its frame, a voxel around it
            sub.undeclare()
            xyz, revision, version = client.get_points("ground-floor", "lidar3d")  # a get: the latest cloud
            assert (revision, version) == (meta2["revision"], 2)
            np.testing.assert_array_equal(xyz, after)
            with pytest.raises(DaemonTimeoutError, match="'navigation' is not a points skill"):
                client.get_points("ground-floor", "navigation")  # a 2D skill has no cloud: said so
    finally:
        d.stop_cleanly()


ROBOT = """
[robots.robot1]
namespace = "/robot1"
storey = "ground-floor"
ros = ["bridge", "rmw_zenoh"]
"""


def test_a_ros_robot_gets_its_storeys_cloud_on_points_map_in_both_layouts_and_the_new_floors_after_a_switch(
    fresh_store: Path, tmp_path: Path
) -> None:
    config = tmp_path / "points.toml"
    config.write_text(CONFIG + ROBOT)
    d = start_daemon(fresh_store, "--no-record", config=config)
    try:
        with TwinClient.connect([d.endpoint]) as client:
            topic = RosTopic(0, "/robot1", "points_map", POINT_CLOUD2)
            got: dict[str, list[tuple[np.ndarray, int]]] = {"bridge": [], "rmw_zenoh": []}
            arrived = threading.Condition()

            def on(layout: str) -> Callable[[object], None]:
                def on_sample(sample: object) -> None:
                    msg = deserialize_message(bytes(sample.payload), RosPointCloud2)  # type: ignore[attr-defined]
                    xyz = np.frombuffer(bytes(msg.data), dtype="<f4").reshape(-1, 6)  # x y z, normal
                    extra = sample.attachment  # type: ignore[attr-defined]
                    with arrived:
                        got[layout].append((xyz, 0 if extra is None else len(bytes(extra))))
                        arrived.notify_all()

                return on_sample

            def wait_for(n: int) -> None:
                deadline = time.monotonic() + 30
                with arrived:
                    while min(len(v) for v in got.values()) < n and time.monotonic() < deadline:
                        arrived.wait(0.5)
                assert min(len(v) for v in got.values()) >= n, {k: len(v) for k, v in got.items()}

            subs = [
                declare_latched_subscriber(client.session, topic.bridge_key, on("bridge")),
                declare_latched_subscriber(client.session, topic.data_key, on("rmw_zenoh")),
            ]
            wait_for(1)
            ground = {k: v[0] for k, v in got.items()}
            assert ground["rmw_zenoh"][1] == 33 and ground["bridge"][1] == 0  # rmw_zenoh's attachment
            np.testing.assert_array_equal(ground["bridge"][0], ground["rmw_zenoh"][0])
            assert len(ground["bridge"][0]) > 1000
            assert np.allclose(np.linalg.norm(ground["bridge"][0][:, 3:], axis=1), 1.0, atol=1e-6)
            xyz, _, _ = client.get_points("ground-floor", "lidar3d")  # the native get: the same points
            np.testing.assert_array_equal(xyz, ground["rmw_zenoh"][0][:, :3])
            assert client.robot_storey("robot1", "first-floor") == "first-floor"
            wait_for(2)
            first = got["bridge"][1][0]
            np.testing.assert_array_equal(first, got["rmw_zenoh"][1][0])
            assert not np.array_equal(first, ground["bridge"][0])  # the other floor's cloud
            for s in subs:
                s.undeclare()
    finally:
        d.stop_cleanly()
