"""Many robots, each with its own Zenoh router (rmw_zenoh's ``rmw_zenohd`` is one), reach one daemon:
every robot's router connects to the site's router, and the daemon connects there too. Three robot
routers stand for twenty-five (``twin router`` processes: a Zenoh router like ``rmw_zenohd``); each
robot publishes on rmw_zenoh's keys to its own router only, and every robot's detection arrays reach
the daemon's ingest workers and the twin (``docs/ros2-reporting.md``, "Many robots")."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from adapters.ros.interfaces import DETECTION_3D_ARRAY
from adapters.zenoh.client import TwinClient
from tests.adapters.ros_reports import Det, cdr_detections
from tests.integration.conftest import JsonLinesProcess, start_daemon
from tests.integration.test_router import Router

pytestmark = pytest.mark.slow  # a daemon, routers and robots, each its own process

ROBOTS = 3


class Robot(JsonLinesProcess):
    """A robot process that publishes on rmw_zenoh's keys to ``endpoint`` (its own router) only."""

    def __init__(self, endpoint: str) -> None:
        super().__init__("tests.integration.ros_report_publisher", endpoint, "rmw_zenoh", "0")
        while "ready" not in self.next():  # a message may come first: the subscriptions start before "ready"
            pass

    def send(self, topic: str, payload: bytes) -> None:
        assert self.process.stdin is not None
        line = {"topic": topic, "type": DETECTION_3D_ARRAY, "hex": payload.hex(), "latched": False}
        self.process.stdin.write(json.dumps(line) + "\n")
        self.process.stdin.flush()
        self.next()


@pytest.fixture
def routers() -> Iterator[tuple[Router, list[Router]]]:
    site = Router()
    own = [Router("--connect", site.endpoint) for _ in range(ROBOTS)]
    yield site, own
    for r in [*own, site]:
        if r.process.poll() is None:
            r.process.kill()
            r.process.wait(timeout=10)


def test_robots_each_behind_their_own_router_reach_one_daemon_through_the_site_router(
    fresh_store: Path, tmp_path: Path, routers: tuple[Router, list[Router]]
) -> None:
    site, own = routers
    config = tmp_path / "fleet.toml"
    config.write_text(
        '[ros]\ningest_workers = 1\n[robot_defaults]\nstorey = "ground-floor"\nros = ["rmw_zenoh"]\n'
        '[robot_defaults.detections]\nclasses = { table = "IfcFurniture" }\n'
        + "".join(f'[robots.robot{i}]\nnamespace = "/robot{i}"\n' for i in range(ROBOTS))
    )
    daemon = start_daemon(fresh_store, "--no-record", "--connect", site.endpoint, config=config)
    robots = [Robot(r.endpoint) for r in own]
    try:
        with TwinClient.connect([daemon.endpoint]) as client:
            deadline = time.monotonic() + 30
            while True:  # until every robot's route through the routers carries its arrays
                stamp = time.time_ns()
                for i, robot in enumerate(robots):  # in the map frame: no TF needed
                    table = Det((("table", 0.9),), (13.0 + 2.0 * i, 7.0, 0.375), (0.6, 0.6, 0.75), id="t")
                    robot.send(f"/robot{i}/detections", cdr_detections(stamp, "map", [table]))
                counts = client.status()["ros_ingest"]["counts"]
                if all(counts[f"robot{i}"]["accepted"] >= 1 for i in range(ROBOTS)):
                    break
                assert time.monotonic() < deadline, json.dumps(counts, indent=1)
                time.sleep(0.3)
            status = client.status()["ros_ingest"]
            assert status["workers"] == 1 and status["worker_restarts"] == 0
            assert all(c["refused"] == {} for c in status["counts"].values())
            assert client.status()["revision"] >= ROBOTS  # a table of each robot
    finally:
        for robot in robots:
            robot.close_stdin_and_wait()
        daemon.stop_cleanly()
