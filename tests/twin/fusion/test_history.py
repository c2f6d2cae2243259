"""Late news: a first sighting seen before the element moved or went, arriving late, is that element
(an alias, acked stale), never a ghost at its old place (issue case 5)."""

from __future__ import annotations

from tests.twin.fusion.fusion_helpers import PREFIX, at, box, cell, sensed
from tests.twin.fusion.test_clocks import FakeClock, with_clock
from tests.twin.live_helpers import observe, started

TABLE = "urn:robot1:table"
S = 10**9


def test_a_late_first_sighting_from_before_a_move_becomes_an_alias_and_makes_no_second_table() -> None:
    service, _ = started()
    t = service.clock() - 10 * S
    observe(service, "robot1", sensed(box(TABLE, 5.0, 2.0, sx=1.0, sy=0.6), t))
    moved = observe(service, "robot1", sensed(box(TABLE, 6.4, 2.0, sx=1.0, sy=0.6), t + 3 * S))  # 1.4 m
    assert moved.body["upserted"] == [TABLE]
    late = observe(service, "robot2", sensed(box("urn:robot2:t", 5.02, 2.0, sx=1.0, sy=0.6), t + 1 * S))
    assert late.body["stale"] == ["urn:robot2:t"] and late.body["resolved"] == {"urn:robot2:t": TABLE}
    assert late.body["unchanged"] is True and "urn:robot2:t" not in service.states
    assert cell(service, 5.0, 2.0) == 0 and cell(service, 6.4, 2.0) == 100
    fresh = observe(service, "robot2", sensed(box("urn:robot2:t", 6.41, 2.0, sx=1.0, sy=0.6), t + 4 * S))
    assert fresh.body["resolved"] == {"urn:robot2:t": TABLE} and "stale" not in fresh.body


def test_a_late_first_sighting_of_a_removed_elements_old_place_creates_nothing() -> None:
    service, _ = started()
    t = service.clock() - 10 * S
    observe(service, "robot1", sensed(box(TABLE, 5.0, 2.0, sx=1.0, sy=0.6), t))
    gone = observe(
        service, "robot1", f"{PREFIX}<{TABLE}> twin:removed true ; twin:senseTime {at(t + 3 * S)} .".encode()
    )
    assert gone.body["removed"] == [TABLE]
    late = observe(service, "robot3", sensed(box("urn:robot3:x", 5.0, 2.0, sx=1.0, sy=0.6), t + 2 * S))
    assert late.body["stale"] == ["urn:robot3:x"] and "urn:robot3:x" not in service.states
    assert cell(service, 5.0, 2.0) == 0
    back = observe(service, "robot3", sensed(box("urn:robot3:x", 5.0, 2.0, sx=1.0, sy=0.6), t + 5 * S))
    assert back.body["upserted"] == ["urn:robot3:x"]  # seen after the removal: the table is back


def test_a_new_sighting_after_the_move_at_the_old_place_is_a_new_object() -> None:
    service, _ = started()
    t = service.clock() - 10 * S
    observe(service, "robot1", sensed(box(TABLE, 5.0, 2.0, sx=1.0, sy=0.6), t))
    observe(service, "robot1", sensed(box(TABLE, 6.4, 2.0, sx=1.0, sy=0.6), t + 3 * S))
    other = observe(service, "robot2", sensed(box("urn:robot2:t2", 5.0, 2.0, sx=1.0, sy=0.6), t + 4 * S))
    assert other.body["upserted"] == ["urn:robot2:t2"] and "stale" not in other.body


def test_a_robot_whose_reports_are_always_2_s_late_never_puts_a_moved_table_back() -> None:
    service, _ = started()
    clock = FakeClock(service.clock())
    with_clock(service, clock)
    for _ in range(35):  # 7 s: the late robot's offset (2 s) is known; it sees the table at 5.0
        observe(service, "late", sensed(box("urn:late:t", 5.0, 2.0, sx=1.0, sy=0.6), clock.now - 2 * S))
        clock.now += S // 5
    moved = observe(service, "robot1", sensed(box("urn:late:t", 6.4, 2.0, sx=1.0, sy=0.6), clock.now))
    assert moved.body["upserted"] == ["urn:late:t"], moved.body  # robot1 saw it moved 1.4 m
    for _ in range(8):  # the late robot's reports of the old place, sensed before the move, keep coming
        clock.now += S // 5
        echo = observe(
            service, "late", sensed(box("urn:late:t", 5.0, 2.0, sx=1.0, sy=0.6), clock.now - 2 * S)
        )
        assert "upserted" not in echo.body or not echo.body["upserted"], echo.body
    assert cell(service, 6.4, 2.0) == 100 and cell(service, 5.0, 2.0) == 0
