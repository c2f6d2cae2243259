"""CDR ``nav_msgs/msg/OccupancyGrid`` and ``map_msgs/msg/OccupancyGridUpdate`` messages of core grids,
the ``std_msgs/msg/String`` a robot sends on ``/<ns>/storey``, and the
``nav2_msgs/msg/CostmapFilterInfo`` that points nav2's keepout and speed filters at a mask topic.

These are what travel on ``/map`` and ``/map_updates`` (e.g. through ``zenoh-bridge-ros2dds``).
Serialisation uses ``rosbags`` with the ROS 2 Humble type store, ``map_msgs`` registered from its
``.msg`` definition. Grid data is row-major with row 0 = the origin row (lowest y), as in
``nav_msgs``: nothing is flipped, resampled or re-thresholded.

Example::

    payload = encode_occupancy_grid(grid, stamp_ns=0)
    same, stamp_ns = decode_occupancy_grid(payload, storey=grid.storey, skill=grid.skill)
"""

from __future__ import annotations

import functools
import struct
from typing import Any

import numpy as np
import numpy.typing as npt
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from adapters.ros.interfaces import register_interfaces
from twin.errors import MapError
from twin.maps.grid import GridData, GridFrame, OccupancyGrid, Window

__all__ = [
    "COSTMAP_FILTER_INFO",
    "KEEPOUT_FILTER",
    "OCCUPANCY_GRID",
    "OCCUPANCY_GRID_UPDATE",
    "SPEED_FILTER_PERCENT",
    "STRING",
    "apply_update",
    "decode_costmap_filter_info",
    "decode_occupancy_grid",
    "decode_occupancy_grid_update",
    "decode_string",
    "encode_costmap_filter_info",
    "encode_occupancy_grid",
    "encode_occupancy_grid_update",
    "encode_string",
    "encode_update_cells",
]

OCCUPANCY_GRID = "nav_msgs/msg/OccupancyGrid"
OCCUPANCY_GRID_UPDATE = "map_msgs/msg/OccupancyGridUpdate"
STRING = "std_msgs/msg/String"
COSTMAP_FILTER_INFO = "nav2_msgs/msg/CostmapFilterInfo"
KEEPOUT_FILTER = 0
"""``CostmapFilterInfo.type`` of a keepout (or lanes) mask."""
SPEED_FILTER_PERCENT = 1
"""``CostmapFilterInfo.type`` of a speed mask in percent of the maximum speed."""

# nav2_msgs/msg/CostmapFilterInfo.msg, as shipped by nav2 (Jazzy, Kilted; comments dropped).
_COSTMAP_FILTER_INFO_MSG = """\
std_msgs/Header header
uint8 type
string filter_mask_topic
float32 base
float32 multiplier
"""

# map_msgs/msg/OccupancyGridUpdate.msg, as shipped by ROS 2 (rosbags has no map_msgs).
_OCCUPANCY_GRID_UPDATE_MSG = """\
std_msgs/Header header
int32 x
int32 y
uint32 width
uint32 height
int8[] data
"""


_NS_PER_S = 1_000_000_000
_INT32_MIN, _INT32_MAX = -(2**31), 2**31 - 1


@functools.cache
def _typestore() -> Any:
    """The ROS 2 Humble type store with ``map_msgs/msg/OccupancyGridUpdate`` and
    ``nav2_msgs/msg/CostmapFilterInfo`` registered (built once)."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(_OCCUPANCY_GRID_UPDATE_MSG, OCCUPANCY_GRID_UPDATE))
    store.register(get_types_from_msg(_COSTMAP_FILTER_INFO_MSG, COSTMAP_FILTER_INFO))
    register_interfaces(store)  # vision_msgs, rmf_obstacle_msgs, rmf_door_msgs (adapters/ros/interfaces.py)
    return store


def _time(stamp_ns: int) -> Any:
    """``builtin_interfaces/Time`` for integer nanoseconds (``sec`` floors, ``nanosec`` in [0, 1e9))."""
    if isinstance(stamp_ns, bool) or not isinstance(stamp_ns, int | np.integer):
        msg = f"stamp_ns must be integer nanoseconds, got {stamp_ns!r}."
        raise MapError(msg)
    sec, nanosec = divmod(int(stamp_ns), _NS_PER_S)
    if not _INT32_MIN <= sec <= _INT32_MAX:
        msg = f"stamp_ns={stamp_ns} does not fit builtin_interfaces/Time (int32 seconds)."
        raise MapError(msg)
    return _typestore().types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)


def _header(stamp_ns: int, frame_id: str) -> Any:
    if not isinstance(frame_id, str):
        msg = f"frame_id must be a string, got {frame_id!r}."
        raise MapError(msg)
    return _typestore().types["std_msgs/msg/Header"](stamp=_time(stamp_ns), frame_id=frame_id)


def _stamp_ns(header: Any) -> int:
    return int(header.stamp.sec) * _NS_PER_S + int(header.stamp.nanosec)


def _serialize(message: Any, typename: str) -> bytes:
    try:
        return bytes(_typestore().serialize_cdr(message, typename))
    except (SerdeError, struct.error, ValueError, TypeError, OverflowError) as exc:
        msg = f"Cannot serialise {typename}: {exc}"
        raise MapError(msg) from exc


def _deserialize(payload: bytes | bytearray | memoryview, typename: str) -> Any:
    if not isinstance(payload, bytes | bytearray | memoryview):
        msg = f"A {typename} CDR payload must be bytes, got {type(payload).__name__}."
        raise MapError(msg)
    try:
        return _typestore().deserialize_cdr(payload, typename)
    except (SerdeError, struct.error, ValueError, TypeError, UnicodeDecodeError, IndexError) as exc:
        msg = f"Malformed {typename} CDR payload ({len(payload)} bytes): {exc}"
        raise MapError(msg) from exc


def _resolution_from_float32(value: float) -> float:
    """The float64 resolution a float32 ``value`` came from: its shortest round-tripping decimal.

    ``0.05`` travels as ``0.05000000074505806`` and comes back as ``0.05``.
    """
    return float(np.format_float_positional(np.float32(value), unique=True, trim="-"))


def _check_values(data: npt.NDArray[np.int8], what: str) -> None:
    """Cells are -1 (unknown) or 0..100: trinary maps, keepout masks and speed masks (percent)."""
    bad = (data < -1) | (data > 100)
    if bad.any():
        examples = sorted({int(v) for v in data[bad][:1000]})[:5]
        msg = f"{what} has {int(bad.sum())} cell values outside -1..100 (e.g. {examples})."
        raise MapError(msg)


def encode_occupancy_grid(grid: OccupancyGrid, *, stamp_ns: int, frame_id: str = "map") -> bytes:
    """Serialise ``grid`` as a CDR ``nav_msgs/msg/OccupancyGrid`` (little-endian, with encapsulation header).

    ``header.stamp`` and ``info.map_load_time`` are ``stamp_ns``; ``info.resolution`` is float32;
    ``info.origin`` is ``(origin_x, origin_y, 0)`` with identity orientation; ``data`` is the
    ``(height, width) int8`` grid flattened row-major, row 0 = the origin row (no flipping).

    Example::

        payload = encode_occupancy_grid(grid, stamp_ns=1_700_000_000_123_456_789)
        msg = get_typestore(Stores.ROS2_HUMBLE).deserialize_cdr(payload, "nav_msgs/msg/OccupancyGrid")
        assert (msg.info.width, msg.header.stamp.nanosec) == (grid.frame.width, 123_456_789)
    """
    frame = grid.frame
    res32 = np.float32(frame.resolution_m)
    if not (np.isfinite(res32) and res32 > 0):
        msg = f"Grid resolution {frame.resolution_m!r} m is not representable as a float32 > 0."
        raise MapError(msg)
    types = _typestore().types
    header = _header(stamp_ns, frame_id)
    pose = types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=float(frame.origin_x), y=float(frame.origin_y), z=0.0),
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    info = types["nav_msgs/msg/MapMetaData"](
        map_load_time=header.stamp,
        resolution=float(res32),
        width=frame.width,
        height=frame.height,
        origin=pose,
    )
    data = np.ascontiguousarray(grid.data, dtype=np.int8).reshape(-1)
    return _serialize(types[OCCUPANCY_GRID](header=header, info=info, data=data), OCCUPANCY_GRID)


def decode_occupancy_grid(
    payload: bytes | bytearray | memoryview,
    *,
    storey: str = "",
    skill: str = "",
    elevation_m: float = 0.0,
) -> tuple[OccupancyGrid, int]:
    """Parse a CDR ``nav_msgs/msg/OccupancyGrid``: ``(grid, header stamp in integer nanoseconds)``.

    The message carries no storey, skill or elevation: pass them. The float32 resolution is
    recovered as its shortest decimal (``0.05`` round-trips exactly). Rotated origins, a data length
    other than ``width * height`` and cell values outside -1..100 raise :class:`MapError`.

    Example::

        grid2, stamp = decode_occupancy_grid(encode_occupancy_grid(grid, stamp_ns=5), storey="L1")
        assert grid2.frame == grid.frame and stamp == 5
    """
    message = _deserialize(payload, OCCUPANCY_GRID)
    info = message.info
    width, height = int(info.width), int(info.height)
    data = np.asarray(message.data, dtype=np.int8)
    if data.size != width * height:
        msg = (
            f"{OCCUPANCY_GRID} payload has {data.size} cells, but its info says "
            f"{width}x{height} = {width * height}."
        )
        raise MapError(msg)
    q = info.origin.orientation
    if not (abs(q.x) < 1e-9 and abs(q.y) < 1e-9 and abs(q.z) < 1e-9 and abs(abs(q.w) - 1.0) < 1e-9):
        msg = (
            f"{OCCUPANCY_GRID} origin is rotated (quaternion {q.x}, {q.y}, {q.z}, {q.w}); "
            "building-twin grids are axis-aligned."
        )
        raise MapError(msg)
    try:
        frame = GridFrame(
            origin_x=float(info.origin.position.x),
            origin_y=float(info.origin.position.y),
            resolution_m=_resolution_from_float32(info.resolution),
            width=width,
            height=height,
        )
    except MapError as exc:
        msg = f"{OCCUPANCY_GRID} payload has an invalid frame: {exc}"
        raise MapError(msg) from exc
    grid_data = data.reshape(height, width).copy()  # own the memory, not the payload's buffer
    _check_values(grid_data, f"{OCCUPANCY_GRID} payload")
    grid = OccupancyGrid(frame, grid_data, storey=storey, skill=skill, elevation_m=elevation_m)
    return grid, _stamp_ns(message.header)


def _check_window_inside(window: Window, frame: GridFrame, what: str) -> None:
    rows_ok = 0 <= window.row0 <= window.row1 <= frame.height
    if not (rows_ok and 0 <= window.col0 <= window.col1 <= frame.width):
        msg = f"{what}: {window} is not inside the {frame.height}x{frame.width} grid."
        raise MapError(msg)


def encode_occupancy_grid_update(
    grid: OccupancyGrid, window: Window, *, stamp_ns: int, frame_id: str = "map"
) -> bytes:
    """Serialise ``grid``'s cells in ``window`` as a CDR ``map_msgs/msg/OccupancyGridUpdate``.

    ``x = window.col0``, ``y = window.row0``, ``width``/``height`` = the window's size, ``data`` = the
    window's ``(h, w) int8`` cells row-major. The window must be non-empty and inside the grid.

    Example::

        patch = encode_occupancy_grid_update(grid, Window(10, 20, 15, 25), stamp_ns=0)
        window, cells, stamp = decode_occupancy_grid_update(patch)  # cells.shape == (5, 5)
    """
    cells = grid.data[window.row0 : window.row1, window.col0 : window.col1]
    return encode_update_cells(grid.frame, window, cells, stamp_ns=stamp_ns, frame_id=frame_id)


def encode_update_cells(
    frame: GridFrame, window: Window, cells: GridData, *, stamp_ns: int, frame_id: str = "map"
) -> bytes:
    """Like :func:`encode_occupancy_grid_update`, from the window's new ``(h, w) int8`` cells alone
    (what a map update event carries: no copy of the whole grid is needed)."""
    _check_window_inside(window, frame, "Cannot encode an occupancy grid update")
    if window.empty:
        msg = f"Cannot encode an occupancy grid update for the empty {window}."
        raise MapError(msg)
    h, w = window.shape
    if cells.shape != (h, w):
        msg = f"Cannot encode an occupancy grid update: {cells.shape} cells for a {h}x{w} window."
        raise MapError(msg)
    message = _typestore().types[OCCUPANCY_GRID_UPDATE](
        header=_header(stamp_ns, frame_id),
        x=window.col0,
        y=window.row0,
        width=w,
        height=h,
        data=np.ascontiguousarray(cells, dtype=np.int8).reshape(-1),
    )
    return _serialize(message, OCCUPANCY_GRID_UPDATE)


def decode_occupancy_grid_update(
    payload: bytes | bytearray | memoryview,
) -> tuple[Window, npt.NDArray[np.int8], int]:
    """Parse a CDR ``map_msgs/msg/OccupancyGridUpdate``: ``(window, (h, w) int8 cells, stamp_ns)``.

    The window is ``Window(row0=y, col0=x, row1=y + height, col1=x + width)``; it is not checked
    against any grid here (:func:`apply_update` does that).

    Example::

        window, cells, stamp_ns = decode_occupancy_grid_update(payload)
        grid = apply_update(grid, window, cells)
    """
    message = _deserialize(payload, OCCUPANCY_GRID_UPDATE)
    x, y, w, h = int(message.x), int(message.y), int(message.width), int(message.height)
    data = np.asarray(message.data, dtype=np.int8)
    if data.size != w * h:
        msg = f"{OCCUPANCY_GRID_UPDATE} payload has {data.size} cells, but says {w}x{h} = {w * h}."
        raise MapError(msg)
    cells = data.reshape(h, w).copy()
    _check_values(cells, f"{OCCUPANCY_GRID_UPDATE} payload")
    return Window(y, x, y + h, x + w), cells, _stamp_ns(message.header)


def apply_update(grid: OccupancyGrid, window: Window, data: npt.ArrayLike) -> OccupancyGrid:
    """A new grid equal to ``grid`` with ``window`` overwritten by ``data`` (``(h, w) int8``).

    ``grid`` is not modified. An empty window inside the grid gives an unchanged copy.

    Example::

        patched = apply_update(grid, Window(0, 0, 2, 2), np.full((2, 2), 100, np.int8))
    """
    _check_window_inside(window, grid.frame, "Cannot apply an occupancy grid update")
    cells = np.asarray(data)
    if cells.shape != window.shape:
        msg = f"Update data has shape {cells.shape}, but {window} has shape {window.shape}."
        raise MapError(msg)
    if cells.dtype != np.int8:
        msg = f"Update data for {window} must be int8, got {cells.dtype}."
        raise MapError(msg)
    new_data: GridData = grid.data.copy()
    new_data[window.row0 : window.row1, window.col0 : window.col1] = cells
    return OccupancyGrid(grid.frame, new_data, grid.storey, grid.skill, grid.elevation_m)


def encode_string(text: str) -> bytes:
    """Serialise ``text`` as a CDR ``std_msgs/msg/String`` (what ``ros2 topic pub`` sends)."""
    if not isinstance(text, str):
        msg = f"A {STRING} holds text, got {text!r}."
        raise MapError(msg)
    return _serialize(_typestore().types[STRING](data=text), STRING)


def decode_string(payload: bytes | bytearray | memoryview) -> str:
    """Parse a CDR ``std_msgs/msg/String``: its ``data``; MapError names a malformed payload."""
    return str(_deserialize(payload, STRING).data)


def encode_costmap_filter_info(
    filter_type: int,
    mask_topic: str,
    *,
    stamp_ns: int,
    frame_id: str = "map",
    base: float = 0.0,
    multiplier: float = 1.0,
) -> bytes:
    """Serialise a CDR ``nav2_msgs/msg/CostmapFilterInfo``: nav2 reads a mask cell ``v`` as
    ``base + multiplier * v`` (a speed limit), or any occupied cell as keepout.

    Example::

        info = encode_costmap_filter_info(KEEPOUT_FILTER, "/robot1/keepout_mask", stamp_ns=0)
    """
    if filter_type not in (0, 1, 2):
        msg = (
            f"CostmapFilterInfo type must be 0 (keepout), 1 (speed %) or 2 (speed m/s), got {filter_type!r}."
        )
        raise MapError(msg)
    if not mask_topic.startswith("/"):
        msg = f"A filter mask topic must be a fully qualified ROS name (/ns/topic), got {mask_topic!r}."
        raise MapError(msg)
    message = _typestore().types[COSTMAP_FILTER_INFO](
        header=_header(stamp_ns, frame_id),
        type=filter_type,
        filter_mask_topic=mask_topic,
        base=float(np.float32(base)),
        multiplier=float(np.float32(multiplier)),
    )
    return _serialize(message, COSTMAP_FILTER_INFO)


def decode_costmap_filter_info(payload: bytes | bytearray | memoryview) -> tuple[int, str, float, float]:
    """Parse a CDR ``nav2_msgs/msg/CostmapFilterInfo``: ``(type, filter_mask_topic, base, multiplier)``."""
    m = _deserialize(payload, COSTMAP_FILTER_INFO)
    return int(m.type), str(m.filter_mask_topic), float(m.base), float(m.multiplier)
