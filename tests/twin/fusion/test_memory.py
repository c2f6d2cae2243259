"""Fusion's memory: one serialiser covers everything it remembers; the pose index is built at start."""

from __future__ import annotations

import json
import math

import pytest

from tests.twin.fusion.fusion_helpers import ROOM_A, box, sensed, view_only
from tests.twin.fusion.test_clocks import FakeClock, with_clock
from tests.twin.live_helpers import observe, started
from twin.fusion.effects import (
    count_tentative,
    drop_alias,
    looked,
    mark_distinct,
    miss,
    reset_refinement,
    set_alias,
    sighting,
    use_alias,
)
from twin.fusion.footprints import box_pose
from twin.fusion.memory import Dispute, FusionMemory, RobotMean, Tentative

S = 10**9


def test_a_memory_with_every_kind_of_entry_survives_a_json_round_trip() -> None:
    service, _ = started()
    clock = FakeClock(service.clock())
    with_clock(service, clock)
    t = clock.now
    for i in range(30):  # sightings, confirmations, clock offsets, a held move, size evidence
        observe(
            service, "robot1", sensed(box("urn:robot1:desk", 5.0, 2.0, sx=1.0, sy=0.6), t + i * S // 5 - S)
        )
        clock.now += S // 5
    observe(service, "robot2", sensed(box("urn:robot2:d", 5.25, 2.0, sx=1.2, sy=0.6), clock.now))
    observe(service, "robot1", sensed(box("urn:robot1:chair", 2.0, 1.0, sx=0.5, sy=0.5), clock.now))
    observe(service, "robot1", sensed(box("urn:robot1:chair", 3.0, 1.0, sx=0.5, sy=0.5), clock.now + S))
    observe(service, "robot3", view_only(clock.now + S, ROOM_A, detects=("IfcFurniture",)))
    memory = service.live.fusion
    memory.tentative["urn:robot4:x"] = Tentative(1, clock.now)
    here = box_pose(1.0, 2.0, 0.3, 0.5, 0.5, 0.6, yaw=0.0)
    memory.tentative["urn:robot4:y"] = Tentative(1, clock.now, "robot4", "ground-floor", here)
    memory.distinct.add("urn:robot1:chair")
    desk = memory.tracks["urn:robot1:desk"]
    desk.dispute = Dispute((box_pose(5.0, 2.0, 0.4, 1.0, 0.6, 0.8, yaw=0.0),) * 2, {"robot1": (0, clock.now)})
    assert memory.history and memory.clocks and memory.aliases and memory.tracks["urn:robot1:desk"].moving
    assert memory.views  # robot3's view
    text = json.dumps(memory.to_json())
    again = FusionMemory.from_json(json.loads(text))
    assert again.to_json() == memory.to_json()
    for name in ("tracks", "aliases", "tentative", "views", "distinct", "history", "pairs"):
        assert getattr(again, name) == getattr(memory, name), name
    assert {r: list(e.samples) for r, e in again.clocks.items()} == {
        r: list(e.samples) for r, e in memory.clocks.items()
    }
    assert again.poses is None and math.isfinite(again.clocks["robot1"].offset_ns)


def test_undo_puts_back_every_entry_changed_since_begin_and_keep_keeps_them() -> None:
    memory = FusionMemory()
    for effect in (
        sighting("urn:e1", "robot1", S),
        set_alias("urn:robot1:a", "urn:e1", S),
        count_tentative("urn:robot1:b", Tentative(1, S)),
        mark_distinct("urn:e1"),
        looked("robot1", S),
    ):
        effect(memory)
    memory.pairs["robot1", "robot2"] = RobotMean(5, 0.1, 0.0, S)
    before = memory.to_json()
    memory.begin()
    for effect in (
        sighting("urn:e1", "robot2", 2 * S),  # an entry changed in place
        miss("urn:e2", "robot2", 2 * S),  # a new one
        use_alias("urn:robot1:a", 2 * S),
        drop_alias("urn:robot1:a"),
        set_alias("urn:robot2:c", "urn:e2", 2 * S),
        count_tentative("urn:robot1:b", None),
        count_tentative("urn:robot2:d", Tentative(1, 2 * S, "robot2", "ground-floor", None)),
        mark_distinct("urn:e2"),
        looked("robot1", 2 * S),
        reset_refinement("urn:e1"),
    ):
        effect(memory)
    memory.changing("pairs", ("robot1", "robot2"))
    memory.pairs["robot1", "robot2"] = RobotMean(6, 0.2, 0.0, 2 * S)
    changed = memory.to_json()
    assert changed != before
    memory.undo()
    assert memory.to_json() == before and memory.journal is None
    memory.begin()
    miss("urn:e2", "robot2", 2 * S)(memory)
    memory.keep()
    memory.undo()  # nothing journaled any more
    assert "urn:e2" in memory.tracks


def test_a_memory_of_an_unknown_format_is_refused_naming_it() -> None:
    with pytest.raises(ValueError, match="format 99"):
        FusionMemory.from_json({"format": 99})


def test_the_pose_index_is_built_when_the_service_starts() -> None:
    service, _ = started()
    poses = service.live.fusion.poses
    assert poses is not None and any(poses.values())  # the imported table, before any observation
