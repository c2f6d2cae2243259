"""What robots and the building publish, as CDR bytes, for the tests: ``tf2_msgs/msg/TFMessage``,
``vision_msgs/msg/Detection3DArray``, ``rmf_door_msgs/msg/DoorState`` and
``rmf_obstacle_msgs/msg/Obstacles``, each written by :func:`cdr_*` with ``struct`` straight from the CDR
rules (XCDR1 little endian: a 4-byte encapsulation header, then every primitive aligned to its size
from the end of that header; strings as uint32 length with the NUL, then the bytes; sequences as a
uint32 count), independently of rosbags. The parts that wheels ship (``std_msgs/Header``,
``geometry_msgs/Pose``) are checked against rclpy in ``test_ros_reports.py``.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = [
    "Cdr",
    "Det",
    "Obstacle",
    "Tf",
    "cdr_detections",
    "cdr_door_state",
    "cdr_obstacles",
    "cdr_tf",
    "yaw_quaternion",
]

OPTICAL = (-0.5, 0.5, -0.5, 0.5)
"""``camera_link_from_camera_optical_frame``: z forward, x right, y down (REP 103)."""


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


class Cdr:
    """A little-endian CDR stream (XCDR1) with its encapsulation header."""

    def __init__(self) -> None:
        self.body = bytearray()

    def _align(self, n: int) -> None:
        self.body += b"\0" * (-len(self.body) % n)

    def u32(self, v: int) -> Cdr:
        self._align(4)
        self.body += struct.pack("<I", v)
        return self

    def i32(self, v: int) -> Cdr:
        self._align(4)
        self.body += struct.pack("<i", v)
        return self

    def f64(self, *vs: float) -> Cdr:
        for v in vs:
            self._align(8)
            self.body += struct.pack("<d", v)
        return self

    def string(self, s: str) -> Cdr:
        raw = s.encode() + b"\0"
        self.u32(len(raw))
        self.body += raw
        return self

    def time(self, stamp_ns: int) -> Cdr:
        sec, nsec = divmod(stamp_ns, 1_000_000_000)
        return self.i32(sec).u32(nsec)

    def header(self, stamp_ns: int, frame_id: str) -> Cdr:
        return self.time(stamp_ns).string(frame_id)

    def pose(self, position: Sequence[float], orientation: Sequence[float]) -> Cdr:
        return self.f64(*position, *orientation)

    def bytes(self) -> bytes:
        return b"\x00\x01\x00\x00" + bytes(self.body)


@dataclass(frozen=True)
class Tf:
    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    stamp_ns: int = 0


def cdr_tf(transforms: Sequence[Tf]) -> bytes:
    c = Cdr().u32(len(transforms))
    for t in transforms:
        c.header(t.stamp_ns, t.parent).string(t.child).f64(*t.translation, *t.rotation)
    return c.bytes()


@dataclass(frozen=True)
class Det:
    """A detection: best hypothesis first in ``results`` (class_id, score)."""

    results: tuple[tuple[str, float], ...]
    position: tuple[float, float, float]
    size: tuple[float, float, float]
    orientation: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    id: str = ""


def cdr_detections(stamp_ns: int, frame_id: str, detections: Sequence[Det]) -> bytes:
    c = Cdr().header(stamp_ns, frame_id).u32(len(detections))
    for d in detections:
        c.header(stamp_ns, frame_id).u32(len(d.results))
        for class_id, score in d.results:
            c.string(class_id).f64(score)
            c.pose((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)).f64(*([0.0] * 36))  # PoseWithCovariance
        c.pose(d.position, d.orientation).f64(*d.size)
        c.string(d.id)
    return c.bytes()


def cdr_door_state(stamp_ns: int, door_name: str, mode: int) -> bytes:
    return Cdr().time(stamp_ns).string(door_name).u32(mode).bytes()


@dataclass(frozen=True)
class Obstacle:
    id: int
    source: str
    level_name: str
    classification: str
    position: tuple[float, float, float]
    size: tuple[float, float, float]
    lifetime_ns: int = 0
    action: int = 1
    orientation: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)


def cdr_obstacles(stamp_ns: int, obstacles: Sequence[Obstacle]) -> bytes:
    c = Cdr().header(stamp_ns, "map").u32(len(obstacles))
    for o in obstacles:
        c.header(stamp_ns, "map").i32(o.id).string(o.source).string(o.level_name).string(o.classification)
        c.pose(o.position, o.orientation).f64(*o.size)
        c.f64(0.05).u32(0)  # data_resolution, data (no voxels)
        sec, nsec = divmod(o.lifetime_ns, 1_000_000_000)
        c.i32(sec).u32(nsec).i32(o.action)
    return c.bytes()
