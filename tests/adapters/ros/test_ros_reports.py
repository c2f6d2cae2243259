"""The CDR bytes robots and Open-RMF publish: the test's own encoder (``ros_reports.py``, written from
the CDR rules) and rosbags with the registered upstream definitions agree byte for byte, and the parts
a wheel ships are what real rclpy serialises (``std_msgs/Header``, ``geometry_msgs/Pose``)."""

from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Pose, Quaternion
from rclpy.serialization import serialize_message
from std_msgs.msg import Header

from adapters.ros.cdr import _typestore
from adapters.ros.interfaces import DETECTION_3D_ARRAY, DOOR_STATE, OBSTACLES, TF_MESSAGE
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

STAMP = 1_700_000_000_123_456_789


def roundtrip(payload: bytes, type_name: str) -> bytes:
    store = _typestore()
    return bytes(store.serialize_cdr(store.deserialize_cdr(payload, type_name), type_name))


def test_a_detection_array_reads_back_field_by_field_and_reserialises_to_the_same_bytes() -> None:
    payload = cdr_detections(
        STAMP,
        "camera_optical_frame",
        [Det((("table", 0.9), ("chair", 0.2)), (0.0, 0.6, 2.4), (0.6, 0.6, 0.75), OPTICAL, id="7")],
    )
    msg = _typestore().deserialize_cdr(payload, DETECTION_3D_ARRAY)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1_700_000_000, 123_456_789)
    (d,) = msg.detections
    assert [(r.hypothesis.class_id, r.hypothesis.score) for r in d.results] == [
        ("table", 0.9),
        ("chair", 0.2),
    ]
    assert (d.bbox.center.position.z, d.bbox.size.x, d.id) == (2.4, 0.6, "7")
    assert d.results[0].pose.covariance.shape == (36,)
    assert roundtrip(payload, DETECTION_3D_ARRAY) == payload


def test_the_array_header_is_what_rclpy_serialises_for_std_msgs_header() -> None:
    payload = cdr_detections(STAMP, "cam", [])
    header = serialize_message(Header(stamp=Time(sec=1_700_000_000, nanosec=123_456_789), frame_id="cam"))
    assert payload[: len(header)] == header  # encapsulation, stamp, frame_id: the array starts with it


def test_a_box_pose_is_what_rclpy_serialises_for_geometry_msgs_pose() -> None:
    pose = serialize_message(
        Pose(position=Point(x=1.0, y=2.0, z=3.0), orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))
    )
    payload = cdr_detections(0, "map", [Det((("t", 1.0),), (1.0, 2.0, 3.0), (1.0, 1.0, 1.0), id="")])
    assert pose[4:] in payload  # 8-byte aligned in both streams: the same 56 bytes


def test_tf_door_state_and_obstacles_reserialise_to_the_same_bytes() -> None:
    tf = cdr_tf(
        [Tf("map", "base_link", (1.0, 2.0, 0.0), stamp_ns=STAMP), Tf("base_link", "cam", (0.2, 0, 1))]
    )
    msg = _typestore().deserialize_cdr(tf, TF_MESSAGE)
    assert [t.child_frame_id for t in msg.transforms] == ["base_link", "cam"]
    assert roundtrip(tf, TF_MESSAGE) == tf
    door = cdr_door_state(STAMP, "main_door", 2)
    d = _typestore().deserialize_cdr(door, DOOR_STATE)
    assert (d.door_name, d.current_mode.value, d.door_time.nanosec) == ("main_door", 2, 123_456_789)
    assert roundtrip(door, DOOR_STATE) == door
    obstacles = cdr_obstacles(
        STAMP, [Obstacle(3, "cam1", "L1", "human", (1, 2, 0.9), (0.5, 0.5, 1.8), 2_500_000_000)]
    )
    o = _typestore().deserialize_cdr(obstacles, OBSTACLES).obstacles[0]
    assert (o.id, o.source, o.level_name, o.classification, o.action) == (3, "cam1", "L1", "human", 1)
    assert (o.lifetime.sec, o.lifetime.nanosec, o.bbox.size.z) == (2, 500_000_000, 1.8)
    assert isinstance(o.data, np.ndarray) and o.data.size == 0
    assert roundtrip(obstacles, OBSTACLES) == obstacles
