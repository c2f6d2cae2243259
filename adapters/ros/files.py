"""All files of one map: nav2 YAML + PGM, PNG preview and the CDR ``nav_msgs/OccupancyGrid`` payload.

Example::

    files = write_map_files(grid, Path("maps"), stamp_ns=time.time_ns())
    files.cdr.read_bytes()  # what a /map publisher would send
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from pathlib import Path

from adapters.ros._common import write_atomic
from adapters.ros.cdr import encode_occupancy_grid
from adapters.ros.map_server import write_map_server
from adapters.ros.png import write_png_preview
from twin.errors import MapError
from twin.maps.grid import OccupancyGrid

__all__ = ["MapFiles", "write_map_files"]

logger = logging.getLogger(__name__)

_UNSAFE_FILE_CHARS = re.compile(r"[^\w.\-]")


@dataclass(frozen=True, slots=True)
class MapFiles:
    """Everything :func:`write_map_files` writes for one map: nav2 YAML + PGM, PNG preview, CDR bytes."""

    yaml: Path
    pgm: Path
    png: Path
    cdr: Path


def _file_part(name: str, what: str) -> str:
    if not name:
        msg = f"Cannot name map files: the grid's {what} is empty."
        raise MapError(msg)
    return _UNSAFE_FILE_CHARS.sub("_", name)


def write_map_files(grid: OccupancyGrid, out_dir: Path, *, stamp_ns: int, frame_id: str = "map") -> MapFiles:
    """Write ``<storey>__<skill>.yaml/.pgm/.png/.cdr`` into ``out_dir`` (the ``.cdr`` is the
    :func:`encode_occupancy_grid` payload). Characters other than letters, digits, ``_``, ``.`` and ``-``
    in storey/skill become ``_`` in the file names; the YAML comment keeps the exact names.

    Example::

        files = write_map_files(grid, Path("maps"), stamp_ns=time.time_ns())
        files.yaml.name  # 'Level_1__navigation.yaml' for storey 'Level 1', skill 'navigation'
    """
    stem = f"{_file_part(grid.storey, 'storey')}__{_file_part(grid.skill, 'skill')}"
    payload = encode_occupancy_grid(grid, stamp_ns=stamp_ns, frame_id=frame_id)
    server = write_map_server(grid, out_dir, stem)
    png = write_png_preview(grid, out_dir / f"{stem}.png")
    cdr = out_dir / f"{stem}.cdr"
    write_atomic(cdr, payload)
    logger.info("Wrote map files %s.{yaml,pgm,png,cdr} in %s", stem, out_dir)
    return MapFiles(yaml=server.yaml, pgm=server.pgm, png=png, cdr=cdr)
