"""Map publication on Zenoh in process: a real :class:`~adapters.zenoh.ros_maps.RosMapPublisher` on one
session, fed the twin's events by hand as the daemon's dispatcher feeds it (its holder,
:class:`~adapters.zenoh.latest.LatestMaps`, first), robots as sessions of their own on loopback.

What a late joiner gets (the current map, updates applied, once), what a robot topic's ``full_every_s``
policy sends, and that a robot whose sends are stuck holds only its own lane."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zenoh
import zenoh.ext

from adapters.ros import decode_occupancy_grid, decode_occupancy_grid_update
from adapters.ros.cdr import OCCUPANCY_GRID, OCCUPANCY_GRID_UPDATE
from adapters.ros.rmw_zenoh import RosTopic
from adapters.ros.settings import RosSettings
from adapters.zenoh.latest import LatestMaps
from adapters.zenoh.ros_maps import RosMapPublisher
from adapters.zenoh.session import client_config, session_config
from adapters.zenoh.settings import ZenohSettings
from tests.integration.conftest import free_port
from twin.config import Config, load_config
from twin.live.events import MapPublished, MapUpdated, RobotStoreyChanged, TwinEvent, TwinStarted
from twin.live.requests import Reply, ReplyFn
from twin.maps.grid import GridFrame, OccupancyGrid, Window

ROBOTS = """
[robots.robot1]
namespace = "/robot1"
storey = "ground-floor"
[robots.robot1.full_every_s]
map = 0.6

[robots.robot2]
namespace = "/robot2"
storey = "ground-floor"
"""
FRAME = GridFrame(0.0, 0.0, 0.05, 120, 80)
STOREYS = (("ground-floor", "Ground floor", 0.0), ("first-floor", "First floor", 3.0))


def until(predicate: Callable[[], bool], timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


def no_writer(robot: str, storey: str, *, source: str, reply: ReplyFn) -> None:
    """These tests feed the writer's decisions by hand (``RobotStoreyChanged``) and ask it nothing."""
    reply(Reply.error(f"No writer in this test to put {robot!r} on {storey!r} ({source})."))


class Served:
    """The publisher, its session's endpoint, and the maps as the twin has them."""

    def __init__(self, config: Config) -> None:
        self.endpoint = f"tcp/127.0.0.1:{free_port()}"
        self.session = zenoh.open(
            session_config(ZenohSettings(), mode="peer", listen=[self.endpoint], connect=[])
        )
        self.latest = LatestMaps(
            frame_id=config.section(RosSettings).frame_id, timestamp=self.session.new_timestamp
        )
        self.ros = RosMapPublisher(self.session, config, maps=self.latest, request=no_writer)
        self.emit(TwinStarted("lab", 0, 1, STOREYS, (), {}))
        rng = np.random.default_rng(3)
        self.maps: dict[tuple[str, str], np.ndarray] = {}
        self.versions: dict[tuple[str, str], int] = {}
        for storey, _, _ in STOREYS:
            for skill in ("localization", "navigation"):
                data = rng.choice(np.array([0, 100, -1], np.int8), size=FRAME.shape)
                self.maps[(storey, skill)] = data
                self.versions[(storey, skill)] = 1
                self.emit(MapPublished(OccupancyGrid(FRAME, data.copy(), storey, skill), 0, 1, 10))

    def emit(self, event: TwinEvent) -> None:
        """What the daemon's dispatcher does with the writer's event: the holder first, then the sends."""
        if isinstance(event, MapPublished):
            self.latest.publish(event)
        elif isinstance(event, MapUpdated) and not self.latest.update(event):
            return
        self.ros.emit(event)

    def change(self, storey: str, skill: str, row: int, col: int, value: int) -> None:
        key = (storey, skill)
        self.maps[key][row : row + 3, col : col + 4] = value
        self.versions[key] += 1
        window = Window(row, col, row + 3, col + 4)
        cells = self.maps[key][row : row + 3, col : col + 4].copy()
        self.emit(MapUpdated(storey, skill, FRAME, window, cells, 1, self.versions[key], time.time_ns()))

    def close(self) -> None:
        self.ros.close()
        self.session.close()


@pytest.fixture
def served(tmp_path: Path) -> Iterator[Served]:
    path = tmp_path / "robots.toml"
    path.write_text(ROBOTS)
    s = Served(load_config(path))
    yield s
    s.close()


class Follower:
    """A robot's copy of one topic in one layout: updates' subscriber first, then the latched map."""

    def __init__(self, endpoint: str, ns: str, topic: str, layout: str) -> None:
        maps = RosTopic(0, ns, topic, OCCUPANCY_GRID)
        updates = RosTopic(0, ns, f"{topic}_updates", OCCUPANCY_GRID_UPDATE)
        rmw = layout == "rmw_zenoh"
        self.lock = threading.Lock()
        self.grid: np.ndarray | None = None
        self.full: np.ndarray | None = None  # the last full map, as it came
        self.maps = 0
        self.updates = 0
        self.session = zenoh.open(client_config([endpoint]))
        self.entities: list[Any] = [
            self.session.declare_subscriber(updates.data_key if rmw else updates.bridge_key, self._on_update),
            zenoh.ext.declare_advanced_subscriber(  # rmw_zenoh: also recovery by heartbeat (RELIABLE)
                self.session,
                maps.data_key if rmw else maps.bridge_key,
                self._on_map,
                history=zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=1),
                recovery=zenoh.ext.RecoveryConfig(heartbeat=True) if rmw else None,
                subscriber_detection=rmw,
            ),
        ]

    def _on_map(self, sample: zenoh.Sample) -> None:
        grid, _ = decode_occupancy_grid(sample.payload.to_bytes())
        with self.lock:
            self.grid, self.full, self.maps = grid.data.copy(), grid.data, self.maps + 1

    def _on_update(self, sample: zenoh.Sample) -> None:
        window, cells, _ = decode_occupancy_grid_update(sample.payload.to_bytes())
        with self.lock:
            self.updates += 1
            if self.grid is not None:
                self.grid[window.row0 : window.row1, window.col0 : window.col1] = cells

    def shows(self, cells: np.ndarray) -> bool:
        with self.lock:
            return self.grid is not None and np.array_equal(self.grid, cells)

    def shows_in_full(self, cells: np.ndarray) -> bool:
        """Whether the last full map that came is ``cells`` (updates left aside)."""
        with self.lock:
            return self.full is not None and np.array_equal(self.full, cells)

    def close(self) -> None:
        for e in self.entities:
            e.undeclare()
        self.session.close()


@pytest.mark.parametrize("layout", ["rmw_zenoh", "bridge"])
def test_a_late_joiner_gets_the_current_map_with_every_update_applied_once(
    served: Served, layout: str
) -> None:
    for i in range(5):
        served.change("ground-floor", "navigation", 10 + 5 * i, 20, 100)  # updates only, no full map
    served.ros.drain()
    late = Follower(served.endpoint, "/robot2", "navigation_map", layout)
    try:
        until(lambda: late.grid is not None)
        time.sleep(0.7)  # its late-publisher query and a heartbeat's recovery query answer too
        with late.lock:
            assert late.grid is not None
            np.testing.assert_array_equal(late.grid, served.maps[("ground-floor", "navigation")])
            assert late.maps == 1
        served.change("ground-floor", "navigation", 50, 50, 0)
        until(lambda: late.updates >= 1)
        with late.lock:
            np.testing.assert_array_equal(late.grid, served.maps[("ground-floor", "navigation")])
    finally:
        late.close()


def test_a_topic_with_full_every_s_gets_full_maps_at_most_that_often_and_only_when_its_map_changes(
    served: Served,
) -> None:
    amcl = Follower(served.endpoint, "/robot1", "map", "rmw_zenoh")  # map = localization, full_every_s 0.6
    other = Follower(served.endpoint, "/robot2", "map", "rmw_zenoh")  # no policy: updates only
    localization = served.maps[("ground-floor", "localization")]
    try:
        until(lambda: amcl.maps == 1 and other.maps == 1)
        for _ in range(3):
            served.change("ground-floor", "navigation", 5, 5, 100)  # not this topic's map
        served.ros.drain()
        time.sleep(0.8)
        assert amcl.maps == 1 and amcl.updates == 0
        t0 = time.monotonic()
        for i in range(12):  # 1.2 s of changes, every 0.1 s
            served.change("ground-floor", "localization", 2 + i, 3, 100)
            time.sleep(max(0.0, t0 + 0.1 * (i + 1) - time.monotonic()))
        until(lambda: amcl.shows_in_full(localization))  # the last one owed
        took = time.monotonic() - t0
        with amcl.lock:
            # the full maps went out at least 0.6 s apart within ``took`` (1.2 s and the wait for the
            # last owed on a quiet machine: 4 at most; a loaded one stretches the changes)
            assert 2 <= amcl.maps - 1 <= took / 0.6 + 1, took
            np.testing.assert_array_equal(amcl.grid, localization)
        until(lambda: other.updates == 12)
        with other.lock:
            assert other.maps == 1
            np.testing.assert_array_equal(other.grid, localization)
    finally:
        amcl.close()
        other.close()


def test_a_robot_whose_sends_are_stuck_holds_only_its_own_lane(served: Served) -> None:
    one = Follower(served.endpoint, "/robot1", "navigation_map", "rmw_zenoh")
    two = Follower(served.endpoint, "/robot2", "navigation_map", "rmw_zenoh")
    stuck = threading.Event()
    try:
        until(lambda: one.maps == 1 and two.maps == 1)
        lane = served.ros._robots["robot1"].lane  # a send to robot1 that blocks, as on a stalled link
        assert lane is not None
        lane.put(lambda: stuck.wait(30))
        for i in range(10):
            served.change("ground-floor", "navigation", 3 * i, 7, 100)
        until(lambda: two.updates == 10)  # robot2 is served while robot1's lane waits
        assert one.updates == 0
        stuck.set()
        until(lambda: one.updates == 10)  # then robot1 gets every one, in order
        for f in (one, two):
            with f.lock:
                np.testing.assert_array_equal(f.grid, served.maps[("ground-floor", "navigation")])
    finally:
        stuck.set()
        one.close()
        two.close()


def test_a_storey_switch_sends_the_new_floors_current_map_and_a_late_joiner_gets_it(served: Served) -> None:
    early = Follower(served.endpoint, "/robot2", "navigation_map", "bridge")
    try:
        until(lambda: early.maps == 1)
        served.change("first-floor", "navigation", 30, 30, 100)  # updates of a floor robot2 is not on
        served.emit(RobotStoreyChanged("robot2", "first-floor", "ground-floor", "zenoh", 1, time.time_ns()))
        until(lambda: early.maps == 2)
        late = Follower(served.endpoint, "/robot2", "navigation_map", "rmw_zenoh")
        until(lambda: late.maps >= 1)
        for f in (early, late):
            with f.lock:
                np.testing.assert_array_equal(f.grid, served.maps[("first-floor", "navigation")])
        late.close()
    finally:
        early.close()
