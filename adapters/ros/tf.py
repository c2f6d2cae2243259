"""A robot's TF tree, as tf2 keeps it: ``tf2_msgs/msg/TFMessage`` from ``/tf`` (timed) and ``/tf_static``
(timeless), looked up at a stamp with interpolation (linear in translation, slerp in rotation).

Every frame has one parent (the latest message naming it wins, as in tf2). A lookup walks both frames
up to their common root and composes the transforms; a frame nobody published, two frames in separate
trees, or a stamp outside a dynamic transform's history (beyond ``tolerance_ns``, where the nearest
sample is used as tf2 users do with a small timeout) raise :class:`TfError` with a ``cause`` to count
it by: never a guess.

Example::

    tf = TfBuffer()
    tf.add(decode_tf_message(payload), static=False)
    map_from_camera = tf.lookup("map", "camera_optical_frame", stamp_ns)   # (4, 4) float64
"""

from __future__ import annotations

import bisect
import math
import struct
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from adapters.ros.cdr import _deserialize
from adapters.ros.cdr_le import TIME, U32, body, ends_at, read_string
from adapters.ros.interfaces import TF_MESSAGE
from twin.errors import MapError

__all__ = ["TfBuffer", "TfError", "TransformSample", "decode_tf_message", "matrix", "quaternion_matrix"]

Matrix = npt.NDArray[np.float64]
_NS_PER_S = 1_000_000_000
MAX_TF_BYTES = 1 << 20
"""Larger TF messages are refused before they are decoded (a transform is about 100 bytes)."""
_MEMO = 64
"""Lookups a buffer remembers at most between two changes."""


class TfError(Exception):
    """A frame that does not resolve; ``cause`` is one of ``unknown_frame``, ``disconnected``,
    ``extrapolation``."""

    def __init__(self, cause: str, message: str, *, later: bool = False) -> None:
        super().__init__(message)
        self.cause = cause
        self.later = later
        """For ``extrapolation``: the stamp is after the newest sample (it may still come)."""


@dataclass(frozen=True, slots=True)
class TransformSample:
    """``parent_from_child`` at ``stamp_ns``: translation (x, y, z) and unit quaternion (x, y, z, w)."""

    parent: str
    child: str
    stamp_ns: int
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]


def _frame(name: str) -> str:
    """tf2 strips a leading slash from frame ids."""
    return name[1:] if name.startswith("/") else name


_RawTransform = tuple[str, str, int, int, tuple[float, ...]]
"""A transform as decoded: frame_id, child_frame_id, stamp sec and nanosec, and 7 floats (translation
x y z, rotation x y z w)."""
_TRANSFORM = struct.Struct("<7d")
_MIN_TRANSFORM_BYTES = 8 + 5 + 5 + 56
"""The fewest bytes a transform takes (a stamp, two empty strings, seven doubles; padding aside)."""


def _decode_le(payload: bytes | bytearray | memoryview) -> list[_RawTransform] | None:
    """A little-endian CDR TFMessage decoded by hand (its layout is fixed: a count, then per transform a
    header, the child's frame and seven doubles); None if anything is unusual (another encoding, a
    count that does not fit, a string without its terminator or not UTF-8, trailing bytes): rosbags
    then decodes it or says why not, so both refuse the same messages."""
    data = body(payload)
    if data is None:
        return None
    end = len(data)
    u32, unpack_time, unpack_transform = U32.unpack_from, TIME.unpack_from, _TRANSFORM.unpack_from

    try:
        (count,) = u32(data, 0)
        pos = 4
        if count * _MIN_TRANSFORM_BYTES > end - pos:
            return None
        out: list[_RawTransform] = []
        for _ in range(count):
            pos += -pos % 4
            sec, nanosec = unpack_time(data, pos)
            parent, pos = read_string(data, pos + 8)
            child, pos = read_string(data, pos)
            pos += -pos % 8
            values = unpack_transform(data, pos)
            pos += 56
            out.append((parent, child, sec, nanosec, values))
    except (struct.error, ValueError, UnicodeDecodeError):
        return None
    if not ends_at(pos, data):
        return None
    return out


def _decode_rosbags(payload: bytes | bytearray | memoryview) -> list[_RawTransform]:
    """The same as :func:`_decode_le`, by rosbags (any encoding); MapError if malformed."""
    message = _deserialize(payload, TF_MESSAGE)
    out: list[_RawTransform] = []
    for ts in message.transforms:
        t, q, stamp = ts.transform.translation, ts.transform.rotation, ts.header.stamp
        values = (t.x, t.y, t.z, q.x, q.y, q.z, q.w)
        out.append((ts.header.frame_id, ts.child_frame_id, int(stamp.sec), int(stamp.nanosec), values))
    return out


def decode_tf_message(payload: bytes | bytearray | memoryview) -> list[TransformSample]:
    """The transforms of a CDR ``tf2_msgs/msg/TFMessage``; MapError if malformed or not finite, or a
    quaternion is not a rotation. Little-endian messages are read by hand (:func:`_decode_le`), others
    (and anything unusual) by rosbags: the same values either way."""
    if len(payload) > MAX_TF_BYTES:
        msg = f"A TFMessage of {len(payload)} bytes is larger than the limit {MAX_TF_BYTES}."
        raise MapError(msg)
    raw = _decode_le(payload)
    if raw is None:
        raw = _decode_rosbags(payload)
    out: list[TransformSample] = []
    for frame_id, child_frame_id, sec, nanosec, values in raw:
        tx, ty, tz, qx, qy, qz, qw = values
        if not all(math.isfinite(v) for v in values):
            msg = f"Transform {frame_id!r} -> {child_frame_id!r} is not finite: {values}."
            raise MapError(msg)
        norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        if abs(norm - 1.0) > 1e-3:
            msg = f"Transform {frame_id!r} -> {child_frame_id!r} has a quaternion of norm {norm}."
            raise MapError(msg)
        parent, child = _frame(frame_id), _frame(child_frame_id)
        if not parent or not child or parent == child:
            msg = f"Transform {parent!r} -> {child!r} does not join two named frames."
            raise MapError(msg)
        stamp = sec * _NS_PER_S + nanosec
        out.append(
            TransformSample(parent, child, stamp, (tx, ty, tz), (qx / norm, qy / norm, qz / norm, qw / norm))
        )
    return out


def quaternion_matrix(q: Any) -> Matrix:
    """``(3, 3)`` rotation of the unit quaternion ``(x, y, z, w)``."""
    x, y, z, w = (float(v) for v in q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrix(translation: Any, rotation: Any) -> Matrix:
    """``(4, 4)`` homogeneous transform of a translation and a unit quaternion ``(x, y, z, w)``."""
    m = np.eye(4)
    m[:3, :3] = quaternion_matrix(rotation)
    m[:3, 3] = [float(v) for v in translation]
    return m


def _slerp(q0: npt.NDArray[np.float64], q1: npt.NDArray[np.float64], f: float) -> npt.NDArray[np.float64]:
    dot = float(q0 @ q1)
    if dot < 0.0:
        q1, dot = -q1, -dot
    if dot > 0.9995:
        q = q0 + f * (q1 - q0)
    else:
        theta = math.acos(dot)
        q = (math.sin((1 - f) * theta) * q0 + math.sin(f * theta) * q1) / math.sin(theta)
    norm: float = float(np.linalg.norm(q))
    return q / norm


@dataclass(slots=True)
class _Edge:
    """One child's transforms from its parent: timeless (static) or a time-ordered history."""

    parent: str
    static: bool
    stamps: list[int] = field(default_factory=list)
    translations: list[tuple[float, float, float]] = field(default_factory=list)
    rotations: list[tuple[float, float, float, float]] = field(default_factory=list)


class TfBuffer:
    """The TF tree of one robot: a bounded history per dynamic frame (``history_ns``), static frames
    once. Not thread-safe: one owner (the ingest's worker) adds and looks up."""

    def __init__(self, *, history_ns: int = 10 * _NS_PER_S, tolerance_ns: int = _NS_PER_S // 5) -> None:
        self.history_ns = history_ns
        self.tolerance_ns = tolerance_ns
        self._edges: dict[str, _Edge] = {}
        self._memo: dict[tuple[str, str, int], Matrix] = {}
        """Lookups since the last change of the tree (an array asks for the same transform up to three
        times: whether it waits, its boxes, its view)."""

    @property
    def frames(self) -> set[str]:
        return set(self._edges) | {e.parent for e in self._edges.values()}

    def add(self, transforms: Iterable[TransformSample], *, static: bool) -> None:
        self._memo.clear()
        for t in transforms:
            edge = self._edges.get(t.child)
            if edge is None or edge.parent != t.parent or edge.static != static:
                edge = self._edges[t.child] = _Edge(t.parent, static)
            if static:
                edge.stamps, edge.translations, edge.rotations = [t.stamp_ns], [t.translation], [t.rotation]
                continue
            i = bisect.bisect_right(edge.stamps, t.stamp_ns)
            if i > 0 and edge.stamps[i - 1] == t.stamp_ns:  # the same stamp again: replace
                edge.translations[i - 1], edge.rotations[i - 1] = t.translation, t.rotation
                continue
            edge.stamps.insert(i, t.stamp_ns)
            edge.translations.insert(i, t.translation)
            edge.rotations.insert(i, t.rotation)
            cut = bisect.bisect_left(edge.stamps, edge.stamps[-1] - self.history_ns)
            if cut > 0:
                del edge.stamps[:cut], edge.translations[:cut], edge.rotations[:cut]

    def _edge_at(self, child: str, edge: _Edge, stamp_ns: int) -> Matrix:
        if edge.static or stamp_ns == 0:  # tf2: time 0 = the latest
            return matrix(edge.translations[-1], edge.rotations[-1])
        stamps = edge.stamps
        i = bisect.bisect_left(stamps, stamp_ns)
        if i < len(stamps) and stamps[i] == stamp_ns:
            return matrix(edge.translations[i], edge.rotations[i])
        if i == 0 or i == len(stamps):
            nearest = 0 if i == 0 else len(stamps) - 1
            gap = abs(stamps[nearest] - stamp_ns)
            if gap > self.tolerance_ns:
                side = "before the oldest" if i == 0 else "after the newest"
                msg = (
                    f"Transform {edge.parent!r} -> {child!r} at {stamp_ns} ns is {gap / 1e9:.3f} s {side} "
                    f"sample it has (tolerance {self.tolerance_ns / 1e9:.3f} s)."
                )
                raise TfError("extrapolation", msg, later=i > 0)
            return matrix(edge.translations[nearest], edge.rotations[nearest])
        t0, t1 = stamps[i - 1], stamps[i]
        f = (stamp_ns - t0) / (t1 - t0)
        p = np.add(np.multiply(edge.translations[i - 1], 1 - f), np.multiply(edge.translations[i], f))
        q = _slerp(np.asarray(edge.rotations[i - 1]), np.asarray(edge.rotations[i]), f)
        return matrix(p, q)

    def _to_root(self, frame: str, stamp_ns: int) -> tuple[list[str], list[Matrix]]:
        """The chain ``frame, parent, ..., root`` and ``parent_from_child`` of each step."""
        chain, steps = [frame], []
        seen = {frame}
        while (edge := self._edges.get(chain[-1])) is not None:
            steps.append(self._edge_at(chain[-1], edge, stamp_ns))
            if edge.parent in seen:
                msg = f"The TF tree has a loop through {edge.parent!r}."
                raise TfError("disconnected", msg)
            chain.append(edge.parent)
            seen.add(edge.parent)
        return chain, steps

    def waits_for(self, target: str, source: str, stamp_ns: int) -> bool:
        """True when ``target_from_source`` at ``stamp_ns`` is not known yet but may be once more
        transforms arrive (tf2's message filter waits for them too): a frame nobody has published yet,
        or a stamp after the newest sample of a dynamic transform on the way."""
        try:
            self.lookup(target, source, stamp_ns)
        except TfError as err:
            return err.later or err.cause == "unknown_frame"
        return False

    def lookup(self, target: str, source: str, stamp_ns: int) -> Matrix:
        """``target_from_source`` at ``stamp_ns`` (``(4, 4)``): maps points in ``source`` into ``target``."""
        target, source = _frame(target), _frame(source)
        if target == source:
            return np.eye(4)
        key = (target, source, stamp_ns)
        known_result = self._memo.get(key)
        if known_result is not None:
            return known_result.copy()
        result = self._lookup(target, source, stamp_ns)
        if len(self._memo) >= _MEMO:
            self._memo.clear()
        self._memo[key] = result
        return result.copy()

    def _lookup(self, target: str, source: str, stamp_ns: int) -> Matrix:
        known = self.frames
        for name in (source, target):
            if name not in known:
                msg = (
                    f"Frame {name!r} is not in the robot's TF (known: {', '.join(sorted(known)) or 'none'})."
                )
                raise TfError("unknown_frame", msg)
        src_chain, src_steps = self._to_root(source, stamp_ns)
        tgt_chain, tgt_steps = self._to_root(target, stamp_ns)
        common = next((f for f in src_chain if f in set(tgt_chain)), None)
        if common is None:
            roots = f"{src_chain[-1]!r}, {tgt_chain[-1]!r}"
            msg = f"Frames {source!r} and {target!r} are in separate TF trees (roots {roots})."
            raise TfError("disconnected", msg)
        root_from_source = np.eye(4)
        for step in src_steps[: src_chain.index(common)]:
            root_from_source = step @ root_from_source
        up = tgt_steps[: tgt_chain.index(common)]
        if not up:  # the target is the common root (the map, as a rule): inv(I) is I, exactly
            result: Matrix = np.eye(4) @ root_from_source
            return result
        root_from_target = np.eye(4)
        for step in up:
            root_from_target = step @ root_from_target
        result = np.linalg.inv(root_from_target) @ root_from_source
        return result
