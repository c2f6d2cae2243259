"""Scale out: a router (``twin router``), two daemons for two sites and a robot, each its own process."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from adapters.zenoh.client import TwinClient
from adapters.zenoh.errors import DaemonTimeoutError
from tests.integration.conftest import ROOT, Daemon, free_port, start_daemon, twin
from twin.maps.grid import OccupancyGrid

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

TWIN = "https://w3id.org/building-twin#"
NAV = ("ground-floor", "lab-navigation")


class Router:
    def __init__(self, *extra: str) -> None:
        self.endpoint = f"tcp/127.0.0.1:{free_port()}"
        self.process = subprocess.Popen(
            [sys.executable, "-m", "adapters.cli", "router", "--listen", self.endpoint, *extra],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )  # fmt: skip
        assert self.process.stdout is not None
        self.line = self.process.stdout.readline()
        assert self.line.startswith("router "), self.line + self.process.stdout.read()

    def stop(self) -> int:
        self.process.send_signal(signal.SIGTERM)
        self.process.communicate(timeout=10)
        return self.process.returncode


def site_daemon(store_dir: Path, root: Path, site: str, router: Router, config: Path | None = None) -> Daemon:
    shutil.copytree(store_dir, root / site)
    return start_daemon(
        root / site, "--no-record", "--site", site, "--connect", router.endpoint, config=config
    )


def stopped(d: Daemon) -> None:
    d.stop_cleanly()


@pytest.fixture
def router() -> Iterator[Router]:
    r = Router("--store-maps")
    yield r
    if r.process.poll() is None:
        r.process.kill()
        r.process.wait(timeout=10)


def test_the_routers_start_line_says_whether_access_control_is_on(tmp_path: Path, router: Router) -> None:
    assert "access control off" in router.line
    (tmp_path / "users.txt").write_text("robot1:secret\nops:secret\n")
    config = tmp_path / "site.toml"
    config.write_text(
        f'[zenoh.auth]\nusers_file = "{tmp_path / "users.txt"}"\n'
        '[zenoh.access]\noperators = ["ops"]\n[robots.robot1]\n'
    )
    guarded = Router("--acl", "--site", "lab", "--config", str(config))
    try:
        assert "access control on for twin/lab/** (robots and operators: robot1, ops)" in guarded.line
    finally:
        assert guarded.stop() == 0


def table(x: float) -> str:
    return (
        f'<urn:test:router-table> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "ground-floor" ; '
        f'<{TWIN}box> "{x} 7.0 0.375 0.6 0.6 0.75 0.0" .'
    )


def test_a_robot_at_the_router_gets_both_sites_maps_and_an_observation_changes_only_its_site(
    lab_store_dir: Path, tmp_path: Path, router: Router
) -> None:
    north = site_daemon(lab_store_dir, tmp_path, "north", router)
    south = site_daemon(lab_store_dir, tmp_path, "south", router)
    try:
        # the robot connects to the router only, after both daemons started (late joiner)
        with (
            TwinClient.connect([router.endpoint], prefix="twin/north", mode="client") as at_north,
            TwinClient(at_north.session, prefix="twin/south") as at_south,
        ):
            assert NAV in at_north.list_maps() and NAV in at_south.list_maps()
            north_watch, south_watch = at_north.watch(*NAV), at_south.watch(*NAV)
            n0 = north_watch.wait_for(lambda v: True, timeout_s=10)
            s0 = south_watch.wait_for(lambda v: True, timeout_s=10)
            np.testing.assert_array_equal(n0.grid.data, s0.grid.data)  # the same building, two sites
            south_status = at_south.status()

            ack = at_north.observe("robot1", table(16.6))
            assert ack["ok"]
            n1 = north_watch.wait_for(lambda v: v.revision >= ack["revision"], timeout_s=10)
            assert not np.array_equal(n1.grid.data, n0.grid.data)
            time.sleep(0.5)
            assert at_south.status()["revision"] == south_status["revision"]
            assert south_watch.latest is not None and south_watch.latest.version == s0.version
            assert at_south.get_map(*NAV)[2] == s0.version
            north_watch.close()
            south_watch.close()
    finally:
        stopped(north)
        stopped(south)
    assert router.stop() == 0


POINTS = """
[skills.lidar3d]
kind = "points"
resolution_m = 0.2
exclude_types = ["IfcOpeningElement"]    # furniture in: a table observed changes the cloud
[skills.lidar-gone]
kind = "points"
resolution_m = 0.5
"""


def first_cloud(
    robot: TwinClient, storey: str, skill: str, newer_than: int = 0
) -> tuple[np.ndarray, int, int]:
    """The cloud once the daemon has built it (after its 2D maps) at a version above ``newer_than``."""
    deadline = time.monotonic() + 30
    while True:
        try:
            got = robot.get_points(storey, skill)
            if got[2] > newer_than:
                return got
        except DaemonTimeoutError:
            pass
        assert time.monotonic() < deadline, f"no cloud {storey}/{skill} above version {newer_than} in 30 s"
        time.sleep(0.2)


def _map_at(robot: TwinClient, version: int) -> tuple[OccupancyGrid, int, int]:
    """The site's navigation map once ``robot`` is answered with ``version``."""
    deadline = time.monotonic() + 30
    while (got := robot.get_map(*NAV))[2] != version:
        assert time.monotonic() < deadline, f"the map is at version {got[2]}, not {version}, after 30 s"
        time.sleep(0.1)
    return got


def _until_stored(late: TwinClient, version: int, cloud: tuple[str, str], cloud_version: int) -> None:
    """Until the router's storage answers with the map's and the cloud's last versions."""
    deadline = time.monotonic() + 30
    while (late.get_map(*NAV)[2], late.get_points(*cloud)[2]) != (version, cloud_version):
        assert time.monotonic() < deadline, "the router's storage did not get the last versions in 30 s"
        time.sleep(0.1)


def test_the_routers_storage_serves_a_sites_maps_and_clouds_while_its_daemon_is_down(
    lab_store_dir: Path, tmp_path: Path, router: Router
) -> None:
    config = tmp_path / "points.toml"
    config.write_text(POINTS)
    north = site_daemon(lab_store_dir, tmp_path, "north", router, config=config)
    cloud = ("ground-floor", "lidar3d")
    try:
        with TwinClient.connect([router.endpoint], prefix="twin/north", mode="client") as robot:
            live, live_cloud = robot.get_map(*NAV), first_cloud(robot, *cloud)  # built after the maps
            assert len(first_cloud(robot, "ground-floor", "lidar-gone")[0]) > 0
            robot.observe("robot1", table(18.0))
            robot.delete_skill("lidar-gone")  # its clouds are deleted: the storage forgets them
            latest_cloud = first_cloud(robot, *cloud, newer_than=live_cloud[2])  # at most one a second
            (version_now,) = [
                m["version"] for m in robot.status()["maps"] if (m["storey"], m["skill"]) == NAV
            ]
            assert version_now > live[2]
            latest = _map_at(robot, version_now)  # the daemon's or the storage's answer: the same by now
            assert len(latest_cloud[0]) > len(live_cloud[0])  # the table's voxels
    finally:
        stopped(north)
    with TwinClient.connect([router.endpoint], prefix="twin/north", mode="client") as late:
        assert not late.daemon_alive()
        _until_stored(late, latest[2], cloud, latest_cloud[2])  # the last puts may still be on their way
        grid, _, version = late.get_map(*NAV)  # answered by the router's storage
        assert version == latest[2]
        np.testing.assert_array_equal(grid.data, latest[0].data)
        xyz, _, cloud_version = late.get_points(*cloud)  # so is the cloud
        assert cloud_version == latest_cloud[2]
        np.testing.assert_array_equal(xyz, latest_cloud[0])
        with pytest.raises(DaemonTimeoutError):
            late.get_points("ground-floor", "lidar-gone")
        watcher = late.watch(*NAV)
        seen = watcher.wait_for(lambda v: True, timeout_s=10)
        assert seen.version == latest[2]
        watcher.close()


BOX = ("--box", "16.6,7.0,0.375,0.6,0.6,0.75,0.0", "--class", "IfcFurniture", "--storey", "ground-floor")


def observe_process(
    router: Router, *args: str, before: Sequence[str | Path] = ()
) -> subprocess.CompletedProcess[str]:
    """``twin observe`` through the router as a fresh process, as a robot's script runs it."""
    return twin(
        *before, "observe", "--connect", router.endpoint, "--robot", "robot1", *BOX, *args, timeout=60
    )


def readme_robot_snippet(site: str, endpoint: str) -> str:
    """The docs' "A robot in a few lines" (docs/robot-client.md), for ``site`` at ``endpoint``."""
    page = (ROOT / "docs" / "robot-client.md").read_text()
    found = re.search(r"# A robot in a few lines.*?```python\n(.*?)```", page, re.S)
    assert found, "the robot snippet of docs/robot-client.md is gone"
    code = found.group(1)
    assert 'site = "lab"' in code and "tcp/127.0.0.1:7447" in code
    return code.replace('site = "lab"', f'site = "{site}"').replace("tcp/127.0.0.1:7447", endpoint)


def test_robot_commands_through_a_router_get_their_ack_every_time_and_honour_the_zenoh_mode(
    lab_store_dir: Path, tmp_path: Path, router: Router
) -> None:
    north = site_daemon(lab_store_dir, tmp_path, "north", router)
    south = site_daemon(lab_store_dir, tmp_path, "south", router)
    client_toml = tmp_path / "robot.toml"
    client_toml.write_text('[zenoh]\nmode = "client"\n')
    try:
        runs = [
            (["--config", client_toml, "-v"] if i % 2 else [], "north" if i % 4 < 2 else "south")
            for i in range(20)
        ]  # half in the default (peer) mode, half with the robot's [zenoh] mode = "client"
        with ThreadPoolExecutor(max_workers=4) as pool:
            results = list(pool.map(lambda r: observe_process(router, "--site", r[1], before=r[0]), runs))
        acked = [r for r in results if r.returncode == 0 and '"ok": true' in r.stdout]
        assert len(acked) == 20, [r.stdout + r.stderr for r in results if r not in acked]
        for (config, _), r in zip(runs, results, strict=True):
            assert ("zenoh session in client mode" in r.stderr) == bool(config), r.stderr

        nameless = observe_process(router)
        assert nameless.returncode != 0
        assert "2 daemons are running, for the sites north, south: choose one with --site" in nameless.stderr

        snippet = subprocess.run(
            [sys.executable, "-c", readme_robot_snippet("south", router.endpoint)],
            capture_output=True, text=True, cwd=ROOT, timeout=60, check=False,
        )  # fmt: skip
        assert snippet.returncode == 0 and "'ok': True" in snippet.stdout, snippet.stdout + snippet.stderr
    finally:
        stopped(north)
        stopped(south)
