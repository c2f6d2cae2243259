"""The daemon's Zenoh side in one process (:mod:`tests.adapters.served_twin`: a real writer over the box
lab, its ZenohDaemon and RosMapPublisher as ``serve`` composes them), robots as client sessions on
loopback: what a ``get`` answers, how an observation's change reaches a subscriber, and on which thread
the events reach the sinks and the followers."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import zenoh

from adapters.ros import decode_occupancy_grid, decode_occupancy_grid_update
from adapters.zenoh.session import client_config
from tests.adapters.served_twin import KEYS, ServedTwin, robots_config, served_twin, until
from tests.twin.live_helpers import box_turtle
from twin.live.events import (
    MapPublished,
    MapUpdated,
    ObservationAccepted,
    RobotStoreyChanged,
    TwinEvent,
    TwinStarted,
)

GROUND = "ground-floor"
TABLE = "urn:robot1:table-1"


class Threads:
    """A sink (or follower) that keeps, for every event, its kind and the thread it came on."""

    def __init__(self) -> None:
        self.seen: list[tuple[type, int, str]] = []

    def emit(self, event: TwinEvent) -> None:
        t = threading.current_thread()
        self.seen.append((type(event), threading.get_ident(), t.name))

    def kinds(self) -> set[type]:
        return {kind for kind, _, _ in self.seen}


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[ServedTwin, zenoh.Session, Threads, Threads]]:
    sink, follower = Threads(), Threads()
    with served_twin(robots_config(tmp_path), sinks=[sink], followers=[follower]) as twin:
        robot = zenoh.open(client_config([twin.endpoint]))
        try:
            yield twin, robot, sink, follower
        finally:
            robot.close()


Got = dict[tuple[str, str], tuple[np.ndarray, dict[str, int]]]


def get_maps(session: zenoh.Session, selector: str) -> Got:
    """Every map a ``get`` answers: its cells and its attachment (revision, version)."""
    got: Got = {}
    for reply in session.get(selector, timeout=10.0):
        assert reply.ok is not None, reply.err.payload.to_string()
        key = KEYS.map_of(str(reply.ok.key_expr))
        assert key is not None and key not in got
        grid, _ = decode_occupancy_grid(reply.ok.payload.to_bytes())
        assert reply.ok.attachment is not None
        got[key] = (grid.data, json.loads(reply.ok.attachment.to_bytes()))
    return got


def observe(session: zenoh.Session, payload: bytes) -> dict[str, object]:
    (reply,) = session.get(KEYS.observe("robot1"), payload=payload, timeout=10.0)
    assert reply.ok is not None, reply.err.payload.to_string()
    ack: dict[str, object] = json.loads(reply.ok.payload.to_bytes())
    return ack


def test_a_late_joiner_gets_every_current_map_by_get_equal_to_the_writers(
    served: tuple[ServedTwin, zenoh.Session, Threads, Threads],
) -> None:
    twin, robot, _, _ = served
    got = get_maps(robot, KEYS.maps)
    assert set(got) == set(twin.service.live.maps.skill_maps)  # every map, each once
    for (storey, skill), (cells, attachment) in got.items():
        np.testing.assert_array_equal(cells, twin.live_map(storey, skill))
        m = twin.service.live.maps.skill_maps[(storey, skill)]
        assert attachment == {"revision": twin.service.revision, "version": m.version}
    one = get_maps(robot, KEYS.map(GROUND, "navigation"))
    assert list(one) == [(GROUND, "navigation")]  # a selector answers only what it names


def test_an_observation_changes_the_map_its_update_arrives_and_a_get_then_answers_the_changed_map(
    served: tuple[ServedTwin, zenoh.Session, Threads, Threads],
) -> None:
    twin, robot, _, _ = served
    key = (GROUND, "navigation")
    ((before, held),) = get_maps(robot, KEYS.map(*key)).values()
    copy = before.copy()
    updates: list[tuple[int, int]] = []
    lock = threading.Lock()

    def on_update(sample: zenoh.Sample) -> None:
        window, cells, _ = decode_occupancy_grid_update(sample.payload.to_bytes())
        assert sample.attachment is not None
        version = json.loads(sample.attachment.to_bytes())["version"]
        with lock:
            copy[window.row0 : window.row1, window.col0 : window.col1] = cells
            updates.append((version, window.row1 - window.row0))

    sub = robot.declare_subscriber(KEYS.map_updates(*key), on_update)
    try:
        ack = observe(robot, box_turtle(TABLE, 6.6, 2.0))
        assert ack["ok"] and ack["revision"] == 1
        (change,) = [m for m in ack["maps"] if (m["storey"], m["skill"]) == key]  # type: ignore[attr-defined, index]
        until(lambda: len(updates) >= 1, what="the update of the table's cells")
        twin.daemon.drain()
        with lock:
            assert [v for v, _ in updates] == [change["version"]] == [held["version"] + 1]
            now = twin.live_map(*key)
            assert not np.array_equal(now, before)  # the table is in the map
            np.testing.assert_array_equal(copy, now)  # the update brings a copy to the writer's map
    finally:
        sub.undeclare()
    ((after, attachment),) = get_maps(robot, KEYS.map(*key)).values()
    np.testing.assert_array_equal(after, now)  # a get after the ack answers the change (updates applied)
    assert attachment == {"revision": 1, "version": change["version"]}


def test_events_reach_the_sinks_on_the_writers_thread_and_the_followers_on_the_dispatcher_only(
    served: tuple[ServedTwin, zenoh.Session, Threads, Threads],
) -> None:
    twin, robot, sink, follower = served
    assert observe(robot, box_turtle(TABLE, 6.6, 2.0))["ok"]
    robot.put(KEYS.robot_storey("robot1"), b"first-floor")  # a storey switch: the writer decides
    until(lambda: twin.ros.storey_of("robot1") == "first-floor", what="robot1 on the first floor")
    twin.daemon.drain()
    writer = twin.writer.ident
    assert {TwinStarted, MapPublished, MapUpdated, ObservationAccepted, RobotStoreyChanged} <= sink.kinds()
    assert {ident for _, ident, _ in sink.seen} == {writer}
    assert {TwinStarted, MapPublished, MapUpdated, RobotStoreyChanged} <= follower.kinds()
    assert {name for _, _, name in follower.seen} == {"twin-zenoh-out"}  # the daemon's dispatcher
    assert writer not in {ident for _, ident, _ in follower.seen}
