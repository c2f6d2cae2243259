"""Point-cloud maps where 3D localizers look for them: a binary PCD file and ``sensor_msgs/PointCloud2``.

The PCD file is what PCL's ``pcl::io::loadPCDFile`` reads (``hdl_localization``,
``lidar_localization_ros2``, Autoware's ``pointcloud_map_loader``): PCL's v0.7 header, fields
``x y z`` as float32, ``VIEWPOINT 0 0 0 1 0 0 0``, ``DATA binary``. Coordinates are the map frame's:
world x, y (as in the 2D maps' YAML), z above the storey's elevation.

Offset: float32 keeps half a millimetre up to 8,192 m from the origin. When a cloud's x or y reaches
:data:`OFFSET_LIMIT_M`, the file holds ``x - offset_x, y - offset_y`` with the offset the map frame's
origin (the 2D map's ``origin``, a multiple of the resolution), written in the header's comment line
``# building-twin ... offset_x=<m> offset_y=<m> offset_z=0``; give it to the localizer as the
map -> cloud transform. Below the limit the offset is 0 and the file is in the map frame.

The ``PointCloud2`` (``height 1``, ``width n``, fields ``x y z`` FLOAT32 at 0, 4, 8, ``point_step 12``,
little-endian, dense) carries the same points in the map frame, without offset.

Example::

    files = write_points_files(cloud, Path("maps"), stamp_ns=time.time_ns())
    xyz, offset = read_pcd(files.pcd)            # float32 (n, 3), the file's offset
    payload = encode_point_cloud2(cloud, stamp_ns=0)
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from adapters.ros._common import write_atomic
from adapters.ros.cdr import _deserialize, _header, _serialize, _stamp_ns, _typestore
from twin.errors import MapError
from twin.maps.points import PointCloud

__all__ = [
    "OFFSET_LIMIT_M",
    "POINT_CLOUD2",
    "PointsFiles",
    "decode_point_cloud2",
    "encode_point_cloud2",
    "pcd_bytes",
    "points_offset",
    "read_pcd",
    "write_points_files",
]

logger = logging.getLogger(__name__)

POINT_CLOUD2 = "sensor_msgs/msg/PointCloud2"
OFFSET_LIMIT_M = 8192.0
"""From this distance to the origin on, float32 steps exceed 0.5 mm: PCD files get an offset."""
_FLOAT32 = 7  # sensor_msgs/msg/PointField FLOAT32
_UNSAFE = re.compile(r"[^\w.\-]")


def points_offset(cloud: PointCloud) -> tuple[float, float]:
    """The offset a PCD file of ``cloud`` has: 0 near the origin, else the map frame's origin."""
    if not len(cloud) or float(np.abs(cloud.xyz[:, :2]).max()) < OFFSET_LIMIT_M:
        return (0.0, 0.0)
    return (cloud.frame.origin_x, cloud.frame.origin_y)


def pcd_bytes(cloud: PointCloud) -> bytes:
    """The binary PCD file of ``cloud`` (x, y less :func:`points_offset`)."""
    ox, oy = points_offset(cloud)
    xyz = np.empty((len(cloud), 3), dtype="<f4")
    xyz[:, 0] = cloud.xyz[:, 0] - ox
    xyz[:, 1] = cloud.xyz[:, 1] - oy
    xyz[:, 2] = cloud.xyz[:, 2]
    n = len(cloud)
    header = (
        "# .PCD v0.7 - Point Cloud Data file format\n"
        f"# building-twin storey={_UNSAFE.sub('_', cloud.storey)} skill={_UNSAFE.sub('_', cloud.skill)} "
        f"elevation_m={cloud.elevation_m!r} resolution_m={cloud.resolution_m!r} "
        f"offset_x={ox!r} offset_y={oy!r} offset_z=0\n"
        "VERSION 0.7\n"
        "FIELDS x y z\n"
        "SIZE 4 4 4\n"
        "TYPE F F F\n"
        "COUNT 1 1 1\n"
        f"WIDTH {n}\n"
        "HEIGHT 1\n"
        "VIEWPOINT 0 0 0 1 0 0 0\n"
        f"POINTS {n}\n"
        "DATA binary\n"
    )
    return header.encode("ascii") + xyz.tobytes()


def read_pcd(path: Path) -> tuple[npt.NDArray[np.float32], tuple[float, float]]:
    """Read a binary ``x y z`` float32 PCD file: ``(xyz (n, 3) float32, (offset_x, offset_y))``; the
    offset is 0 unless the building-twin comment gives one. MapError names what is not supported."""
    blob = path.read_bytes()
    pos, fields, n, offset = 0, {}, None, (0.0, 0.0)
    while True:
        end = blob.find(b"\n", pos)
        if end < 0:
            msg = f"{path}: the PCD header has no DATA line."
            raise MapError(msg)
        line = blob[pos:end].decode("ascii", "replace").strip()
        pos = end + 1
        if line.startswith("#"):
            found = dict(re.findall(r"(offset_[xy])=(\S+)", line))
            if found:
                offset = (float(found.get("offset_x", 0.0)), float(found.get("offset_y", 0.0)))
            continue
        key, _, value = line.partition(" ")
        fields[key] = value
        if key == "POINTS":
            n = int(value)
        if key == "DATA":
            break
    wanted = {"FIELDS": "x y z", "SIZE": "4 4 4", "TYPE": "F F F", "DATA": "binary"}
    for key, value in wanted.items():
        if fields.get(key) != value:
            msg = f"{path}: PCD {key} is {fields.get(key)!r}; only {value!r} is read here."
            raise MapError(msg)
    if n is None or len(blob) - pos != 12 * n:
        msg = f"{path}: PCD says {n} points but holds {len(blob) - pos} bytes of data."
        raise MapError(msg)
    return np.frombuffer(blob, dtype="<f4", offset=pos).reshape(n, 3).astype(np.float32), offset


def encode_point_cloud2(cloud: PointCloud, *, stamp_ns: int, frame_id: str = "map") -> bytes:
    """Serialise ``cloud`` as a CDR ``sensor_msgs/msg/PointCloud2`` (x y z float32, map frame)."""
    types = _typestore().types
    field = types["sensor_msgs/msg/PointField"]
    fields = [field(name=name, offset=4 * i, datatype=_FLOAT32, count=1) for i, name in enumerate("xyz")]
    data = np.ascontiguousarray(cloud.xyz, dtype="<f4").view(np.uint8).reshape(-1)
    message = types[POINT_CLOUD2](
        header=_header(stamp_ns, frame_id),
        height=1,
        width=len(cloud),
        fields=fields,
        is_bigendian=False,
        point_step=12,
        row_step=12 * len(cloud),
        data=data,
        is_dense=True,
    )
    return _serialize(message, POINT_CLOUD2)


def decode_point_cloud2(payload: bytes | bytearray | memoryview) -> tuple[npt.NDArray[np.float32], int, str]:
    """Parse a CDR ``sensor_msgs/msg/PointCloud2`` of float32 ``x y z`` (any ``point_step``):
    ``(xyz (n, 3) float32, stamp_ns, frame_id)``; MapError names a layout it cannot read."""
    m: Any = _deserialize(payload, POINT_CLOUD2)
    offsets = {f.name: (int(f.offset), int(f.datatype), int(f.count)) for f in m.fields}
    n = int(m.width) * int(m.height)
    step = int(m.point_step)
    data = np.asarray(m.data, dtype=np.uint8)
    if m.is_bigendian or any(offsets.get(a, (0, 0, 0))[1:] != (_FLOAT32, 1) for a in "xyz"):
        msg = f"{POINT_CLOUD2}: only little-endian FLOAT32 x, y, z fields are read (fields: {offsets})."
        raise MapError(msg)
    if len(data) < n * step:
        msg = f"{POINT_CLOUD2}: {n} points of {step} bytes need {n * step} bytes, the data has {len(data)}."
        raise MapError(msg)
    rows = data[: n * step].reshape(n, step)
    xyz = np.empty((n, 3), dtype=np.float32)
    for i, a in enumerate("xyz"):
        o = offsets[a][0]
        xyz[:, i] = rows[:, o : o + 4].copy().view("<f4").reshape(-1)
    return xyz, _stamp_ns(m.header), str(m.header.frame_id)


@dataclass(frozen=True, slots=True)
class PointsFiles:
    """What :func:`write_points_files` writes for one points map."""

    pcd: Path
    cdr: Path


def write_points_files(
    cloud: PointCloud, out_dir: Path, *, stamp_ns: int, frame_id: str = "map"
) -> PointsFiles:
    """Write ``<storey>__<skill>.pcd`` and ``.cdr`` (the :func:`encode_point_cloud2` payload) into
    ``out_dir``, beside the 2D maps' map_server files (same file naming)."""
    if not cloud.storey or not cloud.skill:
        msg = "Cannot name point-cloud files: the cloud's storey or skill is empty."
        raise MapError(msg)
    stem = f"{_UNSAFE.sub('_', cloud.storey)}__{_UNSAFE.sub('_', cloud.skill)}"
    out_dir.mkdir(parents=True, exist_ok=True)
    pcd = out_dir / f"{stem}.pcd"
    cdr = out_dir / f"{stem}.cdr"
    write_atomic(pcd, pcd_bytes(cloud))
    write_atomic(cdr, encode_point_cloud2(cloud, stamp_ns=stamp_ns, frame_id=frame_id))
    logger.info("Wrote point-cloud files %s.{pcd,cdr} in %s (%d points)", stem, out_dir, len(cloud))
    return PointsFiles(pcd=pcd, cdr=cdr)
