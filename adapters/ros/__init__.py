"""ROS 2 views of the core's occupancy grids: CDR messages and nav2 ``map_server`` files.

The core's :class:`~twin.maps.grid.OccupancyGrid` already uses ``nav_msgs/OccupancyGrid`` conventions
(``int8`` cells, 0 free, 100 occupied, -1 unknown, row-major, row 0 = lowest y), so this package only
translates containers; it never resamples or re-thresholds a map. :mod:`~adapters.ros.cdr` encodes
and decodes the messages on ``/map`` and ``/map_updates``; :mod:`~adapters.ros.map_server` writes and
reads nav2's YAML + PGM pair; :mod:`~adapters.ros.png` writes a grayscale preview; and
:mod:`~adapters.ros.files` writes all of them for one map. Everything is re-exported here.
:mod:`~adapters.ros.settings` holds the configuration's ROS 2 keys (``[ros]``, a robot's namespace,
topics and detections, a source's topic); it is not re-exported. The re-exports are imported when
first used: the settings, which every ``twin`` command loads, need neither NumPy nor the encoders.

Example::

    files = write_map_files(grid, Path("maps"), stamp_ns=time.time_ns())
    assert read_map_server(files.yaml).data.tobytes() == grid.data.tobytes()
    payload = encode_occupancy_grid(grid, stamp_ns=0)
    same, stamp_ns = decode_occupancy_grid(payload, storey=grid.storey, skill=grid.skill)
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from adapters.ros.cdr import OCCUPANCY_GRID as OCCUPANCY_GRID
    from adapters.ros.cdr import OCCUPANCY_GRID_UPDATE as OCCUPANCY_GRID_UPDATE
    from adapters.ros.cdr import (
        apply_update,
        decode_occupancy_grid,
        decode_occupancy_grid_update,
        encode_occupancy_grid,
        encode_occupancy_grid_update,
        encode_update_cells,
    )
    from adapters.ros.files import MapFiles, write_map_files
    from adapters.ros.map_server import (
        FREE_PIXEL,
        FREE_THRESH,
        OCCUPIED_PIXEL,
        OCCUPIED_THRESH,
        UNKNOWN_PIXEL,
        MapServerFiles,
        read_map_server,
        write_map_server,
    )
    from adapters.ros.png import write_png_preview

__all__ = [
    "FREE_PIXEL",
    "FREE_THRESH",
    "OCCUPIED_PIXEL",
    "OCCUPIED_THRESH",
    "UNKNOWN_PIXEL",
    "MapFiles",
    "MapServerFiles",
    "apply_update",
    "decode_occupancy_grid",
    "decode_occupancy_grid_update",
    "encode_occupancy_grid",
    "encode_occupancy_grid_update",
    "encode_update_cells",
    "read_map_server",
    "write_map_files",
    "write_map_server",
    "write_png_preview",
]

_MODULES = {
    "OCCUPANCY_GRID": "cdr",
    "OCCUPANCY_GRID_UPDATE": "cdr",
    "apply_update": "cdr",
    "decode_occupancy_grid": "cdr",
    "decode_occupancy_grid_update": "cdr",
    "encode_occupancy_grid": "cdr",
    "encode_occupancy_grid_update": "cdr",
    "encode_update_cells": "cdr",
    "MapFiles": "files",
    "write_map_files": "files",
    "FREE_PIXEL": "map_server",
    "FREE_THRESH": "map_server",
    "OCCUPIED_PIXEL": "map_server",
    "OCCUPIED_THRESH": "map_server",
    "UNKNOWN_PIXEL": "map_server",
    "MapServerFiles": "map_server",
    "read_map_server": "map_server",
    "write_map_server": "map_server",
    "write_png_preview": "png",
}
"""Each re-exported name and the module of this package that defines it."""


def __getattr__(name: str) -> Any:
    if name in _MODULES:
        return getattr(importlib.import_module(f"adapters.ros.{_MODULES[name]}"), name)
    msg = f"module 'adapters.ros' has no attribute {name!r}"
    raise AttributeError(msg)
