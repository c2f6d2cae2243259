"""The hand-written Detection3DArray decoder reads what rosbags reads, field by field, bit for bit: on
generated arrays in both encodings (little endian by hand, big endian falls back to rosbags), and on
hostile bytes it accepts nothing rosbags refuses (whatever it leaves, rosbags decodes or refuses). The
boxes placed at once are box by box's, bit for bit, and refused with the same errors. A TF lookup asked
again (remembered until the tree changes) is the same, and follows a change of the tree."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from adapters.ros.cdr import _typestore
from adapters.ros.detections import (
    _boxes_in_map,
    _decode_le,
    _decode_rosbags,
    _Detection,
    _placements,
    box_in_map,
    decode_detections,
)
from adapters.ros.interfaces import DETECTION_3D_ARRAY
from adapters.ros.observation_doc import RosInputError
from adapters.ros.tf import TfBuffer, decode_tf_message, matrix, quaternion_matrix
from tests.adapters.ros.hand_decoders import accepts_nothing_refused, bits, mutated
from tests.adapters.ros_reports import Det, Tf, cdr_detections, cdr_tf
from tests.conftest import examples

FAST = settings(max_examples=examples(120), deadline=None, suppress_health_check=list(HealthCheck))
floats = st.floats(allow_nan=True, allow_infinity=True, width=64)
text = st.text(max_size=12)
stamps = st.tuples(st.integers(-(2**31), 2**31 - 1), st.integers(0, 2**32 - 1))


@st.composite
def arrays(draw: st.DrawFn) -> Any:
    t = _typestore().types
    time, header = t["builtin_interfaces/msg/Time"], t["std_msgs/msg/Header"]
    point, quat, vec = (
        t["geometry_msgs/msg/Point"],
        t["geometry_msgs/msg/Quaternion"],
        t["geometry_msgs/msg/Vector3"],
    )
    pose, pwc = t["geometry_msgs/msg/Pose"], t["geometry_msgs/msg/PoseWithCovariance"]
    hyp, hwp = t["vision_msgs/msg/ObjectHypothesis"], t["vision_msgs/msg/ObjectHypothesisWithPose"]
    box, det, arr = (
        t["vision_msgs/msg/BoundingBox3D"],
        t["vision_msgs/msg/Detection3D"],
        t[DETECTION_3D_ARRAY],
    )

    def head() -> Any:
        sec, nsec = draw(stamps)
        return header(stamp=time(sec=sec, nanosec=nsec), frame_id=draw(text))

    def a_pose() -> Any:
        f = [draw(floats) for _ in range(7)]
        return pose(position=point(x=f[0], y=f[1], z=f[2]), orientation=quat(x=f[3], y=f[4], z=f[5], w=f[6]))

    detections = []
    for _ in range(draw(st.integers(0, 4))):
        results = [
            hwp(hypothesis=hyp(class_id=draw(text), score=draw(floats)),
                pose=pwc(pose=a_pose(), covariance=np.full(36, draw(floats))))
            for _ in range(draw(st.integers(0, 3)))
        ]  # fmt: skip
        size = vec(x=draw(floats), y=draw(floats), z=draw(floats))
        detections.append(
            det(header=head(), results=results, bbox=box(center=a_pose(), size=size), id=draw(text))
        )
    return arr(header=head(), detections=detections)


def _cdr(message: Any, *, little_endian: bool = True) -> bytes:
    return bytes(_typestore().serialize_cdr(message, DETECTION_3D_ARRAY, little_endian=little_endian))


@FAST
@given(message=arrays())
def test_the_hand_decoder_reads_every_field_rosbags_reads_and_big_endian_goes_to_rosbags(
    message: Any,
) -> None:
    le, be = _cdr(message), _cdr(message, little_endian=False)
    fast = _decode_le(le)
    assert fast is not None
    assert bits(fast) == bits(_decode_rosbags(le)) == bits(_decode_rosbags(be))
    assert _decode_le(be) is None
    assert bits(decode_detections(le, max_detections=8)) == bits(decode_detections(be, max_detections=8))


@FAST
@given(
    message=arrays(),
    cut=st.integers(0, 4000),
    flips=st.lists(st.tuples(st.integers(0, 4000), st.integers(0, 255)), max_size=4),
    tail=st.binary(max_size=8),
)
def test_on_hostile_bytes_the_hand_decoder_accepts_nothing_rosbags_refuses(
    message: Any, cut: int, flips: list[tuple[int, int]], tail: bytes
) -> None:
    payload = mutated(_cdr(message), cut, flips, tail)
    accepts_nothing_refused(payload, _decode_le, _decode_rosbags, RosInputError)


def test_a_truncated_array_is_refused_as_malformed_naming_its_size() -> None:
    payload = cdr_detections(0, "cam", [Det((("table", 0.9),), (1.0, 0.0, 0.4), (0.2, 0.2, 0.8))])
    assert _decode_le(payload) is not None
    with pytest.raises(RosInputError, match="6 bytes") as refused:
        decode_detections(payload[:6], max_detections=8)
    assert refused.value.cause == "malformed"


near_one = st.one_of(st.floats(-1.0, 1.0), floats)
coordinates = st.one_of(*(st.floats(-50.0, 50.0),) * 6, st.just(2e5), floats)
sizes = st.one_of(*(st.floats(0.01, 5.0),) * 6, st.floats(0.0, 25.0), floats)


@st.composite
def boxes(draw: st.DrawFn) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    sane = draw(st.integers(0, 3)) > 0  # mostly a pose and size that place, sometimes any floats
    position = tuple(draw(st.floats(-50.0, 50.0) if sane else coordinates) for _ in range(3))
    if draw(st.integers(0, 3)):  # mostly upright, a small tilt, sometimes a large one
        yaw, tilt = draw(st.floats(-4.0, 4.0)), draw(st.one_of(st.floats(-0.2, 0.2), st.floats(-3.0, 3.0)))
        cy, sy, ct, st_ = math.cos(yaw / 2), math.sin(yaw / 2), math.cos(tilt / 2), math.sin(tilt / 2)
        quat = (cy * st_, sy * st_, sy * ct, cy * ct)  # a yaw after a tilt about x
        scale = draw(st.sampled_from([1.0, 1.0, 1.005, 0.98, 0.0]))
        orientation = tuple(v * scale for v in quat)
    else:
        orientation = tuple(draw(near_one) for _ in range(4))
    size = tuple(draw(st.floats(0.01, 5.0) if sane else sizes) for _ in range(3))
    return position, orientation, size


@FAST
@given(
    frame=st.tuples(*(st.floats(-20, 20),) * 2, st.floats(-2, 2), st.floats(-4, 4), st.floats(-0.3, 0.3)),
    placed=st.lists(boxes(), max_size=8),
)
def test_boxes_placed_at_once_are_the_boxes_placed_one_by_one_bit_for_bit_and_refused_alike(
    frame: tuple[float, float, float, float, float],
    placed: list[tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]],
) -> None:
    x, y, z, yaw, roll = frame
    q = (math.sin(roll / 2), 0.0, 0.0, math.cos(roll / 2))
    heading = (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
    map_from_frame = matrix((x, y, z), heading) @ matrix((0, 0, 0), q)
    dets = [_Detection("f", 0, "c", 1.0, p, o, s, "") for p, o, s in placed]  # type: ignore[arg-type]
    limits = {"max_tilt_rad": math.radians(15.0), "max_size_m": 20.0}
    at_once = _boxes_in_map([map_from_frame] * len(dets), dets, **limits)
    for d, got in zip(dets, at_once, strict=True):
        one: Any
        try:
            one = box_in_map(map_from_frame, d.position, d.orientation, d.size, **limits)
        except RosInputError as err:
            one = err
        if isinstance(one, RosInputError):
            assert isinstance(got, RosInputError)
            assert (got.cause, str(got)) == (one.cause, str(one))
        else:
            assert not isinstance(got, RosInputError)
            assert bits(got) == bits(one)


@FAST
@given(
    frame=st.tuples(*(st.floats(-20, 20),) * 2, st.floats(-2, 2), st.floats(-4, 4), st.floats(-0.3, 0.3)),
    placed=st.lists(boxes(), max_size=8),
    boxed=st.lists(st.booleans(), min_size=8, max_size=8),
)
def test_the_footprints_placed_with_the_boxes_are_each_box_s_map_extent_and_only_known_ones_are_boxed(
    frame: tuple[float, float, float, float, float],
    placed: list[tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]],
    boxed: list[bool],
) -> None:
    x, y, z, yaw, roll = frame
    map_from_frame = matrix((x, y, z), (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))) @ matrix(
        (0, 0, 0), (math.sin(roll / 2), 0.0, 0.0, math.cos(roll / 2))
    )
    dets = [_Detection("f", 0, "c", 1.0, p, o, s, "") for p, o, s in placed]  # type: ignore[arg-type]
    wanted = boxed[: len(dets)]
    limits = {"max_tilt_rad": math.radians(15.0), "max_size_m": 20.0}
    got, shadows, ok = _placements([map_from_frame] * len(dets), dets, wanted, **limits)
    assert [b is not None for b in got] == wanted
    for d, footprint, placeable in zip(dets, shadows.tolist(), ok.tolist(), strict=True):
        values = (*d.position, *d.orientation, *d.size)
        norm = math.sqrt(sum(v * v for v in d.orientation)) if all(map(math.isfinite, values)) else 0.0
        sane = all(abs(v) <= 1e5 for v in (*d.position, *d.size)) and norm > 0
        assert placeable == sane
        if not sane:
            continue
        turned = map_from_frame[:3, :3] @ quaternion_matrix([v / norm for v in d.orientation])
        centre = map_from_frame[:3, :3] @ d.position + map_from_frame[:3, 3]
        extent = np.abs(turned) @ np.abs(d.size)
        want = [centre[0], centre[1], extent[0], extent[1], 0.0]
        assert np.allclose(footprint, want, rtol=1e-12, atol=1e-9), (footprint, want)


def test_a_lookup_asked_again_is_the_same_and_follows_a_change_of_the_tree() -> None:
    tf = TfBuffer()
    tf.add(decode_tf_message(cdr_tf([Tf("map", "base_link", (1.0, 2.0, 0.0), stamp_ns=10**9)])), static=False)
    tf.add(decode_tf_message(cdr_tf([Tf("base_link", "cam", (0.2, 0.0, 1.0))])), static=True)
    first = tf.lookup("map", "cam", 10**9)
    first[0, 3] = 99.0  # the caller's copy: the buffer's memory is untouched
    assert tf.lookup("map", "cam", 10**9)[:3, 3].tolist() == [1.2, 2.0, 1.0]
    tf.add(decode_tf_message(cdr_tf([Tf("base_link", "cam", (0.5, 0.0, 1.0))])), static=True)
    assert tf.lookup("map", "cam", 10**9)[:3, 3].tolist() == [1.5, 2.0, 1.0]  # the new static transform
