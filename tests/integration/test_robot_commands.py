"""The robot-side commands against a real daemon process: ``twin status``, and the one-line errors of
``twin watch`` and ``twin storey`` that the README promises; ``twin watch --out`` stopped by SIGTERM."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.integration.conftest import ROOT, Daemon, start_daemon, twin

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast


@pytest.fixture(scope="module")
def daemon(lab_store_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Daemon]:
    """One daemon for the module: these commands change nothing in the twin."""
    store = tmp_path_factory.mktemp("commands") / "store"
    shutil.copytree(lab_store_dir, store)
    d = start_daemon(store, "--no-record")
    yield d
    d.stop()


def test_status_prints_the_daemons_status_readably_and_as_json(daemon: Daemon) -> None:
    r = twin("status", "--connect", daemon.endpoint, timeout=60)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert "site: lab" in lines and "storeys: ground-floor, first-floor" in lines
    assert "maps (8):" in lines and "  ground-floor/lab-navigation version 1 (revision 0)" in lines
    raw = twin("status", "--connect", daemon.endpoint, "--json", timeout=60)
    status = json.loads(raw.stdout)
    assert status["site"] == "lab" and len(status["maps"]) == 8
    assert f"elements: {status['elements']}" in lines


def test_watch_names_an_unknown_storey_or_skill_in_one_line_with_the_known_ones(daemon: Daemon) -> None:
    r = twin("watch", "--connect", daemon.endpoint, "--skill", "lab-navigation", "--storey", "ground_floor")
    assert r.returncode == 1 and r.stdout == ""
    assert r.stderr.strip() == (
        "twin: error: Unknown storey 'ground_floor': twin/lab serves lab-navigation maps of the storeys "
        "first-floor, ground-floor."
    )
    r = twin("watch", "--connect", daemon.endpoint, "--skill", "lab-nav", "--storey", "ground-floor")
    assert r.returncode == 1
    assert r.stderr.startswith("twin: error: Unknown skill 'lab-nav': twin/lab serves maps of the skills")
    assert "lab-navigation" in r.stderr and len(r.stderr.splitlines()) == 1


def test_storey_of_a_robot_the_daemon_does_not_know_is_refused_naming_it(daemon: Daemon) -> None:
    r = twin("storey", "--connect", daemon.endpoint, "--robot", "robot1", "--timeout", "5", timeout=60)
    assert r.returncode == 1
    assert r.stderr.strip() == (
        "twin: error: Unknown robot 'robot1': the daemon of twin/lab has no robots configured "
        "(no [robots.NAME] table)."
    )


def test_watch_out_stopped_by_sigterm_writes_the_maps_it_watched(daemon: Daemon, tmp_path: Path) -> None:
    out = tmp_path / "watched"
    watch = subprocess.Popen(
        [sys.executable, "-m", "adapters.cli", "watch", "--connect", daemon.endpoint,
         "--skill", "lab-navigation", "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    assert watch.stdout is not None
    seen = {watch.stdout.readline().split()[0] for _ in range(2)}  # both storeys' latched maps
    assert seen == {"ground-floor/lab-navigation", "first-floor/lab-navigation"}
    watch.send_signal(signal.SIGTERM)
    rest, err = watch.communicate(timeout=30)
    assert watch.returncode == 0, err
    assert sorted(p.name for p in out.glob("*.yaml")) == [
        "first-floor__lab-navigation.yaml",
        "ground-floor__lab-navigation.yaml",
    ]
    assert f"wrote {out / 'ground-floor__lab-navigation.yaml'}" in rest


def test_explain_errors_are_one_line_starting_twin_error(daemon: Daemon) -> None:
    r = twin("explain", "--connect", daemon.endpoint, "--storey", "ground_floor", "--skill", "navigation",
             "--at", "16.6,7.0", timeout=60)  # fmt: skip
    assert r.returncode == 1 and r.stdout == ""
    assert (
        r.stderr.startswith("twin: error: No map ground_floor/navigation") and len(r.stderr.splitlines()) == 1
    )
