"""The hand-written TFMessage decoder reads what rosbags reads, field by field, bit for bit: on generated
messages in both encodings (little endian by hand, big endian falls back to rosbags), a transform
refused for the same reason with the same message either way, and on hostile bytes it accepts nothing
rosbags refuses (whatever it leaves, rosbags decodes or refuses)."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from adapters.ros.cdr import _typestore
from adapters.ros.interfaces import TF_MESSAGE
from adapters.ros.tf import TransformSample, _decode_le, _decode_rosbags, decode_tf_message
from tests.adapters.ros.hand_decoders import accepts_nothing_refused, bits, mutated
from tests.adapters.ros_reports import Tf, cdr_tf
from tests.conftest import examples
from twin.errors import MapError

FAST = settings(max_examples=examples(120), deadline=None, suppress_health_check=list(HealthCheck))
floats = st.floats(allow_nan=True, allow_infinity=True, width=64)
text = st.text(max_size=12)
stamps = st.tuples(st.integers(-(2**31), 2**31 - 1), st.integers(0, 2**32 - 1))
unit = st.sampled_from([(0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.6, 0.8), (0.5, -0.5, 0.5, 0.5)])


@st.composite
def messages(draw: st.DrawFn) -> Any:
    """TFMessages of 0-4 transforms: any frames, stamps and doubles, or (half the time) a unit
    quaternion, so that both the accepted and the refused transforms are drawn."""
    t = _typestore().types
    time, header = t["builtin_interfaces/msg/Time"], t["std_msgs/msg/Header"]
    vec, quat = t["geometry_msgs/msg/Vector3"], t["geometry_msgs/msg/Quaternion"]
    transform, stamped = t["geometry_msgs/msg/Transform"], t["geometry_msgs/msg/TransformStamped"]
    out = []
    for _ in range(draw(st.integers(0, 4))):
        sec, nsec = draw(stamps)
        q = draw(unit) if draw(st.booleans()) else tuple(draw(floats) for _ in range(4))
        out.append(
            stamped(
                header=header(stamp=time(sec=sec, nanosec=nsec), frame_id=draw(text)),
                child_frame_id=draw(text),
                transform=transform(
                    translation=vec(x=draw(floats), y=draw(floats), z=draw(floats)),
                    rotation=quat(x=q[0], y=q[1], z=q[2], w=q[3]),
                ),
            )
        )
    return t[TF_MESSAGE](transforms=out)


def _cdr(message: Any, *, little_endian: bool = True) -> bytes:
    return bytes(_typestore().serialize_cdr(message, TF_MESSAGE, little_endian=little_endian))


def _decoded(payload: bytes) -> Any:
    """What :func:`decode_tf_message` makes of ``payload``: its transforms' bits, or its error's text."""
    try:
        return bits(decode_tf_message(payload))
    except MapError as err:
        return ("refused", str(err))


@FAST
@given(message=messages())
def test_the_hand_decoder_reads_every_field_rosbags_reads_and_big_endian_goes_to_rosbags(
    message: Any,
) -> None:
    le, be = _cdr(message), _cdr(message, little_endian=False)
    fast = _decode_le(le)
    assert fast is not None
    assert bits(fast) == bits(_decode_rosbags(le)) == bits(_decode_rosbags(be))
    assert _decode_le(be) is None
    assert _decoded(le) == _decoded(be)  # the same transforms, or refused with the same message


@FAST
@given(
    message=messages(),
    cut=st.integers(0, 600),
    flips=st.lists(st.tuples(st.integers(0, 600), st.integers(0, 255)), max_size=4),
    tail=st.binary(max_size=8),
)
def test_on_hostile_bytes_the_hand_decoder_accepts_nothing_rosbags_refuses(
    message: Any, cut: int, flips: list[tuple[int, int]], tail: bytes
) -> None:
    payload = mutated(_cdr(message), cut, flips, tail)
    accepts_nothing_refused(payload, _decode_le, _decode_rosbags, MapError)


@pytest.mark.parametrize(
    ("tf", "message"),
    [
        (Tf("map", "base_link", (1.0, float("nan"), 0.0)), "Transform 'map' -> 'base_link' is not finite"),
        (Tf("map", "base_link", (1.0, 2.0, 0.0), (0.0, 0.0, 0.0, 2.0)), "has a quaternion of norm 2.0"),
        (Tf("/map", "map", (1.0, 2.0, 0.0)), "Transform 'map' -> 'map' does not join two named frames"),
    ],
)
def test_a_transform_that_is_not_one_is_refused_by_the_hand_decoder_as_by_rosbags(
    tf: Tf, message: str
) -> None:
    payload = cdr_tf([Tf("map", "odom", (0.0, 0.0, 0.0)), tf])
    assert _decode_le(payload) is not None  # read by hand, and refused for what it holds
    with pytest.raises(MapError, match=message):
        decode_tf_message(payload)


def test_a_transform_read_by_hand_is_its_parent_child_stamp_and_normalised_pose() -> None:
    payload = cdr_tf(
        [Tf("/map", "base_link", (15.2, 7.1, 0.0), (0.0, 0.0, 0.6, 0.8), 1_700_000_000_123_456_789)]
    )
    (sample,) = decode_tf_message(payload)
    assert sample == TransformSample(
        "map", "base_link", 1_700_000_000_123_456_789, (15.2, 7.1, 0.0), (0.0, 0.0, 0.6, 0.8)
    )
