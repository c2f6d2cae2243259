"""The ROS 2 map topics in one process, on the daemon's live path as ``serve`` composes it
(:mod:`tests.adapters.served_twin`: a real writer over the two-storey box lab): a robot's storey, sent on
its ROS topic, is decided by the writer and changes which floor its topics carry; a floor it is not on
never reaches its topics."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import zenoh
import zenoh.ext

from adapters.ros.cdr import STRING, encode_string
from adapters.ros.rmw_zenoh import RosTopic
from adapters.zenoh.session import client_config
from tests.adapters.served_twin import KEYS, ServedTwin, robots_config, served_twin, until
from tests.adapters.zenoh.test_zenoh_maps import Follower
from tests.twin.live_helpers import box_turtle
from twin.live.events import RobotStoreyChanged, TwinEvent

GROUND, FIRST = "ground-floor", "first-floor"


class Storeys:
    """A sink that keeps every storey switch the writer emits, with the thread it came on."""

    def __init__(self) -> None:
        self.seen: list[tuple[RobotStoreyChanged, int]] = []

    def emit(self, event: TwinEvent) -> None:
        if isinstance(event, RobotStoreyChanged):
            self.seen.append((event, threading.get_ident()))


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[ServedTwin, zenoh.Session, Follower, Storeys]]:
    storeys = Storeys()
    with served_twin(robots_config(tmp_path), sinks=[storeys]) as twin:
        robot = zenoh.open(client_config([twin.endpoint]))
        topic = Follower(twin.endpoint, "/robot1", "navigation_map", "bridge")  # latched, history
        try:
            until(lambda: topic.shows(twin.live_map(GROUND, "navigation")), what="the ground floor's map")
            yield twin, robot, topic, storeys
        finally:
            topic.close()
            robot.close()


def put_storey(robot: zenoh.Session, layout: str, storey: str) -> None:
    """What a lift controller's ``std_msgs/String`` on ``/robot1/storey`` looks like on the wire."""
    topic = RosTopic(0, "/robot1", "storey", STRING)
    robot.put(topic.data_key if layout == "rmw_zenoh" else topic.bridge_key, encode_string(storey))


@pytest.mark.parametrize("layout", ["bridge", "rmw_zenoh"])
def test_a_storey_a_ros_robot_publishes_is_decided_by_the_writer_and_its_topic_then_carries_that_floor(
    served: tuple[ServedTwin, zenoh.Session, Follower, Storeys], layout: str
) -> None:
    twin, robot, topic, storeys = served
    first = twin.live_map(FIRST, "navigation")
    assert not np.array_equal(first, twin.live_map(GROUND, "navigation"))  # else the test proves nothing
    put_storey(robot, layout, FIRST)
    until(lambda: topic.shows(first), what="the first floor's map on /robot1/navigation_map")
    assert twin.service.robot_storey("robot1") == FIRST  # the writer's decision
    assert twin.ros.storey_of("robot1") == FIRST
    ((event, thread),) = storeys.seen
    assert (event.robot, event.storey, event.previous, event.source) == ("robot1", FIRST, GROUND, "ros")
    assert thread == twin.writer.ident
    status = twin.ros.status()["robots"]["robot1"]  # type: ignore[index]
    assert status["switches"] == 1 and status["refused"] is None  # type: ignore[index]
    again = robot.get(KEYS.robot_storey("robot1"), payload=FIRST.encode(), timeout=5.0)  # via the writer
    assert [r.ok.payload.to_bytes() for r in again if r.ok is not None] == [FIRST.encode()]
    twin.daemon.drain()
    assert len(storeys.seen) == 1 and topic.maps == 2  # the same storey again: no switch, no map


def test_an_unknown_storey_from_a_ros_robot_is_refused_by_the_writer_and_its_topic_keeps_its_floor(
    served: tuple[ServedTwin, zenoh.Session, Follower, Storeys],
) -> None:
    twin, robot, topic, storeys = served
    put_storey(robot, "bridge", "attic")

    def refused() -> str | None:
        return twin.ros.status()["robots"]["robot1"]["refused"]  # type: ignore[index, no-any-return]

    until(lambda: refused() is not None, what="the refusal")
    assert "attic" in (refused() or "") and FIRST in (refused() or "")  # names it and the storeys
    twin.daemon.drain()
    assert storeys.seen == [] and twin.service.robot_storey("robot1") == GROUND
    assert topic.maps == 1 and topic.shows(twin.live_map(GROUND, "navigation"))


def test_a_change_on_the_robots_floor_reaches_its_topic_as_an_update_and_one_on_another_floor_does_not(
    served: tuple[ServedTwin, zenoh.Session, Follower, Storeys],
) -> None:
    twin, robot, topic, _ = served

    def observe(storey: str) -> list[tuple[str, str]]:
        payload = box_turtle(f"urn:robot1:table-{storey}", 6.6, 2.0, storey=storey)
        (reply,) = robot.get(KEYS.observe("robot1"), payload=payload, timeout=10.0)
        assert reply.ok is not None, reply.err.payload.to_string()
        return [(m["storey"], m["skill"]) for m in json.loads(reply.ok.payload.to_bytes())["maps"]]

    assert (FIRST, "navigation") in observe(FIRST)  # the first floor's map changed
    twin.daemon.drain()
    assert topic.maps == 1 and topic.updates == 0  # robot1 is on the ground floor
    assert (GROUND, "navigation") in observe(GROUND)
    until(lambda: topic.updates == 1, what="the ground floor's update")
    twin.daemon.drain()
    assert topic.maps == 1 and topic.shows(twin.live_map(GROUND, "navigation"))
