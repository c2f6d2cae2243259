"""What a restart remembers of Open-RMF obstacles: the tracker takes back from the graph the obstacles
a previous run added, so DELETE, DELETEALL and lifetimes hold across a clean stop and start."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from adapters.ros.interfaces import OBSTACLES
from adapters.zenoh.client import TwinClient
from tests.adapters.ros_reports import Obstacle, cdr_obstacles
from tests.integration.conftest import Daemon, start_daemon
from tests.integration.settled import map_where
from tests.integration.test_ros_ingest import Publisher, cells, config, counts, wait_until
from twin.maps.grid import OccupancyGrid

pytestmark = pytest.mark.slow

OCCUPIED = 100
DELETE, DELETEALL = 2, 3


def _at(grid: OccupancyGrid, x: float) -> bool:
    spot = cells(grid, x, 7.0, 0.5, 0.5, grow=-grid.frame.resolution_m)
    return bool((grid.data[spot] == OCCUPIED).all())


def _expired(added_at: float, lifetime_s: float = 6.0) -> int:
    """1 once the brief obstacle's lifetime has surely run out (with a second's margin), else 0."""
    return int(time.monotonic() - added_at > lifetime_s + 1.0)


def test_delete_deleteall_and_lifetimes_of_obstacles_hold_across_a_restart(
    fresh_store: Path, tmp_path: Path
) -> None:
    path = tmp_path / "robots.toml"
    path.write_text(config("rmw_zenoh"))
    stamp = time.time_ns()
    kept = Obstacle(1, "cam_a", "L1", "human", (10.0, 7.0, 0.9), (0.5, 0.5, 1.8))
    brief = Obstacle(2, "cam_a", "L1", "human", (12.0, 7.0, 0.9), (0.5, 0.5, 1.8), lifetime_ns=6 * 10**9)
    other = Obstacle(3, "cam_b", "L1", "human", (14.0, 7.0, 0.9), (0.5, 0.5, 1.8))
    other2 = Obstacle(4, "cam_b", "L1", "human", (16.0, 7.0, 0.9), (0.5, 0.5, 1.8))
    d: Daemon = start_daemon(fresh_store, "--no-record", "-v", config=path)
    try:
        with TwinClient.connect([d.endpoint], prefix="twin/lab") as client:
            robot = Publisher(d, "rmw_zenoh")
            robot.send("/rmf_obstacles", OBSTACLES, cdr_obstacles(stamp, [kept, brief, other, other2]))
            wait_until(client, lambda s: s["ros_ingest"]["obstacles_held"] == 4)
            added_at = time.monotonic()
            map_where(client, lambda g: all(_at(g, x) for x in (10.0, 12.0, 14.0, 16.0)), "the 4 obstacles")
            robot.close_stdin_and_wait()
        d.stop_cleanly()

        d = start_daemon(fresh_store, "--no-record", "-v", config=path)
        with TwinClient.connect([d.endpoint], prefix="twin/lab") as client:
            status = wait_until(client, lambda s: s["ros_ingest"]["obstacles_held"] == 4)
            assert any("4 obstacle(s) of a previous run held again" in line for line in d.log), d.log
            robot = Publisher(d, "rmw_zenoh")
            gone = Obstacle(1, "cam_a", "L1", "human", (0, 0, 0), (0, 0, 0), action=DELETE)
            robot.send("/rmf_obstacles", OBSTACLES, cdr_obstacles(stamp, [gone]))
            # the brief one may run out of lifetime meanwhile on a loaded machine: 3 held, or 2 after 6 s
            status = wait_until(client, lambda s: s["ros_ingest"]["obstacles_held"] == 3 - _expired(added_at))
            assert "unknown_id" not in counts(status, "obstacles").get("ignored", {})
            map_where(
                client, lambda g: not _at(g, 10.0) and _at(g, 14.0) and _at(g, 16.0), "the kept one deleted"
            )
            everything = Obstacle(0, "cam_b", "L1", "", (0, 0, 0), (0, 0, 0), action=DELETEALL)
            robot.send("/rmf_obstacles", OBSTACLES, cdr_obstacles(stamp, [everything]))
            wait_until(client, lambda s: s["ros_ingest"]["obstacles_held"] == 1 - _expired(added_at))
            grid = map_where(
                client, lambda g: not any(_at(g, x) for x in (10.0, 14.0, 16.0)), "cam_b's deleted"
            )
            brief_held = client.status()["ros_ingest"]["obstacles_held"] == 1  # held then, so in the map
            assert not any(_at(grid, x) for x in (10.0, 14.0, 16.0))
            assert _at(grid, 12.0) or not brief_held
            wait_until(client, lambda s: s["ros_ingest"]["obstacles_held"] == 0, timeout_s=20)
            assert time.monotonic() - added_at < 6 + 8  # its lifetime, from before the restart, held
            grid = map_where(client, lambda g: not _at(g, 12.0), "the brief one gone at its lifetime's end")
            assert np.count_nonzero(grid.data == OCCUPIED) > 0
            robot.close_stdin_and_wait()
    finally:
        d.stop_cleanly()
