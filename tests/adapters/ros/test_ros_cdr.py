"""ROS 2 adapter, CDR messages: nav_msgs/OccupancyGrid and map_msgs/OccupancyGridUpdate."""

from __future__ import annotations

import contextlib
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from adapters.ros import (
    apply_update,
    decode_occupancy_grid,
    decode_occupancy_grid_update,
    encode_occupancy_grid,
    encode_occupancy_grid_update,
)
from tests.adapters.ros_samples import STAMP_NS, random_grid
from twin.errors import MapError
from twin.maps.grid import GridFrame, OccupancyGrid, Window

UPDATE_MSG = "std_msgs/Header header\nint32 x\nint32 y\nuint32 width\nuint32 height\nint8[] data\n"


# ------------------------------------------------------------------------------------- CDR: grid


def test_occupancy_grid_round_trips_through_cdr_with_frame_data_and_stamp() -> None:
    grid = random_grid()
    payload = encode_occupancy_grid(grid, stamp_ns=STAMP_NS)
    back, stamp_ns = decode_occupancy_grid(payload, storey="Level 1", skill="navigation", elevation_m=3.2)
    assert stamp_ns == STAMP_NS
    assert back.frame == grid.frame  # 0.05 survives the float32 trip exactly
    assert back.frame.resolution_m == 0.05
    assert back.data.dtype == np.int8
    assert np.array_equal(back.data, grid.data)
    assert (back.storey, back.skill, back.elevation_m) == ("Level 1", "navigation", 3.2)


def test_rosbags_reads_our_occupancy_grid_bytes_independently() -> None:
    grid = random_grid()
    payload = encode_occupancy_grid(grid, stamp_ns=STAMP_NS, frame_id="building")
    msg: Any = get_typestore(Stores.ROS2_HUMBLE).deserialize_cdr(payload, "nav_msgs/msg/OccupancyGrid")
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1_700_000_123, 456_789_012)
    assert msg.header.frame_id == "building"
    assert (msg.info.map_load_time.sec, msg.info.map_load_time.nanosec) == (1_700_000_123, 456_789_012)
    assert msg.info.resolution == pytest.approx(0.05, abs=1e-8)
    assert (msg.info.width, msg.info.height) == (53, 37)
    pos, q = msg.info.origin.position, msg.info.origin.orientation
    assert (pos.x, pos.y, pos.z) == (-12.35, -7.5, 0.0)
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)
    # row-major from the origin row, exactly nav_msgs' layout: no flipping
    assert np.array_equal(msg.data, grid.data.reshape(-1))
    assert msg.data[0] == grid.data[0, 0]
    assert msg.data[53] == grid.data[1, 0]


def test_negative_stamp_and_other_resolutions_round_trip() -> None:
    frame = GridFrame(0.0, -1.0, 0.025, 3, 2)
    grid = OccupancyGrid(frame, np.array([[0, 100, -1], [-1, -1, 0]], np.int8), "s", "k")
    back, stamp_ns = decode_occupancy_grid(encode_occupancy_grid(grid, stamp_ns=-1), storey="s", skill="k")
    assert stamp_ns == -1
    assert back.frame == frame


def test_truncated_occupancy_grid_payload_raises_map_error() -> None:
    payload = encode_occupancy_grid(random_grid(), stamp_ns=STAMP_NS)
    for cut in (0, 3, 10, 60, len(payload) - 5):
        with pytest.raises(MapError, match=r"Malformed nav_msgs/msg/OccupancyGrid CDR payload"):
            decode_occupancy_grid(payload[:cut])


def test_payload_of_the_wrong_type_raises_map_error() -> None:
    update = encode_occupancy_grid_update(random_grid(), Window(0, 0, 2, 2), stamp_ns=0)
    with pytest.raises(MapError, match=r"Malformed nav_msgs/msg/OccupancyGrid CDR payload"):
        decode_occupancy_grid(update)
    with pytest.raises(MapError, match=r"must be bytes, got str"):
        decode_occupancy_grid("not bytes")  # type: ignore[arg-type]


def test_foreign_grids_that_the_core_cannot_hold_raise_map_error() -> None:
    store = get_typestore(Stores.ROS2_HUMBLE)
    t = {
        name: store.types[full]
        for name, full in [
            ("Time", "builtin_interfaces/msg/Time"),
            ("Pose", "geometry_msgs/msg/Pose"),
            ("Point", "geometry_msgs/msg/Point"),
            ("Quaternion", "geometry_msgs/msg/Quaternion"),
        ]
    }

    def payload(data: list[int], q: tuple[float, ...] = (0, 0, 0, 1), width: int = 2) -> bytes:
        pose = t["Pose"](t["Point"](0.0, 0.0, 0.0), t["Quaternion"](*q))
        info = store.types["nav_msgs/msg/MapMetaData"](t["Time"](0, 0), 0.05, width, 1, pose)
        header = store.types["std_msgs/msg/Header"](t["Time"](0, 0), "map")
        msg = store.types["nav_msgs/msg/OccupancyGrid"](header, info, np.array(data, dtype=np.int8))
        return bytes(store.serialize_cdr(msg, "nav_msgs/msg/OccupancyGrid"))

    with pytest.raises(MapError, match=r"has 3 cells, but its info says 2x1 = 2"):
        decode_occupancy_grid(payload([0, 0, 0]))
    with pytest.raises(MapError, match=r"origin is rotated"):
        decode_occupancy_grid(payload([0, 0], q=(0.0, 0.0, 0.7071, 0.7071)))
    with pytest.raises(MapError, match=r"cell values outside -1..100 \(e.g. \[-5\]\)"):
        decode_occupancy_grid(payload([0, -5]))
    with pytest.raises(MapError, match=r"invalid frame: Grid size must be positive"):
        decode_occupancy_grid(payload([], width=0))


def test_encoding_rejects_stamps_that_do_not_fit_ros_time() -> None:
    with pytest.raises(MapError, match=r"does not fit builtin_interfaces/Time"):
        encode_occupancy_grid(random_grid(), stamp_ns=2**31 * 1_000_000_000)
    with pytest.raises(MapError, match=r"stamp_ns must be integer nanoseconds, got 1.5"):
        encode_occupancy_grid(random_grid(), stamp_ns=1.5)  # type: ignore[arg-type]


# ----------------------------------------------------------------------------------- CDR: update


def test_occupancy_grid_update_round_trips_and_applies() -> None:
    source = random_grid(seed=1)
    target = random_grid(seed=2)
    window = Window(row0=5, col0=11, row1=9, col1=18)
    payload = encode_occupancy_grid_update(source, window, stamp_ns=STAMP_NS)
    back_window, cells, stamp_ns = decode_occupancy_grid_update(payload)
    assert (back_window, stamp_ns) == (window, STAMP_NS)
    assert cells.dtype == np.int8
    assert np.array_equal(cells, source.data[5:9, 11:18])

    patched = apply_update(target, back_window, cells)
    expected = target.data.copy()
    expected[5:9, 11:18] = source.data[5:9, 11:18]
    assert np.array_equal(patched.data, expected)
    assert patched.frame == target.frame
    assert (patched.storey, patched.skill, patched.elevation_m) == ("Level 1", "navigation", 3.2)
    assert not np.array_equal(target.data, patched.data)  # the input grid is left alone


def test_rosbags_reads_our_update_bytes_independently() -> None:
    grid = random_grid()
    payload = encode_occupancy_grid_update(grid, Window(2, 3, 4, 8), stamp_ns=STAMP_NS, frame_id="map")
    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(UPDATE_MSG, "map_msgs/msg/OccupancyGridUpdate"))
    msg: Any = store.deserialize_cdr(payload, "map_msgs/msg/OccupancyGridUpdate")
    assert (msg.x, msg.y, msg.width, msg.height) == (3, 2, 5, 2)
    assert msg.header.frame_id == "map"
    assert np.array_equal(msg.data, grid.data[2:4, 3:8].reshape(-1))


def test_update_windows_outside_the_grid_or_misshapen_data_raise_map_error() -> None:
    grid = random_grid()  # 37 x 53
    with pytest.raises(MapError, match=r"Window\(row0=30, col0=0, row1=40, col1=5\) is not inside the 37x53"):
        encode_occupancy_grid_update(grid, Window(30, 0, 40, 5), stamp_ns=0)
    with pytest.raises(MapError, match=r"empty Window"):
        encode_occupancy_grid_update(grid, Window(3, 3, 3, 5), stamp_ns=0)
    with pytest.raises(MapError, match=r"Cannot apply .*Window\(row0=-1, col0=0, row1=1, col1=2\)"):
        apply_update(grid, Window(-1, 0, 1, 2), np.zeros((2, 2), np.int8))
    with pytest.raises(MapError, match=r"shape \(3, 2\), but Window\(row0=0, col0=0, row1=2, col1=2\)"):
        apply_update(grid, Window(0, 0, 2, 2), np.zeros((3, 2), np.int8))
    with pytest.raises(MapError, match=r"must be int8, got float64"):
        apply_update(grid, Window(0, 0, 2, 2), np.zeros((2, 2)))


def test_truncated_update_payload_raises_map_error() -> None:
    payload = encode_occupancy_grid_update(random_grid(), Window(0, 0, 3, 3), stamp_ns=0)
    with pytest.raises(MapError, match=r"Malformed map_msgs/msg/OccupancyGridUpdate CDR payload"):
        decode_occupancy_grid_update(payload[:-12])


def test_corrupted_cdr_bytes_only_ever_raise_map_error() -> None:
    rng = np.random.default_rng(3)
    grid = random_grid(4, 5)
    cases = [
        (encode_occupancy_grid(grid, stamp_ns=7), decode_occupancy_grid),
        (encode_occupancy_grid_update(grid, Window(0, 0, 2, 2), stamp_ns=7), decode_occupancy_grid_update),
    ]
    for payload, decode in cases:
        for _ in range(300):
            corrupt = bytearray(payload)
            for _ in range(int(rng.integers(1, 4))):
                corrupt[int(rng.integers(0, len(corrupt)))] = int(rng.integers(0, 256))
            corrupt = corrupt[: int(rng.integers(len(corrupt) // 2, len(corrupt) + 1))]
            with contextlib.suppress(MapError):  # anything else would fail the test
                decode(bytes(corrupt))  # type: ignore[operator]
