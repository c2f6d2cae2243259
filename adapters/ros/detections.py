"""``vision_msgs/msg/Detection3DArray`` -> one observation: boxes on the robot's storey and the view its
sensor had.

For each detection, its best hypothesis (highest ``score``) is looked up in the robot's class table
(``class_id`` -> IFC class): an unknown class or a score under the threshold is ignored and counted.
Its ``bbox`` (centre pose, size) is taken to the map frame through the robot's TF at the stamp; a
small roll and pitch are dropped, a box tilted beyond ``max_tilt_rad`` is refused. ``id`` (a tracker's
id) makes a stable robot IRI ``urn:twin-ros:<robot>:det:s<session>:<id>`` (:mod:`adapters.ros.sessions`),
so a tracked object is one element;
an empty ``id`` gets a one-off IRI (``once:<stamp>-<index>``), never reused. The array's
``header.stamp`` is the sense time, and the view is what the camera saw
(:func:`~adapters.ros.view.camera_view`): the floor where its frustum (the sensor frame's pose from TF,
pitch and roll included; ``optical`` says whether that frame looks along +z or +x; the horizontal and
vertical field of view configured or from ``sensor_msgs/CameraInfo``) holds the band of heights of what
it detects, beyond its near blind zone and within its range, cut by the building's structure and by
the footprint of every detection of the array, of any class and score (what stands behind a person is
not seen). The view carries the sensor's position (``twin:origin``), so the twin also leaves out what
the elements it holds hide; and the classes of the table as what the detector reports.

A view is only claimed when every detection could be placed: if one of a known class was refused (a
bad pose, a tilted box), or any detection's frame does not resolve (its shadow is unknown), the boxes
go without a view, so nothing the robot did see collects a miss.

Example::

    t = translate_detections(payload, settings, context)
    t.document   # b"@prefix twin: ... <urn:twin-ros:robot1:det:7> twin:ifcClass ..."
"""

from __future__ import annotations

import logging
import math
import struct
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple

import numpy as np
import numpy.typing as npt

from adapters.ros.cdr import _deserialize
from adapters.ros.cdr_le import TIME, U32, body, ends_at, read_string
from adapters.ros.interfaces import CAMERA_INFO, DETECTION_3D_ARRAY
from adapters.ros.observation_doc import (
    BoxReport,
    RosInputError,
    Translation,
    ViewReport,
    observation_records,
    observation_turtle,
    robot_iri,
)
from adapters.ros.sessions import TrackerSession, session_iri
from adapters.ros.settings import DetectionConfig
from adapters.ros.tf import Matrix, TfBuffer, TfError, matrix
from adapters.ros.view import Camera, Structure, ViewCache, camera_view
from twin.config import Limits
from twin.errors import MapError
from twin.maps.grid import OccupancyGrid

__all__ = [
    "DetectionContext",
    "DetectionSettings",
    "array_header",
    "box_in_map",
    "camera_fov",
    "decode_detections",
    "translate_detections",
]

log = logging.getLogger(__name__)
FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
_NS_PER_S = 1_000_000_000
MIN_SIZE_M = 0.001
"""A box side shorter than this (1 mm, the precision boxes are written with) is refused."""
MAX_COORDINATE_M = 100_000.0
BYTES_PER_DETECTION = 8192
"""Larger arrays are refused before they are decoded (a detection with one hypothesis is about 500 bytes)."""
"""A pose farther than this from its frame's origin is refused as nonsense (100 km)."""


@dataclass(frozen=True, slots=True)
class DetectionSettings:
    """How one robot's detections become observations (from ``[robots.NAME.detections]``)."""

    robot: str
    classes: Mapping[str, str]
    """``class_id`` -> IFC class."""
    types: Mapping[str, str] = field(default_factory=dict)
    """``class_id`` -> descriptive type IRI (``furn:Chair``), for the ids that give one."""
    min_score: float = 0.5
    fov_rad: float = math.radians(90.0)
    range_m: float = 5.0
    rays: int = 64
    max_tilt_rad: float = math.radians(15.0)
    max_detections: int = 256
    max_size_m: float = 20.0
    future_ns: int = 2 * _NS_PER_S
    """A stamp later than now + this is refused (clock skew allowed)."""
    session_gap_ns: int = 10 * _NS_PER_S
    """Arrays stamped further apart than this are two tracker sessions (:mod:`adapters.ros.sessions`)."""
    map_frame: str = "map"
    sensor_frame: str | None = None
    """The frame whose pose is the view's origin and heading (default: the array's ``frame_id``)."""
    optical: bool = False
    """The sensor frame looks along +z (x right, y down: a camera's optical frame, REP 103); False:
    along +x (x forward, y left, z up). Configured, never guessed from the frame's name."""
    vfov_rad: float | None = None
    """Vertical field of view (None: no vertical limit, unless CameraInfo gives one)."""
    near_m: float = 0.0
    """The detector sees nothing nearer than this (horizontal distance from the sensor)."""
    band_m: tuple[float, float] = (0.1, 0.5)
    """Heights above the floor the camera's frame must hold for a place to be in its view."""
    z_reference: Literal["storey", "building"] = "storey"
    """What z = 0 of the map frame is: the robot's storey's floor (a per-floor ROS map, the default)
    or the building's z = 0 (then the storey's elevation is subtracted)."""

    @property
    def detects(self) -> tuple[str, ...]:
        return tuple(sorted(set(self.classes.values())))

    @classmethod
    def from_config(cls, robot: str, d: DetectionConfig, limits: Limits) -> DetectionSettings:
        """A robot's ``[robots.NAME.detections]`` within the site's ``[limits]``."""
        return cls(
            robot=robot,
            classes=dict(d.classes),
            types=dict(d.types),
            min_score=d.min_score,
            fov_rad=math.radians(d.fov_deg),
            range_m=d.range_m,
            rays=d.rays,
            max_tilt_rad=math.radians(d.max_tilt_deg),
            max_detections=min(d.max_detections, limits.elements_per_observation),
            max_size_m=limits.box_size_m,
            future_ns=int(d.future_s * _NS_PER_S),
            session_gap_ns=int(d.session_gap_s * _NS_PER_S),
            map_frame=d.map_frame,
            sensor_frame=d.sensor_frame,
            z_reference=d.z_reference,
            optical=d.optical,
            vfov_rad=None if d.vfov_deg is None else math.radians(d.vfov_deg),
            near_m=d.near_m,
            band_m=d.heights_m,
        )


@dataclass(frozen=True, slots=True)
class DetectionContext:
    """What the daemon knows when an array arrives."""

    storey: str | None
    elevation_m: float
    now_ns: int
    tf: TfBuffer
    occluders: OccupancyGrid | Structure | None = None
    fusion_terms: bool = True
    occlusion_known: bool = True
    """False when the structure that hides parts of the view is not known (its map not yet built):
    then no view is claimed at all, rather than one that sees through walls."""
    fov_rad: tuple[float, float] | None = None
    """The camera's (horizontal, vertical) field of view from its ``sensor_msgs/CameraInfo``, if it
    publishes one: it takes the place of the configured ones."""
    session: TrackerSession | None = None
    """The robot's tracker session (:mod:`adapters.ros.sessions`): its IRIs carry it. None: the IRIs
    are ``det:<id>`` (no session)."""
    view_cache: ViewCache | None = None
    """The robot's last march of its camera's rays, reused while it stands still (same result)."""


class _Detection(NamedTuple):
    """One detection as decoded (a named tuple: an array makes twenty at a time)."""

    frame_id: str
    stamp_ns: int
    class_id: str | None
    score: float
    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]
    size: tuple[float, float, float]
    id: str


def _stamp(header: Any) -> int:
    return int(header.stamp.sec) * _NS_PER_S + int(header.stamp.nanosec)


_RawDetection = tuple[str, int, list[tuple[str, float]], tuple[float, ...], str]
"""A detection as decoded: frame_id, stamp (ns), its hypotheses (class_id, score), its box's centre
pose and size (10 floats: position, orientation x y z w, size) and its id."""
_F64 = struct.Struct("<d")
_BOX = struct.Struct("<10d")
_POSE_WITH_COVARIANCE = 8 * (7 + 36)


def _decode_le(payload: bytes | bytearray | memoryview) -> tuple[str, int, list[_RawDetection]] | None:
    """A little-endian CDR Detection3DArray decoded by hand (its layout is fixed: a header, then per
    detection a header, hypotheses, a box and an id); None if anything is unusual (another encoding,
    a length or count that does not fit, a string without its terminator or not UTF-8, trailing
    bytes): rosbags then decodes it or says why not, so both refuse the same messages."""
    data = body(payload)
    if data is None:
        return None
    end = len(data)
    u32, unpack_time, f64, box = U32.unpack_from, TIME.unpack_from, _F64.unpack_from, _BOX.unpack_from

    try:
        sec, nsec = unpack_time(data, 0)
        frame, pos = read_string(data, 8)
        pos += -pos % 4
        (count,) = u32(data, pos)
        pos += 4
        if count * 40 > end - pos:  # a detection holds at least 40 bytes
            return None
        out: list[_RawDetection] = []
        for _ in range(count):
            pos += -pos % 4
            d_sec, d_nsec = unpack_time(data, pos)
            d_frame, pos = read_string(data, pos + 8)
            pos += -pos % 4
            (n_results,) = u32(data, pos)
            pos += 4
            if n_results * 12 > end - pos:
                return None
            results: list[tuple[str, float]] = []
            for _ in range(n_results):
                class_id, pos = read_string(data, pos)
                pos += -pos % 8
                (score,) = f64(data, pos)
                pos += 8 + _POSE_WITH_COVARIANCE  # the hypothesis's pose: not used
                results.append((class_id, score))
            pos += -pos % 8
            values = box(data, pos)
            d_id, pos = read_string(data, pos + 80)
            out.append((d_frame, d_sec * _NS_PER_S + d_nsec, results, values, d_id))
    except (struct.error, ValueError, UnicodeDecodeError):
        return None
    if not ends_at(pos, data):
        return None
    return frame, sec * _NS_PER_S + nsec, out


def _decode_rosbags(payload: bytes | bytearray | memoryview) -> tuple[str, int, list[_RawDetection]]:
    """The same as :func:`_decode_le`, by rosbags (any encoding); RosInputError if malformed."""
    try:
        message = _deserialize(payload, DETECTION_3D_ARRAY)
    except MapError as err:
        raise RosInputError("malformed", str(err)) from err
    out: list[_RawDetection] = []
    for d in message.detections:
        s, p, q = d.bbox.size, d.bbox.center.position, d.bbox.center.orientation
        values = tuple(float(v) for v in (p.x, p.y, p.z, q.x, q.y, q.z, q.w, s.x, s.y, s.z))
        results = [(str(r.hypothesis.class_id), float(r.hypothesis.score)) for r in d.results]
        out.append((str(d.header.frame_id), _stamp(d.header), results, values, str(d.id)))
    return str(message.header.frame_id), _stamp(message.header), out


def decode_detections(
    payload: bytes | bytearray | memoryview, *, max_detections: int
) -> tuple[str, int, list[_Detection]]:
    """``(frame_id, stamp_ns, detections)`` of a CDR Detection3DArray; RosInputError if malformed or
    too long."""
    limit = max_detections * BYTES_PER_DETECTION + 4096
    if len(payload) > limit:
        msg = f"Detection3DArray of {len(payload)} bytes: {max_detections} detections fit in {limit}."
        raise RosInputError("oversized", msg)
    fast = _decode_le(payload)
    if fast is None:  # anything unusual (big endian, malformed): rosbags decodes it, or says why not
        fast = _decode_rosbags(payload)
    frame, stamp, raw = fast
    if len(raw) > max_detections:
        msg = f"Detection3DArray has {len(raw)} detections, more than the limit {max_detections}."
        raise RosInputError("oversized", msg)
    out: list[_Detection] = []
    for d_frame, d_stamp, results, v, d_id in raw:
        best = results[0] if len(results) == 1 else max(results, key=lambda r: r[1], default=None)
        out.append(
            _Detection(  # frame_id, stamp_ns, class_id, score, position, orientation, size, id
                d_frame or frame,
                d_stamp or stamp,
                None if best is None else best[0],
                -math.inf if best is None else best[1],
                (v[0], v[1], v[2]),
                (v[3], v[4], v[5], v[6]),
                (v[7], v[8], v[9]),
                d_id,
            )
        )
    return frame, stamp, out


def camera_fov(payload: bytes | bytearray | memoryview) -> tuple[float, float]:
    """``(horizontal, vertical)`` field of view (radians) of a CDR ``sensor_msgs/msg/CameraInfo``: from
    its intrinsics ``k`` (fx, fy, cx, cy) and image size, each the narrower side's angle twice (an
    off-centre principal point gives no side more than it sees); RosInputError if malformed or it
    describes no camera (zero size or focal length, as an uncalibrated driver publishes)."""
    try:
        message = _deserialize(payload, CAMERA_INFO)
    except MapError as err:
        raise RosInputError("malformed", str(err)) from err
    k = [float(v) for v in message.k]
    width, height = int(message.width), int(message.height)
    fx, cx, fy, cy = k[0], k[2], k[4], k[5]
    if not (all(math.isfinite(v) for v in k) and fx > 0 and fy > 0 and width > 0 and height > 0):
        msg = f"CameraInfo describes no camera: width {width}, height {height}, k {k}."
        raise RosInputError("malformed", msg)
    half_x = min(cx, width - cx)
    half_y = min(cy, height - cy)
    if half_x <= 0 or half_y <= 0:
        raise RosInputError("malformed", f"CameraInfo's principal point ({cx}, {cy}) lies outside its image.")
    return 2 * math.atan(half_x / fx), 2 * math.atan(half_y / fy)


def array_header(payload: bytes | bytearray | memoryview) -> tuple[str, int] | None:
    """``(frame_id, stamp_ns)`` of a CDR message that starts with a ``std_msgs/Header`` (read without
    decoding the rest), or None if it does not parse."""
    raw = bytes(payload[:4096])
    if len(raw) < 16 or raw[:2] != b"\x00\x01":
        return None
    sec, nanosec, length = struct.unpack_from("<iII", raw, 4)
    if not 0 < length <= len(raw) - 16 or nanosec >= _NS_PER_S:
        return None
    try:
        frame = raw[16 : 16 + length - 1].decode()
    except UnicodeDecodeError:
        return None
    return frame, sec * _NS_PER_S + nanosec


def _resolve(tf: TfBuffer, target: str, source: str, stamp_ns: int) -> Matrix:
    if source.lstrip("/") == target.lstrip("/"):
        return np.eye(4)
    if not source:
        raise RosInputError("unknown_frame", "The detection has an empty frame_id.")
    try:
        return tf.lookup(target, source, stamp_ns)
    except TfError as err:
        raise RosInputError(err.cause, str(err)) from err


def box_in_map(
    map_from_frame: Matrix,
    position: tuple[float, float, float],
    orientation: tuple[float, float, float, float],
    size: tuple[float, float, float],
    *,
    max_tilt_rad: float,
    max_size_m: float,
) -> tuple[float, float, float, float, float, float, float]:
    """``(cx, cy, cz, sx, sy, sz, yaw)`` in the map frame of a box posed in another frame; RosInputError for a
    non-finite or far-away pose, a quaternion that is no rotation, a size out of (0, max_size_m], or a
    tilt (angle of its z axis to the vertical) beyond ``max_tilt_rad``."""
    values = (*position, *orientation)
    if not all(math.isfinite(v) for v in values) or any(abs(v) > MAX_COORDINATE_M for v in position):
        raise RosInputError("pose", f"Box pose is not finite or out of range: {values}.")
    if not all(math.isfinite(v) and MIN_SIZE_M <= v <= max_size_m for v in size):
        raise RosInputError("size", f"Box size {size} is not within [{MIN_SIZE_M}, {max_size_m}] m.")
    norm = math.sqrt(sum(v * v for v in orientation))
    if abs(norm - 1.0) > 1e-2:
        raise RosInputError(
            "pose", f"Box orientation {orientation} is not a unit quaternion (norm {norm:.4g})."
        )
    local = matrix(position, [v / norm for v in orientation])
    return _upright(map_from_frame @ local, size, max_tilt_rad=max_tilt_rad)


def _upright(
    world: Matrix, size: tuple[float, float, float], *, max_tilt_rad: float
) -> tuple[float, float, float, float, float, float, float]:
    """The end of :func:`box_in_map`: ``world`` is the map from the box (its pose checked)."""
    r = world[:3, :3]
    tilt = math.acos(max(-1.0, min(1.0, float(r[2, 2]))))
    if tilt > max_tilt_rad:
        msg = (
            f"Box is tilted {math.degrees(tilt):.1f} deg from upright "
            f"(tolerance {math.degrees(max_tilt_rad):.1f} deg)."
        )
        raise RosInputError("tilt", msg)
    yaw = math.atan2(float(r[1, 0]), float(r[0, 0]))
    cx, cy, cz = (float(v) for v in world[:3, 3])
    if not all(math.isfinite(v) and abs(v) <= MAX_COORDINATE_M for v in (cx, cy, cz)):
        raise RosInputError("pose", f"Box centre in the map frame is out of range: {(cx, cy, cz)}.")
    return (cx, cy, cz, size[0], size[1], size[2], yaw)


_BOX_PLACED = tuple[float, float, float, float, float, float, float]
# the rotation matrix of a unit quaternion (tf.matrix's) from the products q_i * q_j, entry by entry:
# 2 * (a + s * b), and 1 minus that on the diagonal; q = (x, y, z, w) = indices 0..3 of q q^T (flat 4 x 4)
_ROT_A = np.array([5, 1, 2, 1, 0, 6, 2, 6, 0])  # yy, xy, xz / xy, xx, yz / xz, yz, xx
_ROT_B = np.array([10, 11, 7, 11, 10, 3, 7, 3, 5])  # zz, zw, yw / zw, zz, xw / yw, xw, yy
_ROT_SIGN = np.array([1.0, -1.0, 1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0])
_ROT_DIAGONAL = np.array([0, 4, 8])


def _rotations(q: FloatArray) -> FloatArray:
    """``(n, 3, 3)``: the rotation matrices of unit quaternions ``q`` ``(n, 4)`` (x, y, z, w), the same
    floats as :func:`adapters.ros.tf.quaternion_matrix` makes of each (the same products, sums and
    differences: ``a - b`` is ``a + (-b)`` exactly)."""
    n = len(q)
    products = (q[:, :, None] * q[:, None, :]).reshape(n, 16)
    rot = products[:, _ROT_A] + _ROT_SIGN * products[:, _ROT_B]
    rot *= 2.0
    rot[:, _ROT_DIAGONAL] = 1.0 - rot[:, _ROT_DIAGONAL]
    return rot.reshape(n, 3, 3)


def _placements(
    frames: list[Matrix],
    dets: list[_Detection],
    boxed: list[bool],
    *,
    max_tilt_rad: float,
    max_size_m: float,
    footprints: bool = True,
) -> tuple[list[_BOX_PLACED | RosInputError | None], FloatArray, BoolArray]:
    """Every detection placed at once (``frames[i]``: map from detection ``i``'s frame): for those
    ``boxed``, :func:`box_in_map`'s box or its error (the same floats, bit for bit: the same operations
    in the same order; a box whose pose or size fails goes through :func:`box_in_map` for its error;
    None for the others); and the footprints of all as :func:`_shadows` describes them (``(0, 5)``
    without ``footprints``: no view will be cut by them), with which could be placed."""
    n = len(dets)
    if n == 0:
        return [], np.zeros((0, 5)), np.zeros(0, dtype=bool)
    values = np.array([(*d.position, *d.orientation, *d.size) for d in dets], dtype=np.float64)
    p, q, size = values[:, :3], values[:, 3:7], values[:, 7:]
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        finite = np.isfinite(values)
        posed = finite[:, :7].all(axis=1) & (np.abs(p) <= MAX_COORDINATE_M).all(axis=1)
        x, y, z, w = q.T
        norm = np.sqrt(x * x + y * y + z * z + w * w)  # left to right, as sum() adds (and np.linalg.norm)
        box_ok = (
            posed & ((size >= MIN_SIZE_M) & (size <= max_size_m)).all(axis=1) & finite[:, 7:].all(axis=1)
            & (np.abs(norm - 1.0) <= 1e-2)
        )  # fmt: skip
        shadow_ok = (
            posed & finite[:, 7:].all(axis=1) & (np.abs(size) <= MAX_COORDINATE_M).all(axis=1) & (norm > 0)
        )
        turns = box_ok | shadow_ok
        unit = np.where(turns[:, None], q / np.where(turns, norm, 1.0)[:, None], _NO_TURN)
    rot = _rotations(unit)
    m = np.array(frames)  # (n, 4, 4): map from frame
    boxes: list[_BOX_PLACED | RosInputError | None] = [None] * n
    if any(boxed):
        local = np.zeros((n, 4, 4))
        local[:, :3, :3] = rot
        local[:, :3, 3] = np.where(box_ok[:, None], p, 0.0)
        local[:, 3, 3] = 1.0
        world = np.matmul(m, local)
        # _upright's reads of each box's matrix, as Python floats at once (the same values)
        r22, r10, r00 = world[:, 2, 2].tolist(), world[:, 1, 0].tolist(), world[:, 0, 0].tolist()
        centres = world[:, :3, 3].tolist()
        acos, atan2, isfinite = math.acos, math.atan2, math.isfinite
        for i, (d, good) in enumerate(zip(dets, box_ok.tolist(), strict=True)):
            if not boxed[i]:
                continue
            try:
                if not good:
                    limits = {"max_tilt_rad": max_tilt_rad, "max_size_m": max_size_m}
                    boxes[i] = box_in_map(frames[i], d.position, d.orientation, d.size, **limits)
                    continue
                tilt = acos(max(-1.0, min(1.0, r22[i])))
                cx, cy, cz = centres[i]
                if tilt > max_tilt_rad or not (
                    isfinite(cx) and isfinite(cy) and isfinite(cz) and abs(cx) <= MAX_COORDINATE_M
                    and abs(cy) <= MAX_COORDINATE_M and abs(cz) <= MAX_COORDINATE_M
                ):  # fmt: skip
                    boxes[i] = _upright(world[i], d.size, max_tilt_rad=max_tilt_rad)  # raises, naming it
                    continue
                s = d.size
                boxes[i] = (cx, cy, cz, s[0], s[1], s[2], atan2(r10[i], r00[i]))
            except RosInputError as err:
                boxes[i] = err
    if not footprints:
        return boxes, np.zeros((0, 5)), shadow_ok
    # the footprints: the map-axis-aligned extent of each box, however tilted
    p, size = np.where(shadow_ok[:, None], p, 0.0), np.where(shadow_ok[:, None], size, 0.0)
    m33 = m[:, :3, :3]
    centre = np.einsum("nij,nj->ni", m33, p) + m[:, :3, 3]
    turned = np.einsum("nij,njk->nik", m33, rot)
    extent = np.einsum("nij,nj->ni", np.abs(turned), np.abs(size) / 2)  # half extents along map axes
    shadows = np.zeros((n, 5))
    shadows[:, :2] = centre[:, :2]
    shadows[:, 2:4] = 2 * extent[:, :2]
    return boxes, shadows, shadow_ok


_NO_TURN = np.array([0.0, 0.0, 0.0, 1.0])


def _boxes_in_map(
    frames: list[Matrix], dets: list[_Detection], *, max_tilt_rad: float, max_size_m: float
) -> list[_BOX_PLACED | RosInputError]:
    """:func:`box_in_map` of many boxes at once (``frames[i]``: map from detection ``i``'s frame), the
    same floats, bit for bit (:func:`_placements`)."""
    boxes = _placements(
        frames, dets, [True] * len(dets), max_tilt_rad=max_tilt_rad, max_size_m=max_size_m, footprints=False
    )[0]
    return [b for b in boxes if b is not None]


def _shadows(frames: list[Matrix], dets: list[_Detection]) -> tuple[FloatArray, BoolArray]:
    """``(n, 5)`` ``(cx, cy, sx, sy, 0)``: the map-axis-aligned footprints of detections' boxes, however
    tilted (``frames[i]``: map from detection ``i``'s frame), and which could be placed (a pose or size
    that is not finite or out of range, or an orientation that is no rotation, cannot)."""
    _, shadows, ok = _placements(frames, dets, [False] * len(dets), max_tilt_rad=0.0, max_size_m=0.0)
    return shadows, ok


def _view(
    settings: DetectionSettings,
    ctx: DetectionContext,
    frame: str,
    stamp_ns: int,
    *,
    storey: str,
    shadows: FloatArray,
    drop_z: float,
) -> ViewReport | None:
    """The view of the sensor (``sensor_frame`` or the array's frame); None if that is the map frame
    or it saw no floor."""
    sensor = settings.sensor_frame or frame
    if sensor.lstrip("/") == settings.map_frame.lstrip("/"):
        return None
    pose = _resolve(ctx.tf, settings.map_frame, sensor, stamp_ns)
    hfov, vfov = ctx.fov_rad if ctx.fov_rad is not None else (settings.fov_rad, settings.vfov_rad)
    cam = Camera.from_pose(
        pose, optical=settings.optical, hfov_rad=hfov, vfov_rad=vfov, range_m=settings.range_m,
        near_m=settings.near_m, z_offset_m=drop_z,
    )  # fmt: skip
    seen = camera_view(
        ctx.occluders, cam, band_m=settings.band_m, shadows=shadows, rays=settings.rays, cache=ctx.view_cache
    )
    if seen is None:
        return None
    return ViewReport(storey, seen.rings, settings.detects, seen.hole_rings, origin=cam.position)


def translate_detections(
    payload: bytes | bytearray | memoryview,
    settings: DetectionSettings,
    ctx: DetectionContext,
    *,
    typed: bool = False,
) -> Translation:
    """One Detection3DArray as one observation (see the module's docstring): Turtle, or with ``typed``
    the core's records that Turtle parses to (for the daemon's own process: nothing written or parsed).

    Raises RosInputError for the whole array: malformed CDR, too many detections, no current storey, a stamp
    in the future, a frame (of the view) that does not resolve. Single detections that cannot be used
    are in ``refused`` of the result.
    """
    frame, stamp, detections = decode_detections(payload, max_detections=settings.max_detections)
    if ctx.storey is None:
        raise RosInputError(
            "no_storey", f"Robot {settings.robot!r} has no current storey: its detections have no floor."
        )
    if stamp > ctx.now_ns + settings.future_ns:
        msg = f"Detection3DArray stamp {stamp} ns is {(stamp - ctx.now_ns) / 1e9:.3f} s in the future."
        raise RosInputError("future", msg)
    label = None
    if ctx.session is not None:
        label = ctx.session.observe(stamp, [d.id for d in detections if d.id], gap_ns=settings.session_gap_ns)
    ignored: Counter[str] = Counter()
    refused: list[tuple[str, str]] = []
    boxes: list[BoxReport] = []
    seen: set[str] = set()
    transforms: dict[tuple[str, int], Matrix] = {}
    drop_z = ctx.elevation_m if settings.z_reference == "building" else 0.0
    blind = False  # a detection whose place is unknown: what it hides is unknown, so no view
    # first each detection's class and frame, then every box and footprint at once, then in order
    steps: list[tuple[int, _Detection, str | None, str | None, RosInputError | None, int]] = []
    frames: list[Matrix] = []  # of every detection placed: any detection hides what stands behind it
    placed: list[_Detection] = []
    boxed: list[bool] = []
    for index, d in enumerate(detections):
        ifc_class = settings.classes.get(d.class_id) if d.class_id is not None else None
        why: str | None = None
        if d.class_id is None:
            why = "no_hypothesis"
        elif ifc_class is None:
            why = "unknown_class"
        elif not d.score >= settings.min_score:
            why = "low_score"
            ifc_class = None
        try:
            if ifc_class is not None and d.stamp_ns > ctx.now_ns + settings.future_ns:
                raise RosInputError("future", f"Detection stamp {d.stamp_ns} ns is in the future.")
            key = (d.frame_id, d.stamp_ns)
            if key not in transforms:  # the detections of an array share their frame: one lookup
                transforms[key] = _resolve(ctx.tf, settings.map_frame, d.frame_id, d.stamp_ns)
        except RosInputError as err:
            steps.append((index, d, why, ifc_class, err, -1))
            continue
        steps.append((index, d, why, ifc_class, None, len(placed)))
        frames.append(transforms[key])
        placed.append(d)
        boxed.append(ifc_class is not None)
    viewed = ctx.fusion_terms and ctx.occlusion_known  # a view is cut by the detections' footprints
    placed_boxes, shadows, ok = _placements(
        frames, placed, boxed, max_tilt_rad=settings.max_tilt_rad, max_size_m=settings.max_size_m,
        footprints=viewed,
    )  # fmt: skip
    for index, d, why, ifc_class, error, row in steps:
        if why is not None:
            ignored[why] += 1
        if error is not None:
            if ifc_class is not None:
                refused.append((error.cause, str(error)))
            else:
                blind = True
            continue
        if ifc_class is None:
            continue
        placed_box = placed_boxes[row]
        assert placed_box is not None  # every detection of a known class is boxed
        if isinstance(placed_box, RosInputError):
            refused.append((placed_box.cause, str(placed_box)))
            continue
        cx, cy, cz, sx, sy, sz, yaw = placed_box
        iri = (
            (
                robot_iri(settings.robot, "det", d.id)
                if label is None
                else session_iri(settings.robot, label, d.id)
            )
            if d.id
            else robot_iri(settings.robot, "once", f"{stamp}-{index}")
        )
        if iri in seen:
            ignored["duplicate_id"] += 1
            continue
        seen.add(iri)
        box = (cx, cy, cz - drop_z, sx, sy, sz, yaw)
        boxes.append(BoxReport(iri, ifc_class, ctx.storey, box, kind=settings.types.get(d.class_id or "")))
    view = None
    if viewed and not refused and not blind and ok.all():
        view = _view(settings, ctx, frame, stamp, storey=ctx.storey, shadows=shadows, drop_z=drop_z)
    write = observation_records if typed else observation_turtle
    document = write(boxes=boxes, view=view, sense_ns=stamp or None, fusion_terms=ctx.fusion_terms)
    return Translation(document, tuple(b.iri for b in boxes), dict(ignored), tuple(refused))
