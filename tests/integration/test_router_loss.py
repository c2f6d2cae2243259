"""A lost router: the daemon and a robot in client mode through ``twin router``; the router is killed
and started again on its endpoint. The daemon's keys come back without restarting it, an observation
sent during the outage is refused (the robot retries) and never acked and lost, and a watch resumes."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from adapters.zenoh.client import TwinClient
from tests.integration.conftest import ROOT, free_port, start_daemon

pytestmark = pytest.mark.slow

TWIN = "https://w3id.org/building-twin#"
NAV = ("ground-floor", "lab-navigation")


def _router(endpoint: str) -> subprocess.Popen[str]:
    process = subprocess.Popen(
        [sys.executable, "-m", "adapters.cli", "router", "--listen", endpoint],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    assert process.stdout is not None
    line = process.stdout.readline()
    assert line.startswith("router "), line + process.stdout.read()
    return process


def _table(x: float) -> str:
    return (f'<urn:test:router-loss-table> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "ground-floor" ; '
            f'<{TWIN}box> "{x} 7.0 0.375 0.6 0.6 0.75 0.0" .')  # fmt: skip


def _until(what: str, check: Callable[[], bool], timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    last: Exception | None = None
    while time.monotonic() < deadline:
        try:
            if check():
                return
        except Exception as err:  # not yet
            last = err
        time.sleep(0.2)
    raise AssertionError(f"{what} within {timeout_s} s (last: {last})")


def test_a_router_killed_and_restarted_costs_the_daemon_nothing(lab_store_dir: Path, tmp_path: Path) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = _router(endpoint)
    shutil.copytree(lab_store_dir, tmp_path / "store")
    d = start_daemon(tmp_path / "store", "--no-record", "--mode", "client", "--connect", endpoint)
    try:
        with TwinClient.connect([endpoint], prefix="twin/lab", mode="client", timeout_s=30) as robot:
            watch = robot.watch(*NAV)
            first = watch.wait_for(lambda v: True, timeout_s=10)
            before = robot.observe("robot1", _table(16.0))
            assert before["ok"]

            router.kill()
            router.wait(timeout=10)
            refused = False
            robot.timeout_s = 5.0  # not longer than that for a request nobody takes
            try:
                during = robot.observe("robot1", _table(16.5))  # nobody to take it
            except Exception:
                refused = True
            robot.timeout_s = 30.0  # what a loaded machine may need
            router = _router(endpoint)
            _until("the daemon answers through the new router", lambda: "revision" in robot.status())
            status = robot.status()
            assert status["revision"] == (before["revision"] if refused else during["revision"])
            after = robot.observe("robot1", _table(17.0))
            assert after["ok"] and after["revision"] == status["revision"] + 1
            version = watch.wait_for(lambda v: v.revision >= after["revision"], timeout_s=20)
            assert version.version > first.version  # the watch resumed with the current map
            watch.close()
        with TwinClient.connect([endpoint], prefix="twin/lab", mode="client") as late:
            grid, revision, _ = late.get_map(*NAV)
            assert grid.data.size > 0  # a late joiner gets the current map
            assert revision == after["revision"]
        d.stop_cleanly()
        assert router.poll() is None
    finally:
        d.stop_cleanly()
        if router.poll() is None:
            router.send_signal(signal.SIGTERM)
            router.wait(timeout=10)
