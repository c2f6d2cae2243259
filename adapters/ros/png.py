"""PNG previews of core grids: 8-bit grayscale in ``map_saver`` colours, written with zlib + struct.

Example::

    write_png_preview(grid, Path("maps/L1__navigation.png"), scale=4)
"""

from __future__ import annotations

import logging
import struct
import zlib
from pathlib import Path

import numpy as np

from adapters.ros._common import trinary_pixels, write_atomic
from twin.errors import MapError
from twin.maps.grid import OccupancyGrid

__all__ = ["png_bytes", "write_png_preview"]

logger = logging.getLogger(__name__)

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _png_chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def png_bytes(grid: OccupancyGrid, *, scale: int = 1) -> bytes:
    """The 8-bit grayscale PNG of ``grid`` (PGM colours, top row = highest y) that
    :func:`write_png_preview` writes."""
    if isinstance(scale, bool) or not isinstance(scale, int) or scale < 1:
        msg = f"PNG preview scale must be a positive integer, got {scale!r}."
        raise MapError(msg)
    pixels = trinary_pixels(grid.data)
    if scale > 1:
        pixels = np.repeat(np.repeat(pixels, scale, axis=0), scale, axis=1)
    height, width = pixels.shape
    rows = np.zeros((height, width + 1), dtype=np.uint8)  # filter byte 0 (None) per row
    rows[:, 1:] = pixels
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)  # 8-bit grayscale, no interlace
    return b"".join(
        [
            _PNG_SIGNATURE,
            _png_chunk(b"IHDR", ihdr),
            # level 1: bounded time on noisy maps (4000x4000 noise: 0.15 s vs 1.5 s at level 6)
            _png_chunk(b"IDAT", zlib.compress(rows.tobytes(), 1)),
            _png_chunk(b"IEND", b""),
        ]
    )


def write_png_preview(grid: OccupancyGrid, path: Path, *, scale: int = 1) -> Path:
    """Write an 8-bit grayscale PNG of ``grid`` (PGM colours, top row = highest y); returns ``path``.

    ``scale`` repeats every cell ``scale x scale`` times (nearest neighbour) so small maps are
    visible; the image is ``(height * scale, width * scale)``. Written with zlib + struct only.

    Example::

        write_png_preview(grid, Path("maps/L1__navigation.png"), scale=4)
    """
    blob = png_bytes(grid, scale=scale)
    if path.parent != Path():
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            msg = f"Cannot create directory for {path}: {exc}"
            raise MapError(msg) from exc
    write_atomic(path, blob)
    logger.debug("Wrote PNG preview %s (%dx%d px)", path, grid.frame.width * scale, grid.frame.height * scale)
    return path
