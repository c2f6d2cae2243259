"""The robot storey key (``twin/<site>/robots/<robot>/storey``) with hostile payloads, in process: the
daemon's live path as ``serve`` composes it (:mod:`tests.adapters.served_twin`: a real writer decides
every switch), a robot's session beside it."""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator

import pytest
import zenoh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from adapters.zenoh.ros_maps import RosMapPublisher
from adapters.zenoh.session import client_config
from tests.adapters.served_twin import KEYS, robots_config, served_twin
from tests.conftest import examples


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[zenoh.Session, RosMapPublisher]]:
    with served_twin(robots_config(tmp_path_factory.mktemp("storey"))) as twin:
        robot = zenoh.open(client_config([twin.endpoint]))
        try:
            yield robot, twin.ros
        finally:
            robot.close()


def _get(session: zenoh.Session, payload: bytes | None) -> list[tuple[bool, bytes]]:
    replies = session.get(KEYS.robot_storey("robot1"), payload=payload, timeout=5.0)
    return [
        (True, r.ok.payload.to_bytes()) if r.ok is not None else (False, r.err.payload.to_bytes())
        for r in replies
    ]


def _until_on(ros: RosMapPublisher, storey: str, timeout_s: float = 5.0) -> None:
    """A put and a later get take different paths in Zenoh: wait for the put to be handled."""
    deadline = time.monotonic() + timeout_s
    while ros.storey_of("robot1") != storey:
        assert time.monotonic() < deadline, f"robot1 still on {ros.storey_of('robot1')!r}, not {storey!r}"
        time.sleep(0.01)


def test_a_get_whose_payload_is_not_utf8_gets_an_error_reply_naming_the_bytes(
    served: tuple[zenoh.Session, RosMapPublisher], caplog: pytest.LogCaptureFixture
) -> None:
    robot, ros = served
    with caplog.at_level(logging.WARNING):
        replies = _get(robot, b"\xff\xfeground")
    assert len(replies) == 1
    ok, text = replies[0]
    assert not ok and b"not" in text and b"UTF-8" in text and b"\\xff\\xfe" in text
    assert not [r for r in caplog.records if r.exc_info]
    assert ros.storey_of("robot1") == "ground-floor"
    assert _get(robot, None) == [(True, b"ground-floor")]  # still answering


def test_a_put_whose_payload_is_not_utf8_is_refused_with_a_warning_and_no_traceback(
    served: tuple[zenoh.Session, RosMapPublisher], caplog: pytest.LogCaptureFixture
) -> None:
    robot, ros = served
    with caplog.at_level(logging.WARNING, logger="adapters.zenoh.ros_maps"):
        robot.put(KEYS.robot_storey("robot1"), b"first\xc3(floor")
        robot.put(KEYS.robot_storey("robot1"), b"first-floor")  # in order: after the refusal
        _until_on(ros, "first-floor")
    refusals = [r for r in caplog.records if "Refused a storey put" in r.getMessage()]
    assert len(refusals) == 1 and "UTF-8" in refusals[0].getMessage()
    assert not [r for r in caplog.records if r.exc_info]
    robot.put(KEYS.robot_storey("robot1"), b"ground-floor")
    _until_on(ros, "ground-floor")
    assert _get(robot, None) == [(True, b"ground-floor")]


@settings(
    max_examples=examples(40), deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(payload=st.binary(max_size=64))
def test_any_bytes_on_the_storey_key_get_a_reply_and_leave_no_traceback(
    served: tuple[zenoh.Session, RosMapPublisher], caplog: pytest.LogCaptureFixture, payload: bytes
) -> None:
    robot, ros = served
    caplog.clear()
    robot.put(KEYS.robot_storey("robot1"), payload)
    replies = _get(robot, payload)
    assert len(replies) == 1  # an answer or an error, never silence
    assert not [r for r in caplog.records if r.exc_info]
    robot.put(KEYS.robot_storey("robot1"), b"ground-floor")
    _until_on(ros, "ground-floor")
    assert not [r for r in caplog.records if r.exc_info]
