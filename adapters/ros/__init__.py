"""ROS 2 views of the core's occupancy grids: CDR messages and nav2 ``map_server`` files.

The core's :class:`~twin.maps.grid.OccupancyGrid` already uses ``nav_msgs/OccupancyGrid`` conventions
(``int8`` cells, 0 free, 100 occupied, -1 unknown, row-major, row 0 = lowest y), so this package only
translates containers; it never resamples or re-thresholds a map. :mod:`~adapters.ros.cdr` encodes
and decodes the messages on ``/map`` and ``/map_updates``; :mod:`~adapters.ros.map_server` writes and
reads nav2's YAML + PGM pair; :mod:`~adapters.ros.png` writes a grayscale preview; and
:mod:`~adapters.ros.files` writes all of them for one map. Everything is re-exported here.
:mod:`~adapters.ros.settings` holds the configuration's ROS 2 keys (``[ros]``, a robot's namespace,
topics and detections, a source's topic); it is not re-exported.

Example::

    files = write_map_files(grid, Path("maps"), stamp_ns=time.time_ns())
    assert read_map_server(files.yaml).data.tobytes() == grid.data.tobytes()
    payload = encode_occupancy_grid(grid, stamp_ns=0)
    same, stamp_ns = decode_occupancy_grid(payload, storey=grid.storey, skill=grid.skill)
"""

from __future__ import annotations

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
