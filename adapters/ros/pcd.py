"""Point-cloud maps where 3D localizers look for them: a binary PCD file and ``sensor_msgs/PointCloud2``.

The PCD file is what PCL's ``pcl::io::loadPCDFile`` reads (``hdl_localization``,
``lidar_localization_ros2``, Autoware's ``pointcloud_map_loader``): PCL's v0.7 header, fields
``x y z normal_x normal_y normal_z`` as float32 (PCL's ``PointNormal`` names; a loader into ``PointXYZ``
matches fields by name and skips the normals), ``VIEWPOINT 0 0 0 1 0 0 0``, ``DATA binary``.
Coordinates are the map frame's: world x, y (as in the 2D maps' YAML), z above the storey's elevation;
the normals are unit vectors, outward from the elements' closed surfaces (zero on a degenerate
triangle).

Offset: float32 keeps half a millimetre up to 8,192 m from the origin. When a cloud's x or y reaches
:data:`OFFSET_LIMIT_M`, the file holds ``x - offset_x, y - offset_y`` with the offset the map frame's
origin (the 2D map's ``origin``, a multiple of the resolution), written in the header's comment line
``# building-twin ... offset_x=<m> offset_y=<m> offset_z=0``; give it to the localizer as the
map -> cloud transform. Below the limit the offset is 0 and the file is in the map frame.

The ``PointCloud2`` (``height 1``, ``width n``, fields ``x y z normal_x normal_y normal_z`` FLOAT32 at
0, 4, ..., 20, ``point_step 24``, little-endian, dense) carries the same points and normals in the map
frame, without offset.

Example::

    files = write_points_files(cloud, Path("maps"), stamp_ns=time.time_ns())
    xyz, offset = read_pcd(files.pcd)            # float32 (n, 3), the file's offset
    normals, _ = read_pcd(files.pcd, fields=NORMAL_FIELDS)
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
    "FIELDS",
    "NORMAL_FIELDS",
    "OFFSET_LIMIT_M",
    "POINT_CLOUD2",
    "PointsFiles",
    "decode_point_cloud2",
    "encode_point_cloud2",
    "pcd_bytes",
    "pcd_of_points",
    "points_offset",
    "read_pcd",
    "write_points_files",
]

logger = logging.getLogger(__name__)

POINT_CLOUD2 = "sensor_msgs/msg/PointCloud2"
OFFSET_LIMIT_M = 8192.0
"""From this distance to the origin on, float32 steps exceed 0.5 mm: PCD files get an offset."""
NORMAL_FIELDS = ("normal_x", "normal_y", "normal_z")
FIELDS = ("x", "y", "z", *NORMAL_FIELDS)
"""Every point's fields, float32 each, in files and messages (PCL's ``PointNormal`` names)."""
_FLOAT32 = 7  # sensor_msgs/msg/PointField FLOAT32
_UNSAFE = re.compile(r"[^\w.\-]")


def points_offset(cloud: PointCloud) -> tuple[float, float]:
    """The offset a PCD file of ``cloud`` has: 0 near the origin, else the map frame's origin."""
    if not len(cloud) or float(np.abs(cloud.xyz[:, :2]).max()) < OFFSET_LIMIT_M:
        return (0.0, 0.0)
    return (cloud.frame.origin_x, cloud.frame.origin_y)


def pcd_bytes(cloud: PointCloud) -> bytes:
    """The binary PCD file of ``cloud`` (x, y less :func:`points_offset`; normals)."""
    ox, oy = points_offset(cloud)
    comment = (
        f"building-twin storey={_UNSAFE.sub('_', cloud.storey)} skill={_UNSAFE.sub('_', cloud.skill)} "
        f"elevation_m={cloud.elevation_m!r} resolution_m={cloud.resolution_m!r} "
        f"offset_x={ox!r} offset_y={oy!r} offset_z=0"
    )
    return _pcd(_rows(cloud, ox, oy), comment)


def pcd_of_points(xyz: npt.ArrayLike, normals: npt.ArrayLike, *, comment: str) -> bytes:
    """A binary PCD file of points as received (``xyz``, ``normals``: ``(n, 3)``; no offset), its header's
    comment line ``# <comment>`` (e.g. the topic they came from)."""
    rows = np.concatenate([np.asarray(xyz, "<f4"), np.asarray(normals, "<f4")], axis=1)
    return _pcd(rows, " ".join(comment.split()) + " offset_x=0.0 offset_y=0.0 offset_z=0")


def _pcd(rows: npt.NDArray[np.float32], comment: str) -> bytes:
    n = len(rows)
    header = (
        "# .PCD v0.7 - Point Cloud Data file format\n"
        f"# {comment}\n"
        "VERSION 0.7\n"
        f"FIELDS {' '.join(FIELDS)}\n"
        f"SIZE {' '.join('4' for _ in FIELDS)}\n"
        f"TYPE {' '.join('F' for _ in FIELDS)}\n"
        f"COUNT {' '.join('1' for _ in FIELDS)}\n"
        f"WIDTH {n}\n"
        "HEIGHT 1\n"
        "VIEWPOINT 0 0 0 1 0 0 0\n"
        f"POINTS {n}\n"
        "DATA binary\n"
    )
    return header.encode("ascii") + np.ascontiguousarray(rows, dtype="<f4").tobytes()


def _rows(cloud: PointCloud, ox: float, oy: float) -> npt.NDArray[np.float32]:
    """The cloud's :data:`FIELDS` per point, little-endian float32 ``(n, 6)`` (x, y less the offset)."""
    out = np.empty((len(cloud), len(FIELDS)), dtype="<f4")
    out[:, 0] = cloud.xyz[:, 0] - ox
    out[:, 1] = cloud.xyz[:, 1] - oy
    out[:, 2] = cloud.xyz[:, 2]
    out[:, 3:] = cloud.normals
    return out


def read_pcd(
    path: Path, *, fields: tuple[str, ...] = ("x", "y", "z")
) -> tuple[npt.NDArray[np.float32], tuple[float, float]]:
    """Read ``fields`` (default ``x y z``; :data:`NORMAL_FIELDS` for the normals) of a binary float32
    PCD file: ``(values (n, len(fields)) float32, (offset_x, offset_y))``; the offset is 0 unless the
    building-twin comment gives one. MapError names what is not supported or missing."""
    blob = path.read_bytes()
    pos, header, n, offset = 0, {}, None, (0.0, 0.0)
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
        header[key] = value
        if key == "POINTS":
            n = int(value)
        if key == "DATA":
            break
    names = header.get("FIELDS", "").split()
    k = len(names)
    wanted = {"SIZE": " ".join(["4"] * k), "TYPE": " ".join(["F"] * k), "DATA": "binary"}
    for key, value in wanted.items():
        if header.get(key) != value:
            msg = f"{path}: PCD {key} is {header.get(key)!r}; only {value!r} (float32 fields) is read here."
            raise MapError(msg)
    missing = [f for f in fields if f not in names]
    if missing or not k:
        msg = f"{path}: PCD FIELDS are {header.get('FIELDS')!r}, without {' '.join(missing or fields)}."
        raise MapError(msg)
    if n is None or len(blob) - pos != 4 * k * n:
        msg = f"{path}: PCD says {n} points but holds {len(blob) - pos} bytes of data."
        raise MapError(msg)
    data = np.frombuffer(blob, dtype="<f4", offset=pos).reshape(n, k)
    return data[:, [names.index(f) for f in fields]].astype(np.float32), offset


def encode_point_cloud2(cloud: PointCloud, *, stamp_ns: int, frame_id: str = "map") -> bytes:
    """Serialise ``cloud`` as a CDR ``sensor_msgs/msg/PointCloud2`` (:data:`FIELDS` float32, map frame)."""
    types = _typestore().types
    field = types["sensor_msgs/msg/PointField"]
    fields = [field(name=name, offset=4 * i, datatype=_FLOAT32, count=1) for i, name in enumerate(FIELDS)]
    step = 4 * len(FIELDS)
    data = _rows(cloud, 0.0, 0.0).view(np.uint8).reshape(-1)
    message = types[POINT_CLOUD2](
        header=_header(stamp_ns, frame_id),
        height=1,
        width=len(cloud),
        fields=fields,
        is_bigendian=False,
        point_step=step,
        row_step=step * len(cloud),
        data=data,
        is_dense=True,
    )
    return _serialize(message, POINT_CLOUD2)


def decode_point_cloud2(
    payload: bytes | bytearray | memoryview, *, fields: tuple[str, ...] = ("x", "y", "z")
) -> tuple[npt.NDArray[np.float32], int, str]:
    """Parse a CDR ``sensor_msgs/msg/PointCloud2``'s float32 ``fields`` (default ``x y z``; any
    ``point_step``): ``(values (n, len(fields)) float32, stamp_ns, frame_id)``; MapError names a layout
    it cannot read."""
    m: Any = _deserialize(payload, POINT_CLOUD2)
    offsets = {f.name: (int(f.offset), int(f.datatype), int(f.count)) for f in m.fields}
    n = int(m.width) * int(m.height)
    step = int(m.point_step)
    data = np.asarray(m.data, dtype=np.uint8)
    if m.is_bigendian or any(offsets.get(a, (0, 0, 0))[1:] != (_FLOAT32, 1) for a in fields):
        msg = (
            f"{POINT_CLOUD2}: only little-endian FLOAT32 {', '.join(fields)} fields are read "
            f"(fields: {offsets})."
        )
        raise MapError(msg)
    outside = [a for a in fields if offsets[a][0] + 4 > step]
    if n and outside:
        where = offsets[outside[0]][0]
        msg = f"{POINT_CLOUD2}: field {outside[0]!r} at offset {where} lies outside its point_step {step}."
        raise MapError(msg)
    if len(data) < n * step:
        msg = f"{POINT_CLOUD2}: {n} points of {step} bytes need {n * step} bytes, the data has {len(data)}."
        raise MapError(msg)
    rows = data[: n * step].reshape(n, step)
    out = np.empty((n, len(fields)), dtype=np.float32)
    for i, a in enumerate(fields):
        o = offsets[a][0]
        out[:, i] = rows[:, o : o + 4].copy().view("<f4").reshape(-1)
    return out, _stamp_ns(m.header), str(m.header.frame_id)


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
