"""Steady arrays held back (:class:`adapters.zenoh.ros_hold.SteadyHold`): re-confirmations wait for a
bunch, anything that changes something goes at once with what was held before it, in order."""

from __future__ import annotations

from dataclasses import replace

from adapters.ros.observation_doc import Translation
from adapters.zenoh.ros_hold import SETTLE_ARRAYS, STEADY_M, SteadyHold
from adapters.zenoh.ros_workers import Refused, Translated, Waited
from twin.records import ElementReport, Observation, ObservedBox

TABLES = {"urn:r:t1": (1.0, 2.0), "urn:r:t2": (4.0, 2.0)}


def array(
    robot: str = "robot1", *, moved: dict[str, tuple[float, float]] | None = None, **fields: object
) -> Translated:
    """``robot``'s array of the tables (``moved``: where some stand instead)."""
    spots = {**TABLES, **(moved or {})}
    reports = tuple(
        replace(
            ElementReport(iri, ifc_class="IfcFurniture", storey="ground-floor",
                          box=ObservedBox(x, y, 0.4, 1.2, 0.8, 0.8, 0.1)),
            **fields,  # type: ignore[arg-type]
        )
        for iri, (x, y) in spots.items()
    )  # fmt: skip
    return Translated(robot, Translation(Observation(reports)), 0)


def settled(hold: SteadyHold, robot: str = "robot1") -> float:
    """Pass ``robot``'s first arrays (a change, then the arrays that settle it); the time after them."""
    now = 0.0
    for _ in range(1 + SETTLE_ARRAYS):
        hold.add([array(robot)], now)
        assert hold.due(now)
        hold.take(now)
        now += 0.1
    return now


def test_the_first_array_and_the_arrays_that_settle_it_pass_at_once() -> None:
    hold = SteadyHold(0.04)
    now = settled(hold)
    hold.add([array()], now)
    assert not hold.due(now)  # then steady: held


def test_steady_arrays_are_held_until_the_hold_has_passed_and_then_go_together_in_order() -> None:
    hold = SteadyHold(0.04)
    now = settled(hold)
    first, second = array(), array(moved={"urn:r:t1": (1.0 + STEADY_M / 2, 2.0)})
    hold.add([first], now)
    hold.add([second], now + 0.03)
    assert not hold.due(now + 0.039)
    assert hold.wait_s(now + 0.03) is not None
    assert hold.due(now + 0.041)
    assert hold.take(now + 0.041) == [first, second]
    assert not hold.due(now + 1.0) and hold.wait_s(now + 1.0) is None


def test_a_moved_box_goes_at_once_with_what_was_held_before_it() -> None:
    hold = SteadyHold(10.0)
    now = settled(hold)
    steady, moved = array(), array(moved={"urn:r:t2": (4.8, 2.0)})
    hold.add([steady], now)
    assert not hold.due(now)
    hold.add([moved], now + 0.01)
    assert hold.due(now + 0.01)
    assert hold.take(now + 0.01) == [steady, moved]


def test_the_arrays_after_a_move_pass_at_once_then_the_new_place_is_steady() -> None:
    hold = SteadyHold(10.0)
    now = settled(hold)
    there = {"urn:r:t2": (4.8, 2.0)}
    for k in range(1 + SETTLE_ARRAYS):  # the move, then the sightings that complete it
        hold.add([array(moved=there)], now + k)
        assert hold.due(now + k), k
        hold.take(now + k)
    hold.add([array(moved=there)], now + 10)
    assert not hold.due(now + 10)


def test_a_slow_drift_adds_up_to_a_change() -> None:
    hold = SteadyHold(10.0)
    now = settled(hold)
    step = STEADY_M * 0.3
    dues = []
    for k in range(1, 5):
        hold.add([array(moved={"urn:r:t1": (1.0 + k * step, 2.0)})], now)
        dues.append(hold.due(now))
    assert dues == [False, False, False, True]  # beyond STEADY_M of the box last passed on


def test_a_track_that_appears_or_is_lost_goes_at_once() -> None:
    hold = SteadyHold(10.0)
    now = settled(hold)
    hold.add([array(moved={"urn:r:t3": (7.0, 2.0)})], now)
    assert hold.due(now)
    hold.take(now)
    hold = SteadyHold(10.0)
    now = settled(hold)
    lost = array()
    obs = lost.translation.document
    assert isinstance(obs, Observation)
    hold.add([replace(lost, translation=Translation(Observation(obs.reports[:1])))], now)
    assert hold.due(now)


def test_anything_but_a_plain_array_of_boxes_goes_at_once() -> None:
    for outcome in (
        Refused("robot1", "malformed", "bad bytes"),
        Waited("robot1"),
        array(labels=("Wet floor",)),
        array(is_open=True),
        Translated("robot1", Translation(None), 0),
        Translated("robot1", Translation(b"<a> <b> <c> ."), 0),
    ):
        hold = SteadyHold(10.0)
        now = settled(hold)
        hold.add([outcome], now)
        assert hold.due(now), outcome


def test_a_change_takes_its_robots_held_arrays_and_leaves_the_others_held_until_their_time() -> None:
    hold = SteadyHold(0.04)
    settled(hold, "robot2")
    now = settled(hold, "robot1")
    mine, theirs = array("robot1"), array("robot2")
    moved = array("robot1", moved={"urn:r:t2": (4.8, 2.0)})
    later = array("robot2")
    hold.add([theirs, mine], now)
    hold.add([moved, later], now + 0.01)
    assert hold.due(now + 0.01)
    assert hold.take(now + 0.01) == [mine, moved]
    assert not hold.due(now + 0.03) and hold.wait_s(now + 0.03) is not None
    assert hold.due(now + 0.041)
    assert hold.take(now + 0.041) == [theirs, later]
    assert hold.wait_s(now + 1) is None


def test_each_robot_is_steady_on_its_own() -> None:
    hold = SteadyHold(10.0)
    now = settled(hold, "robot1")
    hold.add([array("robot1")], now)
    assert not hold.due(now)
    hold.add([array("robot2")], now)  # robot2's first array: a change
    assert hold.due(now)


def test_a_hold_of_zero_holds_nothing() -> None:
    hold = SteadyHold(0.0)
    now = settled(hold)
    hold.add([array()], now)
    assert hold.due(now)
