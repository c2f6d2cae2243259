"""``twin watch`` against a real daemon process: ``--count`` keeps waiting after the daemon answered,
``--for`` bounds the watch and the maps are written on any end; points skills and ROS 2 ``points_map``
topics are watched and written as PCD; an unknown ROS namespace names the configured robots; ``twin
status`` and ``twin explain`` print text, not JSON."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from adapters.ros.pcd import read_pcd
from tests.integration.conftest import ROOT, Daemon, lines_until, start_daemon, twin

pytestmark = pytest.mark.slow  # a daemon as a process

CONFIG = """
[skills.lidar3d]
kind = "points"
resolution_m = 0.1
[robots.robot1]
namespace = "/robot1"
storey = "ground-floor"
[robots.robot1.maps]
map = "localization"
"""


@pytest.fixture(scope="module")
def daemon(lab_store_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Daemon]:
    root = tmp_path_factory.mktemp("watch")
    shutil.copytree(lab_store_dir, root / "store")
    (root / "site.toml").write_text(CONFIG)
    d = start_daemon(root / "store", "--no-record", config=root / "site.toml")
    yield d
    d.stop()


def test_start_up_counts_the_maps_and_then_reports_each_cloud(daemon: Daemon) -> None:
    assert "preparing maps: 8 of 8 in " in "\n".join(daemon.log)  # the 8 grid maps, not 10 with clouds
    lines = [ln for ln in daemon.log if ln.startswith("cloud ")]  # those read with the serving line
    if len(lines) < 2:
        lines += lines_until(daemon, lambda line: line.startswith("cloud 2 of 2"), 30.0)
    clouds = [ln for ln in lines if ln.startswith("cloud ")]
    assert [c.split(" ready: ")[0] for c in clouds] == ["cloud 1 of 2", "cloud 2 of 2"]
    ready = {c.split(" ready: ")[1].split(",")[0] for c in clouds}
    assert ready == {"ground-floor/lidar3d", "first-floor/lidar3d"}


def watch(daemon: Daemon, *args: str | Path) -> subprocess.CompletedProcess[str]:
    return twin("--config", daemon_config(daemon), "watch", "--connect", daemon.endpoint, *args, timeout=60)


def daemon_config(daemon: Daemon) -> Path:
    assert daemon.store is not None
    return daemon.store.parent / "site.toml"


def test_watch_count_keeps_waiting_after_the_daemon_answered_and_for_ends_it_writing_the_maps(
    daemon: Daemon, tmp_path: Path
) -> None:
    # --timeout 1 is the wait for the daemon only: the watch goes on until --for ends it
    r = watch(daemon, "--skill", "lab-navigation", "--storey", "ground-floor", "--count", "2",
              "--timeout", "1", "--for", "3", "--out", tmp_path)  # fmt: skip
    assert r.returncode == 1
    assert r.stderr.strip().splitlines() == ["twin: error: 1 of 2 map versions in 3 s (--for)"]
    assert (tmp_path / "ground-floor__lab-navigation.yaml").exists()  # what it had, written
    assert f"wrote {tmp_path / 'ground-floor__lab-navigation.yaml'}" in r.stdout


def test_watch_count_gets_a_version_that_comes_after_its_timeout(daemon: Daemon, tmp_path: Path) -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "adapters.cli", "--config", str(daemon_config(daemon)), "watch",
         "--connect", daemon.endpoint, "--skill", "lab-navigation", "--storey", "ground-floor",
         "--count", "2", "--timeout", "1", "--for", "60"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    assert process.stdout is not None
    assert "version 1" in process.stdout.readline()
    time.sleep(1.5)  # past --timeout
    table = ["--box", "16.6,7,0.375,0.6,0.6,0.75,0.3", "--class", "IfcFurniture", "--storey", "ground-floor"]
    ack = twin("observe", "--connect", daemon.endpoint, "--robot", "robot1", *table)
    assert ack.returncode == 0, ack.stderr
    out, err = process.communicate(timeout=60)
    assert process.returncode == 0, err
    assert "version 2" in out


def test_watch_count_ended_by_sigterm_writes_what_it_has_and_exits_0(daemon: Daemon, tmp_path: Path) -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "adapters.cli", "watch", "--connect", daemon.endpoint, "--skill",
         "lab-navigation", "--storey", "first-floor", "--count", "5", "--out", str(tmp_path)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    assert process.stdout is not None
    assert "version 1" in process.stdout.readline()
    process.send_signal(signal.SIGTERM)
    out, err = process.communicate(timeout=30)
    assert process.returncode == 0, err
    assert f"wrote {tmp_path / 'first-floor__lab-navigation.yaml'}" in out


def test_watch_of_a_points_skill_prints_each_cloud_and_writes_a_pcd(daemon: Daemon, tmp_path: Path) -> None:
    r = watch(daemon, "--skill", "lidar3d", "--storey", "ground-floor", "--count", "1", "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    first = r.stdout.splitlines()[0]
    assert first.startswith("ground-floor/lidar3d version ") and first.endswith(" points")
    n = int(first.rsplit(": ", 1)[1].split()[0].replace(",", ""))
    xyz, offset = read_pcd(tmp_path / "ground-floor__lidar3d.pcd")
    assert xyz.shape == (n, 3) and n > 1000 and offset == (0.0, 0.0)


def test_watch_ros_points_map_decodes_the_point_cloud2_topic(daemon: Daemon, tmp_path: Path) -> None:
    r = watch(daemon, "--ros", "/robot1", "--topic", "points_map", "--count", "1", "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("/robot1/points_map via rmw_zenoh: ")
    xyz, _ = read_pcd(tmp_path / "robot1__points_map.pcd")
    assert len(xyz) > 1000


def test_watch_ros_of_an_unknown_namespace_names_the_configured_robots(daemon: Daemon) -> None:
    r = watch(daemon, "--ros", "/robot9", "--count", "1")
    assert r.returncode == 1
    assert r.stderr.strip().splitlines() == [
        "twin: error: Unknown robot namespace '/robot9': the daemon of twin/lab serves ROS 2 maps to "
        "/robot1 (robot1)."
    ]


def test_status_prints_clouds_and_robots_as_text(daemon: Daemon) -> None:
    r = twin("status", "--connect", daemon.endpoint, timeout=60)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert "  robot1: on ground-floor, namespace /robot1" in lines
    cloud = [line for line in lines if line.startswith("  ground-floor/lidar3d version ")]
    assert len(cloud) == 1 and cloud[0].endswith(" points")
    assert not any("{" in line for line in lines)


def test_a_wrong_site_is_told_with_the_sites_whose_daemons_answer(daemon: Daemon) -> None:
    r = twin("status", "--connect", daemon.endpoint, "--site", "lab2", "--timeout", "2", timeout=60)
    assert r.returncode == 1
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].endswith("(no daemon of site 'lab2' there; daemons answer for the sites lab: --site?).")
