"""ROS 2 adapter, PNG previews: the PGM's colours, top row first, optionally scaled up."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from adapters.ros import write_map_server, write_png_preview
from tests.adapters.ros_samples import corner_grid, decode_png, random_grid, read_pgm
from twin.errors import MapError


def test_png_preview_decodes_to_the_pgm_colours_top_row_first(tmp_path: Path) -> None:
    grid = random_grid()
    pixels = decode_png(write_png_preview(grid, tmp_path / "preview.png"))
    assert np.array_equal(pixels, read_pgm(write_map_server(grid, tmp_path, "same").pgm))
    corner = decode_png(write_png_preview(corner_grid(), tmp_path / "corner.png"))
    assert corner[-1, 0] == 0
    assert corner[0, 5] == 205


def test_png_preview_scales_cells_up_by_nearest_neighbour(tmp_path: Path) -> None:
    path = write_png_preview(corner_grid(), tmp_path / "sub" / "corner.png", scale=3)
    pixels = decode_png(path)
    assert pixels.shape == (12, 18)
    assert (pixels[-3:, :3] == 0).all()
    assert (pixels[:3, -3:] == 205).all()
    assert (pixels == 0).sum() == 9
    with pytest.raises(MapError, match=r"scale must be a positive integer, got 0"):
        write_png_preview(corner_grid(), tmp_path / "x.png", scale=0)
