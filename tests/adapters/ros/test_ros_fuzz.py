"""Hostile ROS input never crashes the translation: malformed CDR, NaN and huge poses and sizes,
unknown frames, stamps in the future, oversized arrays, a message of another type. Each is refused
with a cause (``RosInputError``) or left out and counted; whatever document comes out is one the
core's parser accepts (so nothing invalid reaches the twin). Many examples, fast (no daemon)."""

from __future__ import annotations

import contextlib

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from adapters.ros.detections import translate_detections
from adapters.ros.observation_doc import RosInputError, Translation
from adapters.ros.rmf import DoorSettings, ObstacleTracker, translate_door_state
from adapters.ros.tf import TfError, decode_tf_message
from tests.adapters.ros.test_ros_detections import NOW, SETTINGS, ctx
from tests.adapters.ros.test_ros_rmf import INDEX
from tests.adapters.ros.test_ros_rmf import SETTINGS as OBSTACLE_SETTINGS
from tests.adapters.ros_reports import (
    Det,
    Obstacle,
    Tf,
    cdr_detections,
    cdr_door_state,
    cdr_obstacles,
    cdr_tf,
)
from tests.conftest import examples
from twin.config import Limits
from twin.errors import MapError
from twin.live.parse import parse_observation

FUZZ = settings(max_examples=examples(200), deadline=None, suppress_health_check=list(HealthCheck))
WILD = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-1e3, 1e3),
    st.sampled_from([0.0, 1e308, -1e308, 5e-324, 1.0]),
)
FRAMES = st.sampled_from(["map", "camera_optical_frame", "base_link", "lidar", "", "/map", "x" * 300])
STAMPS = st.one_of(
    st.just(NOW), st.integers(0, 2**31 - 1).map(lambda s: s * 1_000_000_000), st.just(NOW + 10**12)
)


def check(t: Translation) -> None:
    """A translation's document, if any, is valid for the core (elements alone: the fusion terms are
    issue 28's and the parser may not read them yet)."""
    for document in t.documents:
        if b"twin:View" not in document and b"senseTime" not in document:
            parse_observation(document, limits=Limits())


@st.composite
def detections(draw: st.DrawFn) -> Det:
    results = draw(st.lists(st.tuples(st.sampled_from(["table", "chair", "person", ""]), WILD), max_size=3))
    position = draw(st.tuples(WILD, WILD, WILD))
    size = draw(st.tuples(WILD, WILD, WILD))
    orientation = draw(st.one_of(st.just((0.0, 0.0, 0.0, 1.0)), st.tuples(WILD, WILD, WILD, WILD)))
    return Det(tuple(results), position, size, orientation, draw(st.sampled_from(["", "7", 'a b<>"', "é"])))


@FUZZ
@given(stamp=STAMPS, frame=FRAMES, dets=st.lists(detections(), max_size=6))
def test_any_detection_array_is_translated_or_refused_never_crashing(
    stamp: int, frame: str, dets: list[Det]
) -> None:
    with contextlib.suppress(RosInputError):
        check(translate_detections(cdr_detections(stamp, frame, dets), SETTINGS, ctx(fusion_terms=False)))
        check(translate_detections(cdr_detections(stamp, frame, dets), SETTINGS, ctx()))


@FUZZ
@given(
    data=st.data(),
    cut=st.integers(0, 400),
    flips=st.lists(st.tuples(st.integers(0, 400), st.integers(0, 255)), max_size=8),
)
def test_mutated_and_truncated_bytes_are_refused_or_translated(
    data: st.DataObject, cut: int, flips: list[tuple[int, int]]
) -> None:
    kind = data.draw(st.sampled_from(["det", "door", "obstacles", "tf", "random"]))
    base = {
        "det": cdr_detections(
            NOW, "camera_optical_frame", [Det((("table", 0.9),), (0, 0.6, 2.4), (0.6, 0.6, 0.75), id="1")]
        ),
        "door": cdr_door_state(NOW, "Door A", 2),
        "obstacles": cdr_obstacles(
            NOW, [Obstacle(1, "c", "L1", "human", (1, 2, 0.9), (0.5, 0.5, 1.8), 10**9)]
        ),
        "tf": cdr_tf([Tf("map", "base_link", (1, 2, 0), stamp_ns=NOW)]),
        "random": data.draw(st.binary(max_size=300)),
    }[kind]
    raw = bytearray(base[: max(cut, 0)] if cut < len(base) else base)
    for at, value in flips:
        if at < len(raw):
            raw[at] = value
    payload = bytes(raw)
    # every translator gets every payload: a message of the wrong type is one of the cases
    with contextlib.suppress(RosInputError):
        check(translate_detections(payload, SETTINGS, ctx()))
    with contextlib.suppress(RosInputError):
        check(translate_door_state(payload, DoorSettings("doors", {}), INDEX))
    with contextlib.suppress(RosInputError):
        check(ObstacleTracker(OBSTACLE_SETTINGS).translate(payload, now_ns=NOW))
    with contextlib.suppress(MapError, TfError):
        decode_tf_message(payload)


@FUZZ
@given(
    obstacles=st.lists(
        st.builds(
            Obstacle,
            st.integers(-5, 5),
            st.sampled_from(["a", "b"]),
            st.sampled_from(["L1", "L2", "?"]),
            st.sampled_from(["human", "x"]),
            st.tuples(WILD, WILD, WILD),
            st.tuples(WILD, WILD, WILD),
            st.integers(0, 10**10),
            st.integers(0, 4),
        ),
        max_size=8,
    )
)
def test_any_obstacles_are_translated_or_refused_never_crashing(obstacles: list[Obstacle]) -> None:
    tracker = ObstacleTracker(OBSTACLE_SETTINGS)
    with contextlib.suppress(RosInputError):
        check(tracker.translate(cdr_obstacles(NOW, obstacles), now_ns=NOW))
    check(tracker.expire(now_ns=NOW + 10**11))
    assert tracker.held == 0 or tracker.next_expiry() is None or tracker.next_expiry() > NOW + 10**11  # type: ignore[operator]
