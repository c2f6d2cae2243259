"""Clocks: each robot's clock offset is estimated and corrected before sense times are compared; a
sense time later than its arrival is its arrival (issue case 4)."""

from __future__ import annotations

import logging

import pytest

from tests.twin.fusion.fusion_helpers import ROOM_A, box, sensed, view_only
from tests.twin.live_helpers import observe, started
from twin.live import TwinService
from twin.live.status import service_status

CHAIR = "urn:robot1:chair"
MS = 10**6


class FakeClock:
    """The daemon's clock, moved by the test."""

    def __init__(self, start_ns: int) -> None:
        self.now = start_ns

    def __call__(self) -> int:
        return self.now


def with_clock(service: TwinService, clock: FakeClock) -> None:
    service.clock = clock
    service.observer.clock = clock


def run_fleet(
    *, robot1_behind_ns: int, robot2_ahead_ns: int, caplog: pytest.LogCaptureFixture
) -> TwinService:
    """robot1 sees a chair at 5 Hz (its clock behind by ``robot1_behind_ns``); after 6 s robot2's view,
    at 5 Hz in between, covers the chair without seeing it (its clock ahead by ``robot2_ahead_ns``)."""
    service, _ = started()
    clock = FakeClock(service.clock())
    with_clock(service, clock)
    for tick in range(45):  # 9 s
        seen = observe(
            service,
            "robot1",
            sensed(box(CHAIR, 2.0, 1.0, sx=0.5, sy=0.5, sz=0.9), clock.now - robot1_behind_ns),
        )
        assert seen.ok and "stale" not in seen.body, (tick, seen.body)
        assert not service.states[CHAIR].removed, tick
        clock.now += 100 * MS
        if tick >= 30:
            looked = observe(
                service, "robot2", view_only(clock.now + robot2_ahead_ns, ROOM_A, detects=("IfcFurniture",))
            )
            assert looked.ok, looked.body
        clock.now += 100 * MS
    return service


def test_with_synced_clocks_a_chair_one_robot_sees_is_never_removed_by_anothers_views(
    caplog: pytest.LogCaptureFixture,
) -> None:
    service = run_fleet(robot1_behind_ns=0, robot2_ahead_ns=0, caplog=caplog)
    assert not service.states[CHAIR].removed


def test_a_robot_clock_behind_by_1_5_s_is_corrected_and_its_sightings_keep_the_chair(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with caplog.at_level(logging.WARNING, logger="twin.fusion.clocks"):
        service = run_fleet(robot1_behind_ns=1500 * MS, robot2_ahead_ns=0, caplog=caplog)
    assert not service.states[CHAIR].removed
    offsets = service_status(service)["fusion"]["clock_offsets"]  # type: ignore[index]
    assert offsets["robot1"] == pytest.approx(1.5, abs=0.01) and offsets["robot2"] == pytest.approx(
        0.0, abs=0.01
    )
    warnings = [r for r in caplog.records if "robot1" in r.getMessage()]
    assert len(warnings) == 1 and "+1.500 s" in warnings[0].getMessage()


def test_a_viewing_robot_clock_ahead_by_1_5_s_does_not_remove_the_chair(
    caplog: pytest.LogCaptureFixture,
) -> None:
    service = run_fleet(robot1_behind_ns=0, robot2_ahead_ns=1500 * MS, caplog=caplog)
    assert not service.states[CHAIR].removed


def test_a_sense_time_later_than_its_arrival_is_taken_as_its_arrival() -> None:
    service, _ = started()
    clock = FakeClock(service.clock())
    with_clock(service, clock)
    reply = observe(service, "robot1", sensed(box(CHAIR, 2.0, 1.0, sx=0.5, sy=0.5), clock.now + 1500 * MS))
    assert reply.ok and service.states[CHAIR].sensed_ns == clock.now
