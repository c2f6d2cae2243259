"""Point-cloud maps as 3D localizers read them: the binary PCD file (PCL's header) and the CDR
``sensor_msgs/msg/PointCloud2``, checked against real ROS 2 typesupport (rclpy, the Kilted
``sensor_msgs`` wheel) and its shipped RIHS01 hash."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import PointCloud2 as RosPointCloud2
from sensor_msgs.msg import PointField as RosPointField
from std_msgs.msg import Header

from adapters.ros.pcd import (
    FIELDS,
    NORMAL_FIELDS,
    OFFSET_LIMIT_M,
    POINT_CLOUD2,
    decode_point_cloud2,
    encode_point_cloud2,
    pcd_bytes,
    read_pcd,
    write_points_files,
)
from adapters.ros.rmw_zenoh import type_hash
from tests.adapters.rosidl_build import shipped_hash
from twin.errors import MapError
from twin.maps.grid import GridFrame
from twin.maps.points import PointCloud

STAMP_NS = 1_700_000_123_456_789_012


def padding_of_point_cloud2(frame_id: str, names: Sequence[str]) -> set[int]:
    """Byte positions of our PointCloud2 (fields ``names``) that are CDR alignment padding (offsets after
    the 4-byte encapsulation header): after each string, after ``datatype`` and after ``is_bigendian``."""
    pad: set[int] = set()
    o = 8  # stamp

    def string(text: str) -> None:
        nonlocal o
        o += 4 + len(text.encode()) + 1

    def align(n: int) -> None:
        nonlocal o
        gap = -o % n
        pad.update(range(4 + o, 4 + o + gap))
        o += gap

    string(frame_id)
    align(4)
    o += 4 + 4 + 4  # height, width, the fields' count
    for name in names:
        string(name)
        align(4)
        o += 4 + 1  # offset, datatype
        align(4)
        o += 4  # count
    o += 1  # is_bigendian
    align(4)
    return pad


def _cloud(n: int = 500, *, far: float = 0.0, seed: int = 1) -> PointCloud:
    rng = np.random.default_rng(seed)
    frame = GridFrame(origin_x=far - 3.0, origin_y=far - 4.0, resolution_m=0.1, width=200, height=150)
    xyz = np.column_stack(
        [
            rng.uniform(far - 2.0, far + 15.0, n),
            rng.uniform(far - 3.0, far + 10.0, n),
            rng.uniform(-0.05, 3.0, n),
        ]
    )
    normals = rng.normal(size=(n, 3))
    normals = (normals / np.linalg.norm(normals, axis=1)[:, None]).astype(np.float32)
    return PointCloud("ground floor", "lidar3d", 3.2, 0.1, frame, np.arange(n, dtype=np.int64), xyz, normals)


def test_the_pcd_file_has_pcls_header_and_the_float32_points_and_normals_in_the_map_frame(
    tmp_path: Path,
) -> None:
    cloud = _cloud()
    files = write_points_files(cloud, tmp_path, stamp_ns=STAMP_NS)
    assert files.pcd.name == "ground_floor__lidar3d.pcd" and files.cdr.name == "ground_floor__lidar3d.cdr"
    blob = files.pcd.read_bytes()
    head = blob[: blob.index(b"DATA binary\n") + len(b"DATA binary\n")].decode().splitlines()
    assert [line for line in head if not line.startswith("#")] == [
        "VERSION 0.7",
        "FIELDS x y z normal_x normal_y normal_z",
        "SIZE 4 4 4 4 4 4",
        "TYPE F F F F F F",
        "COUNT 1 1 1 1 1 1",
        "WIDTH 500",
        "HEIGHT 1",
        "VIEWPOINT 0 0 0 1 0 0 0",
        "POINTS 500",
        "DATA binary",
    ]
    assert len(blob) == len("\n".join(head)) + 1 + 24 * 500
    xyz, offset = read_pcd(files.pcd)
    assert offset == (0.0, 0.0)
    np.testing.assert_array_equal(xyz, cloud.xyz.astype(np.float32))
    normals, _ = read_pcd(files.pcd, fields=NORMAL_FIELDS)
    np.testing.assert_array_equal(normals, cloud.normals)
    rows = np.frombuffer(blob[len("\n".join(head)) + 1 :], dtype="<f4").reshape(500, 6)  # interleaved
    np.testing.assert_array_equal(rows[:, 3:], cloud.normals)


def test_far_from_the_origin_the_pcd_holds_points_less_the_documented_offset_to_the_millimetre(
    tmp_path: Path,
) -> None:
    far = 2 * OFFSET_LIMIT_M + 0.123  # a projected CRS easting: float32 steps of 2 mm here
    cloud = _cloud(far=far)
    files = write_points_files(cloud, tmp_path, stamp_ns=0)
    xyz, (ox, oy) = read_pcd(files.pcd)
    assert (ox, oy) == (cloud.frame.origin_x, cloud.frame.origin_y)
    assert "offset_x=" in files.pcd.read_bytes()[:400].decode("ascii", "replace")
    back = xyz.astype(np.float64) + np.array([ox, oy, 0.0])
    assert np.abs(back - cloud.xyz).max() < 1e-5  # without the offset, float32 would lose ~1 mm
    assert np.abs(cloud.xyz.astype(np.float32).astype(np.float64) - cloud.xyz).max() > 2e-4
    np.testing.assert_array_equal(read_pcd(files.pcd, fields=NORMAL_FIELDS)[0], cloud.normals)  # no offset


def test_a_pcd_file_that_is_not_binary_xyz_float32_is_refused_naming_the_field(tmp_path: Path) -> None:
    path = tmp_path / "ascii.pcd"
    path.write_bytes(pcd_bytes(_cloud(3)).replace(b"DATA binary", b"DATA ascii"))
    with pytest.raises(Exception, match="PCD DATA is 'ascii'"):
        read_pcd(path)
    path.write_bytes(pcd_bytes(_cloud(3)).replace(b"normal_y", b"curvature"))
    assert read_pcd(path)[0].shape == (3, 3)  # x y z are there
    with pytest.raises(Exception, match="without normal_y"):
        read_pcd(path, fields=NORMAL_FIELDS)


def test_rclpy_deserializes_our_point_cloud2_to_the_same_points_normals_and_fields() -> None:
    cloud = _cloud()
    payload = encode_point_cloud2(cloud, stamp_ns=STAMP_NS, frame_id="map")
    msg = deserialize_message(payload, RosPointCloud2)
    assert (msg.header.frame_id, msg.header.stamp.sec, msg.header.stamp.nanosec) == (
        "map", STAMP_NS // 10**9, STAMP_NS % 10**9,
    )  # fmt: skip
    assert (msg.height, msg.width, msg.point_step, msg.row_step) == (1, 500, 24, 12000)
    assert [(f.name, f.offset, f.datatype, f.count) for f in msg.fields] == [
        ("x", 0, RosPointField.FLOAT32, 1),
        ("y", 4, RosPointField.FLOAT32, 1),
        ("z", 8, RosPointField.FLOAT32, 1),
        ("normal_x", 12, RosPointField.FLOAT32, 1),
        ("normal_y", 16, RosPointField.FLOAT32, 1),
        ("normal_z", 20, RosPointField.FLOAT32, 1),
    ]
    assert not msg.is_bigendian and msg.is_dense
    rows = np.frombuffer(bytes(msg.data), dtype="<f4").reshape(-1, 6)
    xyz = rows[:, :3]
    np.testing.assert_array_equal(xyz, cloud.xyz.astype(np.float32))
    np.testing.assert_array_equal(rows[:, 3:], cloud.normals)
    again = serialize_message(msg)  # Fast-CDR leaves alignment padding uninitialised: ours is 0 there
    assert len(again) == len(payload)
    differ = [i for i, (a, b) in enumerate(zip(again, payload, strict=True)) if a != b]
    assert set(differ) <= padding_of_point_cloud2("map", FIELDS), differ
    np.testing.assert_array_equal(decode_point_cloud2(again)[0], xyz)
    np.testing.assert_array_equal(decode_point_cloud2(again, fields=NORMAL_FIELDS)[0], cloud.normals)


def test_a_point_cloud2_made_by_rclpy_with_padding_decodes_to_the_same_points() -> None:
    xyz = _cloud(40).xyz.astype(np.float32)
    rows = np.zeros((40, 16), dtype=np.uint8)  # x y z and 4 bytes of something else (intensity)
    rows[:, :12] = xyz.view(np.uint8).reshape(40, 12)
    fields = [
        RosPointField(name=a, offset=4 * i, datatype=RosPointField.FLOAT32, count=1)
        for i, a in enumerate("xyz")
    ]
    fields.append(RosPointField(name="intensity", offset=12, datatype=RosPointField.FLOAT32, count=1))
    msg = RosPointCloud2(
        header=Header(frame_id="map"), height=1, width=40, fields=fields, is_bigendian=False,
        point_step=16, row_step=640, data=rows.reshape(-1).tobytes(), is_dense=True,
    )  # fmt: skip
    back, stamp, frame_id = decode_point_cloud2(serialize_message(msg))
    np.testing.assert_array_equal(back, xyz)
    assert (stamp, frame_id) == (0, "map")


@pytest.mark.parametrize(("z_offset", "step"), [(12, 12), (8, 0)])
def test_a_point_cloud2_whose_field_lies_outside_its_point_step_is_refused_naming_the_field(
    z_offset: int, step: int
) -> None:
    fields = [
        RosPointField(name=a, offset=o, datatype=RosPointField.FLOAT32, count=1)
        for a, o in (("x", 0), ("y", 4), ("z", z_offset))
    ]
    msg = RosPointCloud2(
        header=Header(frame_id="map"), height=1, width=2, fields=fields, is_bigendian=False,
        point_step=step, row_step=2 * step, data=bytes(32), is_dense=True,
    )  # fmt: skip
    with pytest.raises(MapError, match=f"field '[xyz]' at offset [0-9]+ lies outside its point_step {step}"):
        decode_point_cloud2(serialize_message(msg))


def test_the_point_cloud2_hash_equals_the_one_the_sensor_msgs_wheel_ships() -> None:
    assert type_hash(POINT_CLOUD2) == shipped_hash(POINT_CLOUD2)


def test_twin_map_writes_a_points_skill_as_a_pcd_beside_the_2d_maps(tmp_path: Path) -> None:
    store = tmp_path / "store"
    ifc = tmp_path / "lab.ifc"
    cfg = tmp_path / "points.toml"
    cfg.write_text(
        '[skills.lidar3d]\nkind = "points"\nresolution_m = 0.2\n'
        'exclude_types = ["IfcOpeningElement", "IfcFurnishingElement"]\nexclude_materials = ["glass"]\n'
    )

    def twin(*args: str) -> str:
        done = subprocess.run(
            [sys.executable, "-m", "adapters.cli", "--config", str(cfg), *args],
            capture_output=True, text=True, check=False, timeout=300,
        )  # fmt: skip
        assert done.returncode == 0, done.stderr
        return done.stdout

    twin("sample", "lab", str(ifc))
    twin("import", "--store", str(store), str(ifc))
    out = twin(
        "map", "--store", str(store), "--skill", "lidar3d", "--skill", "localization", "--out", str(tmp_path)
    )
    assert "points at 0.2 m" in out
    pcd = next(tmp_path.glob("*__lidar3d.pcd"))
    assert next(tmp_path.glob("*__localization.yaml")).exists()
    xyz, offset = read_pcd(pcd)
    assert len(xyz) > 1000 and offset == (0.0, 0.0)
    assert xyz[:, 2].min() >= -0.05 - 1e-6  # z above the storey: from just below the floor's top
    again = decode_point_cloud2(pcd.with_suffix(".cdr").read_bytes())[0]
    np.testing.assert_array_equal(again, xyz)
    normals = read_pcd(pcd, fields=NORMAL_FIELDS)[0]
    assert np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-6)
    np.testing.assert_array_equal(
        decode_point_cloud2(pcd.with_suffix(".cdr").read_bytes(), fields=NORMAL_FIELDS)[0], normals
    )
