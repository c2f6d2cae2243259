"""Points maps on Zenoh in process: a real :class:`~adapters.zenoh.points.ZenohPoints` and
:class:`~adapters.zenoh.ros_points.RosPointsPublisher` on one session, reading one
:class:`~adapters.zenoh.latest.LatestMaps` (fed the twin's events by hand, as the daemon's dispatcher
does), and a robot as a session of its own on loopback: a ``get`` answers the latest cloud, rclpy decodes
the robot's ``points_map`` to the same points, and a late joiner of the robot's topic gets its current
storey's cloud (nothing for a removed skill), all as for the 2D maps."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import zenoh
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import PointCloud2 as RosPointCloud2

from adapters.ros.pcd import POINT_CLOUD2, decode_point_cloud2
from adapters.ros.rmw_zenoh import RosTopic
from adapters.zenoh.latched import declare_latched_subscriber
from adapters.zenoh.latest import LatestMaps
from adapters.zenoh.points import ZenohPoints
from adapters.zenoh.ros_points import RosPointsPublisher
from adapters.zenoh.session import client_config, session_config
from adapters.zenoh.settings import ZenohSettings
from tests.integration.conftest import free_port
from twin.config import load_config
from twin.live.events import MapRemoved, PointsPublished, RobotStoreyChanged
from twin.maps.grid import GridFrame
from twin.maps.points import PointCloud

PREFIX = "twin/lab"
SITE = """
[skills.lidar3d]
kind = "points"
[robots.robot1]
namespace = "/robot1"
storey = "ground-floor"
ros = ["rmw_zenoh"]
"""


def cloud(storey: str, n: int, seed: int) -> PointCloud:
    rng = np.random.default_rng(seed)
    xyz = np.round(rng.uniform(0, 20, size=(n, 3)), 3)
    normals = np.zeros((n, 3), dtype=np.float32)
    normals[np.arange(n), rng.integers(0, 3, n)] = rng.choice([-1.0, 1.0], n)  # axis-aligned faces
    frame = GridFrame(0.0, 0.0, 0.1, 200, 200)
    return PointCloud(storey, "lidar3d", 0.0, 0.1, frame, np.arange(n), xyz, normals)


def until(predicate: Callable[[], bool], timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


def test_a_get_answers_each_storeys_latest_cloud_and_rclpy_reads_the_robots_topic_as_the_same_points(
    tmp_path: Path,
) -> None:
    (tmp_path / "site.toml").write_text(SITE)
    config = load_config(tmp_path / "site.toml")
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    session = zenoh.open(session_config(ZenohSettings(), mode="peer", listen=[endpoint], connect=[]))
    holder = LatestMaps(frame_id="map", timestamp=session.new_timestamp)
    points = ZenohPoints(session, prefix=PREFIX, frame_id="map", maps=holder)
    ros = RosPointsPublisher(session, config, maps=holder)
    robot = zenoh.open(client_config([endpoint]))
    try:

        def emit(event: PointsPublished | MapRemoved | RobotStoreyChanged) -> None:  # as the dispatcher
            if isinstance(event, PointsPublished):  # the holder first
                holder.publish_points(event)
            elif isinstance(event, MapRemoved):
                holder.remove((event.storey, event.skill))
            points.emit(event)
            ros.emit(event)
            points.drain()

        ground1, ground2, first = (
            cloud("ground-floor", 500, 1),
            cloud("ground-floor", 480, 2),
            cloud("first-floor", 300, 3),
        )
        emit(PointsPublished(ground1, 3, 1, 100))
        emit(PointsPublished(first, 3, 1, 100))
        emit(PointsPublished(ground2, 5, 2, 200))  # the newer version replaces the first

        def get(selector: str) -> dict[str, tuple[np.ndarray, dict[str, int]]]:
            out = {}
            for reply in robot.get(selector, timeout=5.0):
                assert reply.ok is not None
                s = reply.ok
                out[str(s.key_expr)] = (
                    decode_point_cloud2(s.payload.to_bytes())[0],
                    json.loads(s.attachment.to_bytes()),
                )
            return out

        until(lambda: bool(get(f"{PREFIX}/points/**")))
        got = get(f"{PREFIX}/points/**")
        assert set(got) == {f"{PREFIX}/points/ground-floor/lidar3d", f"{PREFIX}/points/first-floor/lidar3d"}
        xyz, meta = got[f"{PREFIX}/points/ground-floor/lidar3d"]
        np.testing.assert_array_equal(xyz, ground2.xyz.astype(np.float32))
        assert meta == {"revision": 5, "version": 2}
        only = get(f"{PREFIX}/points/first-floor/*")  # a get names what it asks for
        assert list(only) == [f"{PREFIX}/points/first-floor/lidar3d"]
        np.testing.assert_array_equal(
            only[f"{PREFIX}/points/first-floor/lidar3d"][0], first.xyz.astype(np.float32)
        )

        topic = RosTopic(0, "/robot1", "points_map", POINT_CLOUD2)

        def late_joiner(wait_s: float = 10.0) -> np.ndarray | None:
            """What a new rmw_zenoh subscription of /robot1/points_map gets, decoded by rclpy."""
            got: list[np.ndarray] = []
            lock = threading.Lock()

            def on_sample(sample: zenoh.Sample) -> None:
                msg = deserialize_message(sample.payload.to_bytes(), RosPointCloud2)
                with lock:
                    got.append(np.frombuffer(bytes(msg.data), dtype="<f4").reshape(-1, 6).copy())

            sub = declare_latched_subscriber(robot, topic.data_key, on_sample)
            deadline = time.monotonic() + wait_s
            while not got and time.monotonic() < deadline:
                time.sleep(0.01)
            sub.undeclare()
            return got[-1] if got else None

        joined = late_joiner()
        assert joined is not None
        np.testing.assert_array_equal(joined[:, :3], xyz)  # rclpy: the same points as the get
        np.testing.assert_array_equal(joined[:, 3:], ground2.normals)  # and their normals
        emit(RobotStoreyChanged("robot1", "first-floor", "ground-floor", "zenoh", 5, 250))
        ros.drain()
        joined = late_joiner()
        assert joined is not None
        np.testing.assert_array_equal(joined[:, :3], first.xyz.astype(np.float32))  # the robot's storey's

        emit(MapRemoved("first-floor", "lidar3d", 6, 300))  # a removed skill's cloud: no longer answered
        assert set(get(f"{PREFIX}/points/**")) == {f"{PREFIX}/points/ground-floor/lidar3d"}
        assert late_joiner(wait_s=1.0) is None  # nor to a late joiner of the robot's topic
    finally:
        robot.close()
        points.close()
        ros.close()
        session.close()
