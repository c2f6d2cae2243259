"""The Rerun recorder process of a running daemon is killed: the daemon keeps serving and acking, a new
recorder process records into a new segment, and the daemon still stops cleanly."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest

from adapters.rerun import map_history
from adapters.zenoh.client import TwinClient
from tests.integration.conftest import start_daemon

pytestmark = pytest.mark.slow

TWIN = "https://w3id.org/building-twin#"


def _recorders(daemon_pid: int) -> list[int]:
    """The daemon's children running ``adapters.rerun.child`` (started by any of its threads)."""
    out = []
    children: list[str] = []
    for task in Path(f"/proc/{daemon_pid}/task").iterdir():
        try:
            children += (task / "children").read_text().split()
        except OSError:  # a thread that ended meanwhile
            continue
    for pid in children:
        try:
            if b"adapters.rerun.child" in Path(f"/proc/{pid}/cmdline").read_bytes():
                out.append(int(pid))
        except OSError:
            continue
    return out


def test_a_killed_recorder_costs_the_daemon_nothing_and_recording_resumes_in_a_new_segment(
    fresh_store: Path, tmp_path: Path
) -> None:
    d = start_daemon(fresh_store, "--record", str(tmp_path / "run.rrd"))
    try:
        (first,) = _recorders(d.process.pid)
        os.kill(first, signal.SIGKILL)
        with TwinClient.connect([d.endpoint], prefix="twin/lab") as robot:
            table = (f'<urn:test:rec> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "ground-floor" ; '
                     f'<{TWIN}box> "16.6 7.0 0.375 0.6 0.6 0.75 0.0" .')  # fmt: skip
            assert robot.observe("robot1", table)["ok"]  # serving and acking as before
            deadline = time.monotonic() + 20
            while time.monotonic() < deadline and not [p for p in _recorders(d.process.pid) if p != first]:
                time.sleep(0.1)
            assert [p for p in _recorders(d.process.pid) if p != first], "no new recorder process"
            assert robot.status()["revision"] == 1
        d.stop_cleanly()
        assert any("The Rerun recorder process" in line and "a new one in 1 s" in line for line in d.log)
        segment = tmp_path / "run-restart1.rrd"
        assert segment.exists() and map_history(segment, "ground-floor", "navigation")
    finally:
        d.stop_cleanly()
