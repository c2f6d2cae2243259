"""ROS 2 adapter, the file bundle of one map: YAML, PGM, PNG and CDR named after storey and skill."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from adapters.ros import (
    MapFiles,
    decode_occupancy_grid,
    encode_occupancy_grid,
    read_map_server,
    write_map_files,
)
from tests.adapters.ros_samples import STAMP_NS, decode_png, random_grid, read_pgm
from twin.errors import MapError
from twin.maps.grid import GridFrame, OccupancyGrid


def test_map_files_bundle_writes_yaml_pgm_png_and_cdr(tmp_path: Path) -> None:
    grid = random_grid()
    files = write_map_files(grid, tmp_path, stamp_ns=STAMP_NS, frame_id="map")
    assert isinstance(files, MapFiles)
    assert [p.name for p in (files.yaml, files.pgm, files.png, files.cdr)] == [
        "Level_1__navigation.yaml",
        "Level_1__navigation.pgm",
        "Level_1__navigation.png",
        "Level_1__navigation.cdr",
    ]
    assert files.cdr.read_bytes() == encode_occupancy_grid(grid, stamp_ns=STAMP_NS)
    back, stamp_ns = decode_occupancy_grid(files.cdr.read_bytes())
    assert (stamp_ns, back.frame) == (STAMP_NS, grid.frame)
    assert np.array_equal(read_map_server(files.yaml).data, grid.data)
    assert np.array_equal(decode_png(files.png), read_pgm(files.pgm))
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        p.name for p in (files.yaml, files.pgm, files.png, files.cdr)
    )  # no temporary files left behind


def test_map_files_need_a_storey_and_a_skill(tmp_path: Path) -> None:
    grid = OccupancyGrid(GridFrame(0.0, 0.0, 0.05, 2, 2), np.zeros((2, 2), np.int8), "", "navigation")
    with pytest.raises(MapError, match=r"the grid's storey is empty"):
        write_map_files(grid, tmp_path, stamp_ns=0)


def test_metadata_with_quotes_and_unusual_names_round_trips(tmp_path: Path) -> None:
    grid = OccupancyGrid(
        GridFrame(0.0, 0.0, 0.05, 2, 2), np.zeros((2, 2), np.int8), 'Ground "A" #1 / Ost', "nav ß", -0.25
    )
    files = write_map_files(grid, tmp_path, stamp_ns=0)
    assert files.yaml.name == "Ground__A___1___Ost__nav_ß.yaml"
    back = read_map_server(files.yaml)
    assert (back.storey, back.skill, back.elevation_m) == ('Ground "A" #1 / Ost', "nav ß", -0.25)
