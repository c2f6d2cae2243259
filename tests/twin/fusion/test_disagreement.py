"""No flapping between robots: a short move another robot contradicts waits, and while two robots disagree
the element covers both poses (issue case 6)."""

from __future__ import annotations

import pytest

from tests.twin.box_lab import OX
from tests.twin.fusion.fusion_helpers import box, cell, sensed
from tests.twin.fusion.test_clocks import FakeClock, with_clock
from tests.twin.live_helpers import observe, started
from twin.live import TwinService

DESK = "urn:robot1:desk"
MS = 10**6
S = 10**9


def pass_by(
    service: TwinService, clock: FakeClock, robot: str, iri: str, x: float, *, sightings: int = 5
) -> None:
    """``robot`` passes the desk, seeing it at ``x`` at 5 Hz."""
    for _ in range(sightings):
        reply = observe(service, robot, sensed(box(iri, x, 2.0, sx=1.2, sy=0.6), clock.now))
        assert reply.ok, reply.body
        clock.now += 200 * MS


def test_two_robots_whose_detectors_differ_by_20_cm_passing_in_turns_do_not_flap_a_still_desk() -> None:
    service, _ = started()
    clock = FakeClock(service.clock())
    with_clock(service, clock)
    pass_by(service, clock, "robot1", DESK, 5.0)
    for turn in range(6):
        clock.now += 3 * S
        if turn % 2 == 0:
            pass_by(service, clock, "robot2", "urn:robot2:d", 5.2)
        else:
            pass_by(service, clock, "robot1", DESK, 5.0)
    assert service.revision == 2  # the creation and one cover of both poses; no flapping after
    assert cell(service, 4.43, 2.0) == 100 and cell(service, 5.77, 2.0) == 100  # both desks' ends


def test_a_desk_two_robots_disagree_on_covers_both_poses_until_a_third_robot_takes_a_side() -> None:
    service, _ = started()
    clock = FakeClock(service.clock())
    with_clock(service, clock)
    pass_by(service, clock, "robot1", DESK, 5.2)  # 20 cm off, the first to see it
    pass_by(service, clock, "robot2", "urn:robot2:d", 5.0)
    covering = service.live_maps.bounds_of(DESK)
    assert covering is not None and covering[3] - covering[0] == pytest.approx(1.4, abs=0.02)
    reply = observe(service, "robot1", sensed(box(DESK, 5.2, 2.0, sx=1.2, sy=0.6), clock.now))
    assert reply.body["unchanged"] is True and reply.body["pending"] == [DESK]
    pass_by(service, clock, "robot3", "urn:robot3:d", 5.0, sightings=1)  # a third robot: 2 against 1
    bounds = service.live_maps.bounds_of(DESK)
    assert bounds is not None and bounds[3] - bounds[0] == pytest.approx(1.2, abs=0.02)
    assert (bounds[0] + bounds[3]) / 2 == pytest.approx(OX + 5.0, abs=0.02)
    pass_by(service, clock, "robot1", DESK, 5.2)  # the loser keeps watching: outvoted, no flap
    assert service.revision == 3  # created, covered, settled


def test_one_sighting_nearer_the_other_pose_does_not_change_a_robots_side_and_settle_the_dispute() -> None:
    service, _ = started()
    clock = FakeClock(service.clock())
    with_clock(service, clock)
    pass_by(service, clock, "robot1", DESK, 5.2)  # 20 cm off, the first to see it
    pass_by(service, clock, "robot2", "urn:robot2:d", 5.0)  # one against one: it covers both poses
    revision = service.revision
    outlier = box("urn:robot2:d", 5.11, 2.0, sx=1.2, sy=0.6)  # robot2's noise: nearer robot1's pose
    assert observe(service, "robot2", sensed(outlier, clock.now)).body["pending"] == [DESK]
    clock.now += 200 * MS
    pass_by(service, clock, "robot2", "urn:robot2:d", 5.0)
    assert service.revision == revision  # not settled at robot1's pose, not covered again
    assert cell(service, 4.43, 2.0) == 100 and cell(service, 5.77, 2.0) == 100  # still both


def test_a_biased_robots_two_quick_sightings_right_after_a_creation_do_not_move_it_first() -> None:
    service, _ = started()
    clock = FakeClock(service.clock())
    with_clock(service, clock)
    observe(service, "robot1", sensed(box(DESK, 5.0, 2.0, sx=1.2, sy=0.6), clock.now))  # its creator
    for _ in range(2):  # before robot1's next sighting, robot2 sees it 20 cm off, twice
        clock.now += 100 * MS
        observe(service, "robot2", sensed(box("urn:robot2:d", 5.2, 2.0, sx=1.2, sy=0.6), clock.now))
    assert cell(service, 4.43, 2.0) == 100 and cell(service, 5.77, 2.0) == 100  # covers both


def test_a_short_move_both_robots_see_is_applied() -> None:
    service, _ = started()
    clock = FakeClock(service.clock())
    with_clock(service, clock)
    pass_by(service, clock, "robot1", DESK, 5.0)
    pass_by(service, clock, "robot2", "urn:robot2:d", 5.0)
    for _ in range(2):  # the desk moved 25 cm: each robot sees it there
        for robot, iri in (("robot1", DESK), ("robot2", "urn:robot2:d")):
            observe(service, robot, sensed(box(iri, 5.25, 2.0, sx=1.2, sy=0.6), clock.now))
            clock.now += 100 * MS
    assert service.revision == 2 and cell(service, 5.82, 2.0) == 100


def test_a_short_move_one_robot_sees_long_after_the_others_last_sighting_covers_both_until_it_returns() -> (
    None
):
    service, _ = started()
    clock = FakeClock(service.clock())
    with_clock(service, clock)
    pass_by(service, clock, "robot1", DESK, 5.0)
    clock.now += 20 * S
    pass_by(service, clock, "robot2", "urn:robot2:d", 5.25, sightings=2)  # moved, or robot2 is off
    assert service.revision == 2 and cell(service, 4.43, 2.0) == 100 and cell(service, 5.82, 2.0) == 100
    clock.now += 20 * S
    pass_by(service, clock, "robot1", DESK, 5.25, sightings=2)  # robot1 back: it did move
    bounds = service.live_maps.bounds_of(DESK)
    assert bounds is not None and bounds[3] - bounds[0] == pytest.approx(1.2, abs=0.02)
    assert (bounds[0] + bounds[3]) / 2 == pytest.approx(OX + 5.25, abs=0.02) and service.revision == 3


def test_a_desk_placed_by_a_biased_robot_follows_the_two_robots_that_agree_while_it_keeps_watching() -> None:
    service, _ = started()
    clock = FakeClock(service.clock())
    with_clock(service, clock)
    observe(service, "biased", sensed(box(DESK, 5.2, 2.0, sx=1.2, sy=0.6), clock.now))  # 20 cm off
    for _ in range(4):  # all three watch, in turns: the biased robot confirms its own pose each time
        for robot, x in (("biased", 5.2), ("robot1", 5.0), ("robot2", 5.0)):
            observe(service, robot, sensed(box(f"urn:{robot}:d", x, 2.0, sx=1.2, sy=0.6), clock.now))
            clock.now += 70 * MS
    bounds = service.live_maps.bounds_of(DESK)
    assert bounds is not None and abs((bounds[0] + bounds[3]) / 2 - (OX + 5.0)) < 0.02
    assert service.revision == 3  # created; both poses covered while 1 against 1; the majority's; no flapping


def test_a_late_robots_sightings_just_older_than_a_watching_biased_robots_latest_cover_its_pose() -> None:
    service, _ = started()
    clock = FakeClock(service.clock())
    with_clock(service, clock)
    for i in range(60):  # robot4 (20 cm off) watches the desk at 5 Hz, its creator
        observe(service, "robot4", sensed(box(DESK, 5.2, 2.0, sx=1.2, sy=0.6), clock.now))
        clock.now += 100 * MS
        if i >= 5:  # robot3's reports arrive 2.0-2.4 s after they were sensed: its sense times, corrected
            late = 2000 * MS if i == 5 else 2400 * MS  # by the least lag, come 0.3 s before robot4's latest
            reply = observe(
                service, "robot3", sensed(box("urn:robot3:d", 5.0, 2.0, sx=1.2, sy=0.6), clock.now - late)
            )
            assert reply.ok, reply.body
        clock.now += 100 * MS
    assert cell(service, 4.43, 2.0) == 100 and cell(service, 5.77, 2.0) == 100  # robot3's desk and robot4's
    assert service.revision == 2  # created, then covered; never moved to the older report
