"""Grids and independent readers shared by the ROS adapter tests (no code shared with ``adapters.ros``)."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import numpy.typing as npt

from twin.maps.grid import GridFrame, OccupancyGrid

STAMP_NS = 1_700_000_123_456_789_012


def random_grid(height: int = 37, width: int = 53, seed: int = 7) -> OccupancyGrid:
    rng = np.random.default_rng(seed)
    data = rng.choice(np.array([-1, 0, 100], dtype=np.int8), size=(height, width))
    frame = GridFrame(origin_x=-12.35, origin_y=-7.5, resolution_m=0.05, width=width, height=height)
    return OccupancyGrid(frame, data, storey="Level 1", skill="navigation", elevation_m=3.2)


def corner_grid() -> OccupancyGrid:
    """Asymmetric: only cell (row=0, col=0) (lowest y, lowest x) is occupied; one unknown cell."""
    data = np.zeros((4, 6), dtype=np.int8)
    data[0, 0] = 100
    data[3, 5] = -1
    return OccupancyGrid(GridFrame(1.0, 2.0, 0.1, 6, 4), data, storey="L0", skill="localization")


def read_pgm(path: Path) -> npt.NDArray[np.uint8]:
    """Tiny independent P5 reader for our own files (header without comments after the first)."""
    raw = path.read_bytes()
    lines = raw.split(b"\n", 4)
    assert lines[0] == b"P5"
    assert lines[1].startswith(b"#")
    width, height = (int(v) for v in lines[2].split())
    assert lines[3] == b"255"
    return np.frombuffer(lines[4], dtype=np.uint8).reshape(height, width)


def decode_png(path: Path) -> npt.NDArray[np.uint8]:
    """Tiny independent PNG decoder: 8-bit grayscale, checks CRCs, unfilters filter types 0 and 2."""
    raw = path.read_bytes()
    assert raw[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, header = 8, b"", b""
    kinds = []
    while pos < len(raw):
        (length,) = struct.unpack(">I", raw[pos : pos + 4])
        kind, body = raw[pos + 4 : pos + 8], raw[pos + 8 : pos + 8 + length]
        (crc,) = struct.unpack(">I", raw[pos + 8 + length : pos + 12 + length])
        assert crc == zlib.crc32(kind + body)
        kinds.append(kind)
        if kind == b"IHDR":
            header = body
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    assert kinds[0] == b"IHDR"
    assert kinds[-1] == b"IEND"
    width, height, depth, colour, compression, filtering, interlace = struct.unpack(">IIBBBBB", header)
    assert (depth, colour, compression, filtering, interlace) == (8, 0, 0, 0, 0)
    rows = np.frombuffer(zlib.decompress(idat), dtype=np.uint8).reshape(height, width + 1)
    image = rows[:, 1:].copy()
    for r in range(height):
        assert rows[r, 0] in (0, 2)
        if rows[r, 0] == 2 and r > 0:
            image[r] += image[r - 1]
    return image
