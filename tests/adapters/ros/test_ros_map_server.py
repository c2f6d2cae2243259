"""ROS 2 adapter, nav2 map_server files: YAML + binary PGM written and read in trinary mode."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from adapters.ros import (
    FREE_PIXEL,
    OCCUPIED_PIXEL,
    UNKNOWN_PIXEL,
    read_map_server,
    write_map_server,
)
from tests.adapters.ros_samples import corner_grid, random_grid, read_pgm
from twin.errors import MapError
from twin.maps.grid import GridFrame


def test_map_server_yaml_and_pgm_round_trip_exactly(tmp_path: Path) -> None:
    grid = random_grid()
    files = write_map_server(grid, tmp_path / "maps", "level1")
    assert files.yaml == tmp_path / "maps" / "level1.yaml"
    assert files.pgm == tmp_path / "maps" / "level1.pgm"
    back = read_map_server(files.yaml)
    assert back.frame == grid.frame
    assert np.array_equal(back.data, grid.data)
    assert (back.storey, back.skill, back.elevation_m) == ("Level 1", "navigation", 3.2)


def test_map_server_yaml_has_nav2_keys_and_a_relative_image(tmp_path: Path) -> None:
    files = write_map_server(random_grid(), tmp_path, "level1")
    lines = files.yaml.read_text().splitlines()
    assert lines[0] == '# building-twin map: storey="Level 1" skill="navigation" elevation=3.2'
    assert lines[1:] == [
        "image: level1.pgm",
        "mode: trinary",
        "resolution: 0.05",
        "origin: [-12.35, -7.5, 0.0]",
        "negate: 0",
        "occupied_thresh: 0.65",
        "free_thresh: 0.196",
    ]


def test_pgm_top_row_is_the_grids_last_row(tmp_path: Path) -> None:
    grid = corner_grid()
    pixels = read_pgm(write_map_server(grid, tmp_path, "corner").pgm)
    assert pixels.shape == (4, 6)
    # the occupied cell (row=0, col=0) is the lowest-y, lowest-x cell: the bottom-left pixel
    assert pixels[-1, 0] == OCCUPIED_PIXEL == 0
    assert pixels[0, 5] == UNKNOWN_PIXEL == 205  # (row=3, col=5): top-right
    expected = np.full((4, 6), FREE_PIXEL, np.uint8)
    expected[-1, 0], expected[0, 5] = 0, 205
    assert np.array_equal(pixels, expected)
    # and for a random grid, pixel row 0 shows grid row -1
    big = random_grid()
    rows = read_pgm(write_map_server(big, tmp_path, "big").pgm)
    colours = {-1: 205, 0: 254, 100: 0}
    assert rows[0].tolist() == [colours[int(v)] for v in big.data[-1]]


def test_map_server_reads_absolute_image_paths_header_comments_and_nav2_thresholds(tmp_path: Path) -> None:
    pgm = tmp_path / "img" / "hand.pgm"
    pgm.parent.mkdir()
    # top row: occupied, unknown grey, free; bottom row: mid greys around the thresholds
    pgm.write_bytes(
        b"P5\n# CREATOR: hand\n3 # width\n2\n# maxval next\n255\n" + bytes([0, 205, 254, 90, 100, 200])
    )
    yaml = tmp_path / "hand.yaml"
    yaml.write_text(
        f'image: "{pgm}"  # absolute\nresolution: 0.1\norigin: [1.5, -2.0, 0]\nnegate: 0\n'
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    grid = read_map_server(yaml)
    # p(90) = 0.647 -> unknown, p(100) = 0.608 -> unknown, p(200) = 0.216 -> unknown
    assert grid.data.tolist() == [[-1, -1, -1], [100, -1, 0]]
    assert grid.frame == GridFrame(1.5, -2.0, 0.1, 3, 2)
    assert (grid.storey, grid.skill, grid.elevation_m) == ("", "", 0.0)


def test_nav2_default_free_thresh_reads_unknown_grey_as_free_and_warns(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    files = write_map_server(corner_grid(), tmp_path, "corner")
    text = files.yaml.read_text().replace("free_thresh: 0.196", "free_thresh: 0.25")
    files.yaml.write_text(text)
    with caplog.at_level(logging.WARNING, logger="adapters.ros"):
        grid = read_map_server(files.yaml)
    assert grid.data[3, 5] == 0  # what nav2 map_server does with 205 and free_thresh 0.25
    assert "reads map_saver's unknown grey 205 as free" in caplog.text


def test_negated_maps_swap_black_and_white(tmp_path: Path) -> None:
    files = write_map_server(corner_grid(), tmp_path, "corner")
    files.yaml.write_text(files.yaml.read_text().replace("negate: 0", "negate: 1"))
    grid = read_map_server(files.yaml)
    assert grid.data[0, 0] == 0  # black is free when negated
    assert grid.data[1, 1] == 100  # 254 -> p = 0.996 -> occupied


def test_stem_with_spaces_is_quoted_in_the_yaml(tmp_path: Path) -> None:
    files = write_map_server(corner_grid(), tmp_path, "my map #2")
    assert 'image: "my map #2.pgm"' in files.yaml.read_text()
    assert np.array_equal(read_map_server(files.yaml).data, corner_grid().data)


def test_corrupt_pgm_raises_map_error(tmp_path: Path) -> None:
    files = write_map_server(corner_grid(), tmp_path, "corner")
    good = files.pgm.read_bytes()
    files.pgm.write_bytes(good[:-3])
    with pytest.raises(
        MapError, match=r"corner\.pgm: PGM size mismatch: header says 6x4 pixels \(24 bytes\)"
    ):
        read_map_server(files.yaml)
    files.pgm.write_bytes(b"P2" + good[2:])
    with pytest.raises(MapError, match=r"corner\.pgm: not a binary PGM \(magic b'P2'"):
        read_map_server(files.yaml)
    files.pgm.write_bytes(b"P5\n6 x\n255\n")
    with pytest.raises(MapError, match=r"corner\.pgm: malformed PGM header"):
        read_map_server(files.yaml)
    files.pgm.write_bytes(b"P5\n2 1\n100\n" + bytes([50, 200]))
    with pytest.raises(MapError, match=r"corner\.pgm: PGM has pixel values above its maxval 100"):
        read_map_server(files.yaml)


def test_bad_map_yaml_raises_map_error_naming_the_file(tmp_path: Path) -> None:
    files = write_map_server(corner_grid(), tmp_path, "corner")
    good = files.yaml.read_text()
    files.yaml.write_text(good.replace("free_thresh: 0.196\n", ""))
    with pytest.raises(MapError, match=r"corner\.yaml: missing map_server key\(s\) free_thresh"):
        read_map_server(files.yaml)
    files.yaml.write_text(good.replace("image: corner.pgm", "image: gone.pgm"))
    with pytest.raises(MapError, match=r"corner\.yaml: map image .*gone\.pgm does not exist"):
        read_map_server(files.yaml)
    files.yaml.write_text(good.replace("mode: trinary", "mode: scale"))
    with pytest.raises(MapError, match=r"corner\.yaml: mode 'scale' is not supported"):
        read_map_server(files.yaml)
    files.yaml.write_text(good.replace("origin: [1.0, 2.0, 0.0]", "origin: [1.0, 2.0, 0.5]"))
    with pytest.raises(MapError, match=r"corner\.yaml: origin yaw 0\.5 is not supported"):
        read_map_server(files.yaml)
    files.yaml.write_text(good.replace("resolution: 0.1", "resolution: fine"))
    with pytest.raises(MapError, match=r"corner\.yaml: 'resolution' must be a number, got 'fine'"):
        read_map_server(files.yaml)
    files.yaml.write_text(good.replace("resolution: 0.1", "resolution: -0.1"))
    with pytest.raises(
        MapError, match=r"corner\.yaml: invalid map frame: Grid resolution must be a positive number"
    ):
        read_map_server(files.yaml)
    with pytest.raises(MapError, match=r"Cannot read map YAML .*nothing\.yaml"):
        read_map_server(tmp_path / "nothing.yaml")
    with pytest.raises(MapError, match=r"stem must be a plain file name, got '\.\./up'"):
        write_map_server(corner_grid(), tmp_path, "../up")
