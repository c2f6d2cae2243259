"""ROS 2 adapter: CDR messages (nav_msgs/OccupancyGrid, map_msgs/OccupancyGridUpdate) and nav2 files."""

from __future__ import annotations

import contextlib
import logging
import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from adapters.ros import (
    FREE_PIXEL,
    OCCUPIED_PIXEL,
    UNKNOWN_PIXEL,
    MapFiles,
    apply_update,
    decode_occupancy_grid,
    decode_occupancy_grid_update,
    encode_occupancy_grid,
    encode_occupancy_grid_update,
    read_map_server,
    write_map_files,
    write_map_server,
    write_png_preview,
)
from twin.errors import MapError
from twin.grid import GridFrame, OccupancyGrid, Window

STAMP_NS = 1_700_000_123_456_789_012
UPDATE_MSG = "std_msgs/Header header\nint32 x\nint32 y\nuint32 width\nuint32 height\nint8[] data\n"


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


# ------------------------------------------------------------------------------------- CDR: grid


def test_occupancy_grid_round_trips_through_cdr_with_frame_data_and_stamp() -> None:
    grid = random_grid()
    payload = encode_occupancy_grid(grid, stamp_ns=STAMP_NS)
    back, stamp_ns = decode_occupancy_grid(payload, storey="Level 1", skill="navigation", elevation_m=3.2)
    assert stamp_ns == STAMP_NS
    assert back.frame == grid.frame  # 0.05 survives the float32 trip exactly
    assert back.frame.resolution_m == 0.05
    assert back.data.dtype == np.int8
    assert np.array_equal(back.data, grid.data)
    assert (back.storey, back.skill, back.elevation_m) == ("Level 1", "navigation", 3.2)


def test_rosbags_reads_our_occupancy_grid_bytes_independently() -> None:
    grid = random_grid()
    payload = encode_occupancy_grid(grid, stamp_ns=STAMP_NS, frame_id="building")
    msg: Any = get_typestore(Stores.ROS2_HUMBLE).deserialize_cdr(payload, "nav_msgs/msg/OccupancyGrid")
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1_700_000_123, 456_789_012)
    assert msg.header.frame_id == "building"
    assert (msg.info.map_load_time.sec, msg.info.map_load_time.nanosec) == (1_700_000_123, 456_789_012)
    assert msg.info.resolution == pytest.approx(0.05, abs=1e-8)
    assert (msg.info.width, msg.info.height) == (53, 37)
    pos, q = msg.info.origin.position, msg.info.origin.orientation
    assert (pos.x, pos.y, pos.z) == (-12.35, -7.5, 0.0)
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)
    # row-major from the origin row, exactly nav_msgs' layout: no flipping
    assert np.array_equal(msg.data, grid.data.reshape(-1))
    assert msg.data[0] == grid.data[0, 0]
    assert msg.data[53] == grid.data[1, 0]


def test_negative_stamp_and_other_resolutions_round_trip() -> None:
    frame = GridFrame(0.0, -1.0, 0.025, 3, 2)
    grid = OccupancyGrid(frame, np.array([[0, 100, -1], [-1, -1, 0]], np.int8), "s", "k")
    back, stamp_ns = decode_occupancy_grid(encode_occupancy_grid(grid, stamp_ns=-1), storey="s", skill="k")
    assert stamp_ns == -1
    assert back.frame == frame


def test_truncated_occupancy_grid_payload_raises_map_error() -> None:
    payload = encode_occupancy_grid(random_grid(), stamp_ns=STAMP_NS)
    for cut in (0, 3, 10, 60, len(payload) - 5):
        with pytest.raises(MapError, match=r"Malformed nav_msgs/msg/OccupancyGrid CDR payload"):
            decode_occupancy_grid(payload[:cut])


def test_payload_of_the_wrong_type_raises_map_error() -> None:
    update = encode_occupancy_grid_update(random_grid(), Window(0, 0, 2, 2), stamp_ns=0)
    with pytest.raises(MapError, match=r"Malformed nav_msgs/msg/OccupancyGrid CDR payload"):
        decode_occupancy_grid(update)
    with pytest.raises(MapError, match=r"must be bytes, got str"):
        decode_occupancy_grid("not bytes")  # type: ignore[arg-type]


def test_foreign_grids_that_the_core_cannot_hold_raise_map_error() -> None:
    store = get_typestore(Stores.ROS2_HUMBLE)
    t = {
        name: store.types[full]
        for name, full in [
            ("Time", "builtin_interfaces/msg/Time"),
            ("Pose", "geometry_msgs/msg/Pose"),
            ("Point", "geometry_msgs/msg/Point"),
            ("Quaternion", "geometry_msgs/msg/Quaternion"),
        ]
    }

    def payload(data: list[int], q: tuple[float, ...] = (0, 0, 0, 1), width: int = 2) -> bytes:
        pose = t["Pose"](t["Point"](0.0, 0.0, 0.0), t["Quaternion"](*q))
        info = store.types["nav_msgs/msg/MapMetaData"](t["Time"](0, 0), 0.05, width, 1, pose)
        header = store.types["std_msgs/msg/Header"](t["Time"](0, 0), "map")
        msg = store.types["nav_msgs/msg/OccupancyGrid"](header, info, np.array(data, dtype=np.int8))
        return bytes(store.serialize_cdr(msg, "nav_msgs/msg/OccupancyGrid"))

    with pytest.raises(MapError, match=r"has 3 cells, but its info says 2x1 = 2"):
        decode_occupancy_grid(payload([0, 0, 0]))
    with pytest.raises(MapError, match=r"origin is rotated"):
        decode_occupancy_grid(payload([0, 0], q=(0.0, 0.0, 0.7071, 0.7071)))
    with pytest.raises(MapError, match=r"cell values other than -1, 0, 100 \(e.g. \[37\]\)"):
        decode_occupancy_grid(payload([0, 37]))
    with pytest.raises(MapError, match=r"invalid frame: Grid size must be positive"):
        decode_occupancy_grid(payload([], width=0))


def test_encoding_rejects_stamps_that_do_not_fit_ros_time() -> None:
    with pytest.raises(MapError, match=r"does not fit builtin_interfaces/Time"):
        encode_occupancy_grid(random_grid(), stamp_ns=2**31 * 1_000_000_000)
    with pytest.raises(MapError, match=r"stamp_ns must be integer nanoseconds, got 1.5"):
        encode_occupancy_grid(random_grid(), stamp_ns=1.5)  # type: ignore[arg-type]


# ----------------------------------------------------------------------------------- CDR: update


def test_occupancy_grid_update_round_trips_and_applies() -> None:
    source = random_grid(seed=1)
    target = random_grid(seed=2)
    window = Window(row0=5, col0=11, row1=9, col1=18)
    payload = encode_occupancy_grid_update(source, window, stamp_ns=STAMP_NS)
    back_window, cells, stamp_ns = decode_occupancy_grid_update(payload)
    assert (back_window, stamp_ns) == (window, STAMP_NS)
    assert cells.dtype == np.int8
    assert np.array_equal(cells, source.data[5:9, 11:18])

    patched = apply_update(target, back_window, cells)
    expected = target.data.copy()
    expected[5:9, 11:18] = source.data[5:9, 11:18]
    assert np.array_equal(patched.data, expected)
    assert patched.frame == target.frame
    assert (patched.storey, patched.skill, patched.elevation_m) == ("Level 1", "navigation", 3.2)
    assert not np.array_equal(target.data, patched.data)  # the input grid is left alone


def test_rosbags_reads_our_update_bytes_independently() -> None:
    grid = random_grid()
    payload = encode_occupancy_grid_update(grid, Window(2, 3, 4, 8), stamp_ns=STAMP_NS, frame_id="map")
    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(UPDATE_MSG, "map_msgs/msg/OccupancyGridUpdate"))
    msg: Any = store.deserialize_cdr(payload, "map_msgs/msg/OccupancyGridUpdate")
    assert (msg.x, msg.y, msg.width, msg.height) == (3, 2, 5, 2)
    assert msg.header.frame_id == "map"
    assert np.array_equal(msg.data, grid.data[2:4, 3:8].reshape(-1))


def test_update_windows_outside_the_grid_or_misshapen_data_raise_map_error() -> None:
    grid = random_grid()  # 37 x 53
    with pytest.raises(MapError, match=r"Window\(row0=30, col0=0, row1=40, col1=5\) is not inside the 37x53"):
        encode_occupancy_grid_update(grid, Window(30, 0, 40, 5), stamp_ns=0)
    with pytest.raises(MapError, match=r"empty Window"):
        encode_occupancy_grid_update(grid, Window(3, 3, 3, 5), stamp_ns=0)
    with pytest.raises(MapError, match=r"Cannot apply .*Window\(row0=-1, col0=0, row1=1, col1=2\)"):
        apply_update(grid, Window(-1, 0, 1, 2), np.zeros((2, 2), np.int8))
    with pytest.raises(MapError, match=r"shape \(3, 2\), but Window\(row0=0, col0=0, row1=2, col1=2\)"):
        apply_update(grid, Window(0, 0, 2, 2), np.zeros((3, 2), np.int8))
    with pytest.raises(MapError, match=r"must be int8, got float64"):
        apply_update(grid, Window(0, 0, 2, 2), np.zeros((2, 2)))


def test_truncated_update_payload_raises_map_error() -> None:
    payload = encode_occupancy_grid_update(random_grid(), Window(0, 0, 3, 3), stamp_ns=0)
    with pytest.raises(MapError, match=r"Malformed map_msgs/msg/OccupancyGridUpdate CDR payload"):
        decode_occupancy_grid_update(payload[:-12])


# ------------------------------------------------------------------------------------ nav2 files


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


def test_metadata_with_quotes_and_unusual_names_round_trips(tmp_path: Path) -> None:
    grid = OccupancyGrid(
        GridFrame(0.0, 0.0, 0.05, 2, 2), np.zeros((2, 2), np.int8), 'Ground "A" #1 / Ost', "nav ß", -0.25
    )
    files = write_map_files(grid, tmp_path, stamp_ns=0)
    assert files.yaml.name == "Ground__A___1___Ost__nav_ß.yaml"
    back = read_map_server(files.yaml)
    assert (back.storey, back.skill, back.elevation_m) == ('Ground "A" #1 / Ost', "nav ß", -0.25)


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


# --------------------------------------------------------------------------------- PNG and bundle


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


def test_corrupted_cdr_bytes_only_ever_raise_map_error() -> None:
    rng = np.random.default_rng(3)
    grid = random_grid(4, 5)
    cases = [
        (encode_occupancy_grid(grid, stamp_ns=7), decode_occupancy_grid),
        (encode_occupancy_grid_update(grid, Window(0, 0, 2, 2), stamp_ns=7), decode_occupancy_grid_update),
    ]
    for payload, decode in cases:
        for _ in range(300):
            corrupt = bytearray(payload)
            for _ in range(int(rng.integers(1, 4))):
                corrupt[int(rng.integers(0, len(corrupt)))] = int(rng.integers(0, 256))
            corrupt = corrupt[: int(rng.integers(len(corrupt) // 2, len(corrupt) + 1))]
            with contextlib.suppress(MapError):  # anything else would fail the test
                decode(bytes(corrupt))  # type: ignore[operator]
