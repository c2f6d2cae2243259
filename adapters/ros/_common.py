"""Private helpers shared by the file writers: map_saver's trinary colours, the thresholds our YAML
declares, the grid -> image lookup and atomic writes.

Thresholds: nav2 reads a trinary pixel ``v`` as ``p = (255 - v) / 255`` and classifies ``p >
occupied_thresh`` as occupied, ``p < free_thresh`` as free, otherwise unknown. ``map_saver`` writes
unknown cells as grey 205, i.e. ``p = 50/255 = 0.19608``; with nav2's default ``free_thresh: 0.25``
that grey would load as *free*. The YAML written here therefore says ``free_thresh: 0.196`` (the ROS 1
``map_saver`` value), which keeps 205 unknown in ``map_server`` and in ``read_map_server``.

Image rows are flipped with respect to the grid: image row 0 is the top of the map (highest y).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import numpy.typing as npt

from twin.errors import MapError
from twin.maps.grid import GridData

__all__ = [
    "FREE_PIXEL",
    "FREE_THRESH",
    "OCCUPIED_PIXEL",
    "OCCUPIED_THRESH",
    "UNKNOWN_PIXEL",
    "raw_pixels",
    "trinary_pixels",
    "write_atomic",
]

# map_saver's trinary colours and the thresholds our YAML declares (see the module docstring).
OCCUPIED_PIXEL = 0
FREE_PIXEL = 254
UNKNOWN_PIXEL = 205
OCCUPIED_THRESH = 0.65
FREE_THRESH = 0.196


def write_atomic(path: Path, blob: bytes) -> None:
    """Write ``blob`` to a temporary sibling, then rename: readers never see a half-written map."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(blob)
        tmp.replace(path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        msg = f"Cannot write {path}: {exc}"
        raise MapError(msg) from exc


def raw_pixels(data: GridData) -> npt.NDArray[np.uint8]:
    """``(h, w) uint8`` image for map_server's ``raw`` mode: the value itself, 255 for unknown (-1);
    top row = highest y."""
    flipped = data[::-1]
    return np.where(flipped < 0, 255, flipped).astype(np.uint8)


def trinary_pixels(data: GridData) -> npt.NDArray[np.uint8]:
    """``(h, w) uint8`` image of ``data`` in map_saver colours, top row = highest y (rows flipped).

    Mirrors map_saver's trinary rule: ``v <= rint(100 * free_thresh)`` free, ``v >=
    rint(100 * occupied_thresh)`` occupied, anything else (including -1) unknown.
    """
    values = np.arange(256, dtype=np.int64)
    values[values > 127] -= 256  # uint8 view of int8 -> signed value
    lut = np.full(256, UNKNOWN_PIXEL, dtype=np.uint8)
    lut[(values >= 0) & (values <= round(100 * FREE_THRESH))] = FREE_PIXEL
    lut[(values >= round(100 * OCCUPIED_THRESH)) & (values <= 100)] = OCCUPIED_PIXEL
    return lut[data[::-1].view(np.uint8)]
