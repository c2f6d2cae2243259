"""Maps as tiles: what makes every recorded version exact and a change cost the tiles it touched.

A map is cut in ``TILE`` x ``TILE`` cells, each tile its own entity
``maps/<storey>/<skill>/tiles/r<i>_c<j>`` holding an ``rr.GridMap``. The tile's placement (image format,
cell size, origin in the building's frame at the storey's elevation, RViz map colours) is logged once,
static; the cells (``GridMap:data``) are logged when the map first appears and again at every revision
that changes one of them. So at any point of the ``revision`` timeline the stock viewer shows exactly
the map the daemon served then, and a change costs one data row per touched tile (~200 bytes
compressed), not the map.

A map whose frame changes (its extent or resolution) starts a new *generation* of tiles,
``tiles_<g>/``, and the previous generation is cleared at that revision: a static placement is never
overwritten, so older revisions keep showing the older frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import rerun as rr

from twin.maps.grid import GridData, GridFrame, OccupancyGrid, Window

TILE = 128
"""Cells per side of a recorded map tile."""


def tiles_of(window: Window) -> list[tuple[int, int]]:
    """``(i, j)`` of every tile ``window`` touches."""
    return [
        (i, j)
        for i in range(window.row0 // TILE, (window.row1 - 1) // TILE + 1)
        for j in range(window.col0 // TILE, (window.col1 - 1) // TILE + 1)
    ]


def tiles_path(storey: str, skill: str, generation: int) -> str:
    """The entity under which one generation of a map's tiles is logged."""
    return f"maps/{storey}/{skill}/tiles" + (f"_{generation}" if generation else "")


@dataclass(frozen=True, slots=True)
class MapMark:
    """A full map version the recorder already holds (equal to its updates applied): only its version
    and revision are recorded. The sink sends this instead of the whole grid."""

    storey: str
    skill: str
    revision: int
    version: int
    stamp_ns: int


class MapTiles:
    """The recorder's copy of one map (updates applied): what its tiles show, and their logging."""

    def __init__(self, grid: OccupancyGrid, generation: int) -> None:
        self.grid = OccupancyGrid(grid.frame, grid.data.copy(), grid.storey, grid.skill, grid.elevation_m)
        self.generation = generation
        self.path = tiles_path(grid.storey, grid.skill, generation)

    @property
    def frame(self) -> GridFrame:
        return self.grid.frame

    def place(self, stream: rr.RecordingStream) -> None:
        """Log every tile's placement, static: once per file."""
        g, f = self.grid, self.grid.frame
        for i, j in tiles_of(f.full):
            r0, c0 = i * TILE, j * TILE
            h, w = min(TILE, f.height - r0), min(TILE, f.width - c0)
            stream.log(
                f"{self.path}/r{i}_c{j}",
                rr.GridMap.from_fields(
                    format=rr.components.ImageFormat(
                        width=w, height=h, color_model="L", channel_datatype="U8"
                    ),
                    cell_size=f.resolution_m,
                    # Rerun draws an image's row 0 at the far (+y) edge, the twin's row 0 is the lowest
                    # y: a half turn about x puts every cell on its world cell without touching the data.
                    translation=[
                        f.origin_x + c0 * f.resolution_m,
                        f.origin_y + (r0 + h) * f.resolution_m,
                        g.elevation_m,
                    ],
                    rotation_axis_angle=rr.RotationAxisAngle(axis=[1.0, 0.0, 0.0], degrees=180.0),
                    colormap=rr.components.Colormap.RvizMap,
                ),
                static=True,
            )

    def log(self, stream: rr.RecordingStream, tiles: list[tuple[int, int]]) -> None:
        """Log the cells of ``tiles`` as they are now (at the stream's current revision)."""
        for i, j in tiles:
            cells = self.grid.data[i * TILE : (i + 1) * TILE, j * TILE : (j + 1) * TILE]
            stream.log(
                f"{self.path}/r{i}_c{j}",
                rr.GridMap.from_fields(
                    data=np.ascontiguousarray(cells).view(np.uint8).tobytes()
                ),  # -1 is 255
            )

    def apply(self, window: Window, data: GridData) -> list[tuple[int, int]]:
        """Apply an update; the tiles it touched."""
        self.grid.data[window.row0 : window.row1, window.col0 : window.col1] = data
        return tiles_of(window)

    def replace(self, data: GridData) -> list[tuple[int, int]]:
        """Take a full version of the same frame; the tiles that differ (none, normally)."""
        diff = np.argwhere(self.grid.data != data)
        self.grid.data[...] = data
        return sorted({(int(r) // TILE, int(c) // TILE) for r, c in diff})
