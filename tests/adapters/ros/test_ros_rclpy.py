"""Every message type the daemon publishes or subscribes, against real ROS 2 typesupport: rclpy's
``serialize_message``/``deserialize_message`` (Kilted wheels, Fast DDS) and the RIHS01 hashes the wheels
ship or that ROS 2's own rosidl generators compute. The wheels are a test dependency (dev extra): if they
are missing, importing them fails this module; nothing is skipped.

- ``nav_msgs/msg/OccupancyGrid`` (every map topic), ``std_msgs/msg/String`` (``/<ns>/storey``): both
  directions through rclpy, byte for byte (alignment padding aside: Fast-CDR leaves it uninitialised).
- ``map_msgs/msg/OccupancyGridUpdate`` (every ``_updates`` topic): no wheel ships map_msgs, so its hash
  comes from rosidl's generators and its bytes are checked field by field: the header is what rclpy
  serialises for ``std_msgs/msg/Header``, then x, y, width, height and the cells at CDR alignment.
- ``nav2_msgs/msg/CostmapFilterInfo`` (every mask's ``_info`` topic): no wheel either; hash from the
  generators, bytes field by field after rclpy's header.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Pose
from nav_msgs.msg import MapMetaData
from nav_msgs.msg import OccupancyGrid as RosOccupancyGrid
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Header
from std_msgs.msg import String as RosString

from adapters.ros import decode_occupancy_grid, encode_occupancy_grid, encode_update_cells
from adapters.ros.cdr import (
    COSTMAP_FILTER_INFO,
    OCCUPANCY_GRID,
    OCCUPANCY_GRID_UPDATE,
    STRING,
    decode_costmap_filter_info,
    decode_occupancy_grid_update,
    decode_string,
    encode_costmap_filter_info,
    encode_string,
)
from adapters.ros.rmw_zenoh import type_hash
from tests.adapters.ros_samples import STAMP_NS, corner_grid, random_grid
from tests.adapters.rosidl_build import generated_hash, shipped_hash
from twin.maps.grid import Window

# map_msgs/msg/OccupancyGridUpdate.msg as ROS 2 ships it (ros-planning/navigation_msgs, map_msgs)
UPDATE_MSG = """\
std_msgs/Header header
int32 x
int32 y
uint32 width
uint32 height
int8[] data
"""

# nav2_msgs/msg/CostmapFilterInfo.msg as nav2 ships it (ros-navigation/navigation2, nav2_msgs)
FILTER_INFO_MSG = """\
std_msgs/Header header
# Type of plugin used (keepout filter, speed limit in m/s, speed limit in percent, etc...)
# 0: keepout/lanes filter
# 1: speed limit filter in % of maximum speed
# 2: speed limit filter in absolute values (m/s)
uint8 type
# Name of filter mask topic
string filter_mask_topic
# Multiplier base offset and multiplier coefficient for conversion of OccGrid.
# Used to convert OccupancyGrid data values to filter space values.
# <filter_space_value> = base + multiplier * <OccupancyGrid_value>
float32 base
float32 multiplier
"""


def padding_of_occupancy_grid(frame_id: str) -> set[int]:
    """Byte positions of a CDR OccupancyGrid that are alignment padding: after ``frame_id`` (to 4) and
    before ``info.origin`` (to 8). Fast-CDR leaves them uninitialised (seen: 0xff), rosbags writes 0."""
    o = 8 + 4 + len(frame_id.encode()) + 1  # stamp, string length, string with NUL (CDR offsets)
    gap1 = range(o, o + (-o % 4))
    o += -o % 4 + 8 + 4 + 4 + 4  # map_load_time, resolution, width, height
    gap2 = range(o, o + (-o % 8))
    return {4 + i for i in (*gap1, *gap2)}  # + the 4-byte encapsulation header


@pytest.mark.parametrize("grid", [random_grid(), corner_grid()], ids=["random", "corner"])
def test_an_occupancy_grid_round_trips_through_rclpy_byte_for_byte(grid: object) -> None:
    ours = encode_occupancy_grid(grid, stamp_ns=STAMP_NS, frame_id="map")  # type: ignore[arg-type]
    msg = deserialize_message(ours, RosOccupancyGrid)
    frame = grid.frame  # type: ignore[attr-defined]
    assert (msg.info.width, msg.info.height) == (frame.width, frame.height)
    assert msg.info.resolution == pytest.approx(frame.resolution_m, rel=1e-7)
    assert (msg.info.origin.position.x, msg.info.origin.position.y) == (frame.origin_x, frame.origin_y)
    assert msg.info.origin.orientation.w == 1.0
    assert (msg.header.frame_id, msg.header.stamp.sec, msg.header.stamp.nanosec) == (
        "map", STAMP_NS // 10**9, STAMP_NS % 10**9,
    )  # fmt: skip
    assert msg.info.map_load_time == msg.header.stamp
    cells = np.asarray(msg.data, dtype=np.int8).reshape(frame.height, frame.width)
    np.testing.assert_array_equal(cells, grid.data)  # type: ignore[attr-defined]
    again = serialize_message(msg)
    assert len(again) == len(ours)
    differ = {i for i, (a, b) in enumerate(zip(again, ours, strict=True)) if a != b}
    assert differ <= padding_of_occupancy_grid("map"), sorted(differ)  # every field byte equal


def test_an_occupancy_grid_made_by_rclpy_decodes_to_the_same_cells() -> None:
    grid = random_grid(9, 11, seed=3)
    frame = grid.frame
    msg = RosOccupancyGrid(
        header=Header(stamp=Time(sec=12, nanosec=34), frame_id="map"),
        info=MapMetaData(
            map_load_time=Time(sec=12, nanosec=34), resolution=frame.resolution_m,
            width=frame.width, height=frame.height, origin=Pose(),
        ),
        data=grid.data.reshape(-1).tolist(),
    )  # fmt: skip
    msg.info.origin.position.x, msg.info.origin.position.y = frame.origin_x, frame.origin_y
    back, stamp = decode_occupancy_grid(serialize_message(msg))
    assert back.frame == frame and stamp == 12 * 10**9 + 34
    np.testing.assert_array_equal(back.data, grid.data)


@pytest.mark.parametrize("text", ["first-floor", "", "Étage 2 / Ost"])
def test_a_storey_string_round_trips_through_rclpy_byte_for_byte(text: str) -> None:
    assert encode_string(text) == serialize_message(RosString(data=text))
    assert decode_string(serialize_message(RosString(data=text))) == text
    assert deserialize_message(encode_string(text), RosString).data == text


@pytest.mark.parametrize("window", [Window(3, 5, 8, 9), Window(0, 0, 1, 1), Window(2, 1, 3, 40)])
@pytest.mark.parametrize("frame_id", ["map", "robot1/map_frame"])
def test_an_occupancy_grid_update_is_rclpys_header_then_the_fields_at_cdr_alignment(
    window: Window, frame_id: str
) -> None:
    grid = random_grid()
    cells = grid.data[window.row0 : window.row1, window.col0 : window.col1]
    ours = encode_update_cells(grid.frame, window, cells, stamp_ns=STAMP_NS, frame_id=frame_id)
    header = serialize_message(
        Header(stamp=Time(sec=STAMP_NS // 10**9, nanosec=STAMP_NS % 10**9), frame_id=frame_id)
    )
    assert ours.startswith(header)
    offset = len(header) - 4  # CDR aligns relative to the end of the 4-byte encapsulation header
    h, w = window.shape
    tail = b"\0" * (-offset % 4) + struct.pack("<iiIII", window.col0, window.row0, w, h, w * h)
    assert ours[len(header) :] == tail + cells.astype(np.int8).tobytes()
    back_window, back_cells, stamp = decode_occupancy_grid_update(ours)
    assert (back_window, stamp) == (window, STAMP_NS)
    np.testing.assert_array_equal(back_cells, cells)


def test_type_hashes_equal_those_the_ros_wheels_ship() -> None:
    for type_name in (OCCUPANCY_GRID, STRING, "std_msgs/msg/Header"):
        assert type_hash(type_name) == shipped_hash(type_name), type_name


def test_the_update_hash_equals_what_rosidls_generators_compute(tmp_path: Path) -> None:
    expected = generated_hash(OCCUPANCY_GRID_UPDATE, UPDATE_MSG, tmp_path, ("std_msgs", "builtin_interfaces"))
    assert type_hash(OCCUPANCY_GRID_UPDATE) == expected
    assert expected == "RIHS01_c4095b0be2e4363f8978a1570e0293ee093436f1e1c61d99b48502ac317025e8"


def test_the_filter_info_hash_equals_what_rosidls_generators_compute(tmp_path: Path) -> None:
    expected = generated_hash(
        COSTMAP_FILTER_INFO, FILTER_INFO_MSG, tmp_path, ("std_msgs", "builtin_interfaces")
    )
    assert type_hash(COSTMAP_FILTER_INFO) == expected


@pytest.mark.parametrize(
    ("kind", "topic", "base", "multiplier"),
    [(0, "/robot1/keepout_mask", 0.0, 1.0), (1, "/a/speed_mask", 10.0, 0.5)],
)
def test_a_filter_info_is_rclpys_header_then_the_fields_at_cdr_alignment(
    kind: int, topic: str, base: float, multiplier: float
) -> None:
    ours = encode_costmap_filter_info(kind, topic, stamp_ns=STAMP_NS, base=base, multiplier=multiplier)
    header = serialize_message(
        Header(stamp=Time(sec=STAMP_NS // 10**9, nanosec=STAMP_NS % 10**9), frame_id="map")
    )
    assert ours.startswith(header)
    o = len(header) - 4  # CDR offset after the header
    text = topic.encode() + b"\0"
    tail = struct.pack("<B", kind)
    o += 1
    tail += b"\0" * (-o % 4) + struct.pack("<I", len(text)) + text
    o += -o % 4 + 4 + len(text)
    tail += b"\0" * (-o % 4) + struct.pack("<ff", base, multiplier)
    assert ours[len(header) :] == tail
    assert decode_costmap_filter_info(ours) == (kind, topic, base, multiplier)
