"""``twin status`` and ``twin explain`` as text: local times, sightings, aliases, misses, any new key."""

from __future__ import annotations

import datetime as dt
import os
import time
from collections.abc import Iterator

import pytest

from adapters.cli.render import describe_explain, describe_status, generic, local_time, scalar

NS = 1_764_324_903_120_000_000  # 2025-11-28 10:15:03.120 UTC


@pytest.fixture
def berlin() -> Iterator[None]:
    """This process's local time zone is Europe/Berlin (CET in November) for the test."""
    before = os.environ.get("TZ")
    os.environ["TZ"] = "Europe/Berlin"
    time.tzset()
    yield
    if before is None:
        del os.environ["TZ"]
    else:
        os.environ["TZ"] = before
    time.tzset()


def test_epoch_nanoseconds_are_shown_as_local_time_with_the_zone(berlin: None) -> None:
    assert local_time(NS) == "2025-11-28 11:15:03.120 CET"
    assert scalar("switched_ns", NS) == "2025-11-28 11:15:03.120 CET"
    assert scalar("took_ns", 2_500_000_000) == "2.5 s"  # a duration, not a time
    assert scalar("uptime_s", 3725.0) == "1 h 2 min"


def test_status_shows_clouds_robots_and_the_store_state_readably(berlin: None) -> None:
    robot = {
        "storey": "first-floor", "namespace": "/robot1", "topics": {"/robot1/map": "localization"},
        "switches": 1, "switched_ns": NS, "refused": 0,
    }  # fmt: skip
    status = {
        "site": "lab",
        "revision": 3,
        "store": "read-only: the disk is full",
        "points": [
            {"storey": "ground-floor", "skill": "lidar3d", "version": 2, "revision": 3, "points": 32437}
        ],
        "robots": {"robot1": robot},
        "sizes": {"live.fusion.tracks": 2, "live.held[*]": 17},
        "uptime_s": 42.0,
    }
    text = describe_status(status).splitlines()
    assert "sizes: 2 containers of the writer (twin status --json lists them)" in text
    assert "store: read-only: the disk is full" in text
    assert "  ground-floor/lidar3d version 2 (revision 3): 32,437 points" in text
    assert "  robot1: on first-floor, namespace /robot1" in text
    assert "    topics: /robot1/map (localization)" in text
    assert "    storey switches: 1, last 2025-11-28 11:15:03.120 CET" in text
    assert "uptime: 42.0 s" in text
    assert not any("{" in line or "_ns" in line for line in text)


def test_a_status_section_this_version_does_not_know_is_rendered_without_json() -> None:
    new = {"views": {"robot1": {"fov_deg": 90, "last_ns": NS}, "kept": 4}, "tags": ["a", "b"]}
    text = describe_status(new)
    assert "{" not in text and "[" not in text
    assert "views:" in text.splitlines()
    assert "tags: a, b" in text.splitlines()
    assert any(line.startswith("  robot1: fov deg 90, last 2025-11-28") for line in text.splitlines())
    assert generic("maps_sent", 3) == ["maps sent: 3"]


def test_explain_lists_sightings_per_robot_aliases_and_misses_in_local_time(berlin: None) -> None:
    table = {
        "iri": "urn:robot1:table", "class": "IfcFurniture", "name": None, "global_id": None,
        "observed": {"robot": "robot1", "at": "2025-11-28T10:15:03.120000Z", "revision": 2},
        "fusion": {
            "sightings": {
                "robot1": {"count": 3, "first_ns": NS, "last_ns": NS + 2_000_000_000},
                "robot2": {"count": 1, "first_ns": NS + 1_000_000_000, "last_ns": NS + 1_000_000_000},
            },
            "misses": [{"robot": "robot3", "sense_ns": NS + 5_000_000_000}],
            "seen_ns": NS + 2_000_000_000,
            "aliases": ["urn:robot2:t7"],
        },
    }  # fmt: skip
    answer = {
        "storey": "ground-floor", "skill": "navigation", "x": 16.6, "y": 7.0, "cell": {"col": 156, "row": 65},
        "value": 100, "state": "occupied", "occupied_by": [table], "within_inflation_of": [], "near": [],
    }  # fmt: skip
    lines = describe_explain(answer).splitlines()
    assert lines[0] == "ground-floor/navigation at (16.6, 7.0), cell (156, 65): occupied (100)"
    assert lines[1] == (
        "  occupied by IfcFurniture <urn:robot1:table>, observed by robot1 at 2025-11-28 11:15:03.120 CET "
        "(revision 2)"
    )
    span = "first 2025-11-28 11:15:03.120 CET, last 2025-11-28 11:15:05.120 CET"
    assert f"    seen by robot1 3 times ({span})" in lines
    assert "    seen by robot2 once (2025-11-28 11:15:04.120 CET)" in lines
    assert "    also reported as: <urn:robot2:t7>" in lines
    assert (
        "    missed by robot3 (a view that should have seen it) at 2025-11-28 11:15:08.120 CET" in lines
    )


def test_local_time_uses_this_machines_zone_by_default() -> None:
    expected = dt.datetime.fromtimestamp(NS / 1e9).astimezone().strftime("%Y-%m-%d %H:%M:%S")
    assert local_time(NS).startswith(expected)
