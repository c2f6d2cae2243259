"""An operator marks rooms as keepout and speed zones with ``twin zone`` while the daemon runs (its own
process): the nav2 filter masks follow, robots without the ``zones`` right cannot, and the building's
maps do not change."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from adapters.zenoh.client import TwinClient
from tests.integration.conftest import Daemon, start_daemon, twin

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

CONFIG = """
[skills.keepout]
kind = "keepout"
[skills.slow]
kind = "speed"
limit_percent = 30

[robots.operator]
rights = ["create", "dynamic", "doors", "static", "zones"]
"""
GROUND = "ground-floor"


@pytest.fixture
def zones_daemon(fresh_store: Path, tmp_path: Path) -> Iterator[Daemon]:
    config = tmp_path / "zones.toml"
    config.write_text(CONFIG)
    d = start_daemon(fresh_store, "--no-record", config=config)
    yield d
    d.stop_cleanly()


def zone(d: Daemon, robot: str, *args: str) -> tuple[int, dict[str, object]]:
    r = twin("zone", "--connect", d.endpoint, "--robot", robot, *args)
    return r.returncode, json.loads(r.stdout) if r.stdout.strip() else {"stderr": r.stderr}


def maps(d: Daemon, *acks: dict[str, object]) -> dict[str, np.ndarray]:
    """The daemon's ground-floor maps, once they include the acked changes (a get answers the current
    map, updates applied; the loop only guards against a slow machine)."""
    wanted = {m["skill"]: m["version"] for a in acks for m in a["maps"]}  # type: ignore[attr-defined]
    out: dict[str, np.ndarray] = {}
    with TwinClient.connect([d.endpoint]) as client:
        deadline = time.monotonic() + 10.0
        for skill in ("keepout", "slow", "navigation", "localization"):
            grid, _, version = client.get_map(GROUND, skill)
            while version < wanted.get(skill, 0) and time.monotonic() < deadline:
                time.sleep(0.05)
                grid, _, version = client.get_map(GROUND, skill)
            out[skill] = grid.data
    return out


def test_an_operator_keeps_robots_out_of_a_room_and_slows_them_in_another_then_lifts_it(
    zones_daemon: Daemon,
) -> None:
    d = zones_daemon
    before = maps(d)
    assert not before["keepout"].any() and not before["slow"].any()
    code, keep = zone(d, "operator", "--space", "Corridor", "--keepout")
    assert code == 0 and keep["ok"], keep
    assert [m["skill"] for m in keep["maps"]] == ["keepout"]  # type: ignore[attr-defined]
    code, slow = zone(d, "operator", "--space", "Room A", "--speed-limit", "30")
    assert code == 0 and slow["ok"], slow
    now = maps(d, keep, slow)
    corridor = int((now["keepout"] == 100).sum())
    assert 80 * 24 <= corridor <= 83 * 27  # the corridor is 4.0 m x 1.2 m at 5 cm, edges touched
    assert set(np.unique(now["slow"])) == {0, 30}
    assert 80 * 80 <= int((now["slow"] == 30).sum()) <= 83 * 83  # room A: 4 m x 4 m
    for skill in ("navigation", "localization"):
        np.testing.assert_array_equal(now[skill], before[skill], err_msg=skill)
    again, ack = zone(d, "operator", "--space", "Corridor", "--keepout")
    assert again == 0 and ack["unchanged"] is True  # the same zone: a re-confirmation
    code, ack = zone(d, "operator", "--space", "Corridor", "--lift")
    assert code == 0 and ack["ok"], ack
    np.testing.assert_array_equal(maps(d, ack)["keepout"], before["keepout"])


def test_a_robot_cannot_mark_a_zone_and_an_unknown_room_is_named(zones_daemon: Daemon) -> None:
    code, reply = zone(zones_daemon, "robot1", "--space", "Corridor", "--keepout")
    assert code == 1 and "lacks the 'zones' right" in str(reply["error"])
    code, reply = zone(zones_daemon, "operator", "--space", "Attic", "--keepout")
    assert code == 1
    assert "No space (IfcSpace) named 'Attic'" in str(reply["stderr"]) and "'Corridor'" in str(
        reply["stderr"]
    )
    assert not maps(zones_daemon)["keepout"].any()
