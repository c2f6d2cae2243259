"""A change costs its changed cells: after a map's first publication its changes go out as updates only,
and a changed map goes out in full again only as a keyframe (at most every ``keyframe_interval_s``)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import imported
from tests.twin.box_lab import box_lab
from tests.twin.live_helpers import Recorder, box_turtle, observe
from twin.config import load_config
from twin.errors import ConfigError
from twin.live import TwinService
from twin.live.events import MapPublished, MapUpdated

TABLE = "urn:robot1:table-1"
SECOND = 1_000_000_000


class Clock:
    """A clock the test moves (ns)."""

    def __init__(self) -> None:
        self.now = 1_000 * SECOND

    def __call__(self) -> int:
        return self.now


def started(keyframe_s: float = 60.0) -> tuple[TwinService, Recorder, Clock]:
    config = load_config()
    limits = config.limits.model_copy(update={"keyframe_interval_s": keyframe_s})
    config = dataclasses.replace(config, limits=limits)
    rec, clock = Recorder(), Clock()
    service = TwinService(imported(box_lab()), config, sinks=[rec], clock=clock)
    service.start()
    return service, rec, clock


def full_maps(rec: Recorder) -> list[tuple[str, str, int]]:
    return [(e.grid.storey, e.grid.skill, e.version) for e in rec.of(MapPublished)]


def test_after_the_first_publication_a_burst_of_changes_sends_updates_and_no_full_map() -> None:
    service, rec, clock = started()
    assert len(full_maps(rec)) == len(service.live_maps.skill_maps)  # every map once, at start
    rec.events.clear()
    for i in range(20):
        clock.now += SECOND // 20
        assert observe(service, "robot1", box_turtle(TABLE, 5.0 + 0.1 * i, 2.0)).ok
    service.process()
    assert full_maps(rec) == []
    assert {(u.storey, u.skill) for u in rec.of(MapUpdated)} == {
        ("ground-floor", "navigation"),
        ("ground-floor", "lab-navigation"),
    }


def test_a_changed_map_goes_out_in_full_once_its_keyframe_is_due_and_an_unchanged_one_never() -> None:
    service, rec, clock = started(keyframe_s=60.0)
    rec.events.clear()
    assert observe(service, "robot1", box_turtle(TABLE, 5.0, 2.0)).ok
    clock.now += 59 * SECOND
    service.process()
    assert full_maps(rec) == []  # 59 s after the start: not yet
    clock.now += 2 * SECOND
    service.process()
    nav = service.live_maps.skill_maps[("ground-floor", "navigation")]
    assert sorted(full_maps(rec)) == [
        (
            "ground-floor",
            "lab-navigation",
            service.live_maps.skill_maps[("ground-floor", "lab-navigation")].version,
        ),
        ("ground-floor", "navigation", nav.version),
    ]
    keyframe = next(e for e in rec.of(MapPublished) if e.grid.skill == "navigation")
    np.testing.assert_array_equal(keyframe.grid.data, nav.data)  # the current map, every change in it
    rec.events.clear()
    clock.now += 120 * SECOND
    service.process()
    assert full_maps(rec) == []  # nothing changed since the keyframe: nothing sent


def test_a_change_right_after_a_keyframe_waits_for_the_next_one() -> None:
    service, rec, clock = started(keyframe_s=10.0)
    clock.now += 11 * SECOND
    assert observe(service, "robot1", box_turtle(TABLE, 5.0, 2.0)).ok  # due at once: 11 s since start
    rec.events.clear()
    clock.now += SECOND
    assert observe(service, "robot1", box_turtle(TABLE, 6.5, 2.0)).ok  # a move (fusion: > 0.5 m at once)
    clock.now += 8 * SECOND
    service.process()
    assert full_maps(rec) == []
    clock.now += 2 * SECOND
    service.process()
    assert {skill for _, skill, _ in full_maps(rec)} == {"navigation", "lab-navigation"}


def test_a_clean_stop_publishes_every_map_that_changed_since_its_last_full_version() -> None:
    service, rec, _ = started()
    assert observe(service, "robot1", box_turtle(TABLE, 5.0, 2.0)).ok
    rec.events.clear()
    service.flush_full_maps()
    assert {skill for _, skill, _ in full_maps(rec)} == {"navigation", "lab-navigation"}


def test_the_old_full_map_interval_key_is_refused_naming_its_replacement(tmp_path: Path) -> None:
    path = tmp_path / "old.toml"
    path.write_text("[limits]\nfull_map_interval_s = 0.2\n")
    with pytest.raises(ConfigError, match="keyframe_interval_s"):
        load_config(path)
