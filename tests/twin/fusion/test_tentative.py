"""New elements from a robot that streams views: M of N. Its new object is held until its next view
that should have seen it reports it again; a view that should have seen it without it drops it (a false
detection, never created nor removed); a one-shot report creates at once."""

from __future__ import annotations

import math
import time
from dataclasses import replace

import pytest

from tests.twin.box_lab import OX, OY
from tests.twin.fusion.fusion_helpers import CORRIDOR, ROOM_A, box, view, view_only
from tests.twin.live_helpers import observe, started
from twin.fusion.footprints import pose_of
from twin.live import TwinService

S = 10**9
GHOST = "urn:robot1:false-1"
CHAIR = "urn:robot1:trk-7"
FURNITURE = ("IfcFurniture",)


def seen(iri: str, x: float, y: float, ns: int, polygon: list[tuple[float, float]] = ROOM_A) -> bytes:
    """A 0.5 m object at lab (x, y) and the view it was seen in."""
    return box(iri, x, y, sx=0.5, sy=0.5) + view(ns, polygon, detects=FURNITURE)


def looking(service: TwinService, robot: str, ns: int, polygon: list[tuple[float, float]] = ROOM_A) -> None:
    assert observe(service, robot, view_only(ns, polygon, detects=FURNITURE)).ok


def test_a_streaming_robots_one_off_detection_is_dropped_by_its_next_view_and_never_becomes_an_element() -> (
    None
):
    service, _ = started()
    t = time.time_ns()
    looking(service, "robot1", t)  # the robot streams from here on
    rev = service.revision
    held = observe(service, "robot1", seen(GHOST, 2.0, 2.0, t + S // 5))
    assert held.body["tentative"] == [GHOST] and held.body["unchanged"] is True
    assert GHOST not in service.states and GHOST in service.live.fusion.tentative
    looking(service, "robot1", t + 2 * S // 5)  # its next view should have seen it: a false detection
    assert GHOST not in service.live.fusion.tentative
    again = observe(service, "robot1", seen(GHOST, 2.0, 2.0, t + 3 * S // 5))  # in a row, not twice ever
    assert again.body["tentative"] == [GHOST] and service.revision == rev and GHOST not in service.states


def test_a_streaming_robots_new_object_seen_again_in_its_next_view_is_created_in_one_revision() -> None:
    service, _ = started()
    t = time.time_ns()
    looking(service, "robot1", t)
    rev = service.revision
    assert observe(service, "robot1", seen(CHAIR, 2.0, 2.0, t + S // 5)).body["tentative"] == [CHAIR]
    second = observe(service, "robot1", seen(CHAIR, 2.01, 2.0, t + 2 * S // 5))
    assert second.body["upserted"] == [CHAIR] and "tentative" not in second.body
    assert service.revision == rev + 1 and CHAIR not in service.live.fusion.tentative


def test_a_held_object_that_the_next_view_could_not_see_stays_held_until_seen_again() -> None:
    service, _ = started()
    t = time.time_ns()
    looking(service, "robot1", t)
    observe(service, "robot1", seen(CHAIR, 2.0, 2.0, t + S // 5))
    looking(service, "robot1", t + 2 * S // 5, CORRIDOR)  # it looked elsewhere
    assert CHAIR in service.live.fusion.tentative
    assert observe(service, "robot1", seen(CHAIR, 2.0, 2.0, t + 3 * S // 5)).body["upserted"] == [CHAIR]


def test_a_one_shot_report_creates_at_once_with_a_view_or_without_one() -> None:
    service, _ = started()
    t = time.time_ns()
    first = observe(service, "robot2", seen("urn:robot2:table", 2.0, 2.0, t))  # its first view
    assert first.body["upserted"] == ["urn:robot2:table"]
    looking(service, "robot1", t)
    plain = observe(service, "robot1", box("urn:robot1:desk", 6.0, 2.0, sx=1.0, sy=0.6))  # no view
    assert plain.body["upserted"] == ["urn:robot1:desk"]


def test_a_robot_whose_previous_view_was_seen_longer_than_stream_gap_s_before_creates_at_once() -> None:
    service, _ = started()
    t = time.time_ns()
    looking(service, "robot1", t - 3 * S)  # seen 3 s before, sent just now: the views' times count
    assert observe(service, "robot1", seen(CHAIR, 2.0, 2.0, t)).body["upserted"] == [CHAIR]


def test_stream_sightings_1_creates_a_streaming_robots_new_object_at_once() -> None:
    service, _ = started()
    rules = replace(service.config.fusion, stream_sightings=1)
    service.observer.config = replace(service.config, fusion=rules)
    t = time.time_ns()
    looking(service, "robot1", t)
    assert observe(service, "robot1", seen(GHOST, 2.0, 2.0, t + S // 5)).body["upserted"] == [GHOST]


def test_a_detector_without_track_ids_is_held_by_place_and_created_at_its_second_view() -> None:
    service, _ = started()
    t = time.time_ns()
    looking(service, "robot1", t)
    first = observe(service, "robot1", seen("urn:robot1:once-1", 2.0, 2.0, t + S // 5))
    assert first.body["tentative"] == ["urn:robot1:once-1"]
    second = observe(service, "robot1", seen("urn:robot1:once-2", 2.02, 2.0, t + 2 * S // 5))
    assert second.body["upserted"] == ["urn:robot1:once-2"] and not service.live.fusion.tentative
    third = observe(service, "robot1", seen("urn:robot1:once-3", 2.01, 2.0, t + 3 * S // 5))
    assert third.body["resolved"] == {"urn:robot1:once-3": "urn:robot1:once-2"}


def test_a_streaming_robots_new_object_is_created_at_the_mean_of_its_held_sightings_not_its_last() -> None:
    # a desk glimpsed twice, its boxes 6 cm apart (a detector's noise; the second with its heading
    # flipped): created where the last one put it, it would stand a map cell off, free floor inside
    # it until refine_after confirmations that a passing robot never sends
    service, _ = started()
    t = time.time_ns()
    looking(service, "robot1", t)
    desk = box(CHAIR, 2.0, 2.0, sx=1.2, sy=0.6, yaw=0.02) + view(t + S // 5, ROOM_A, detects=FURNITURE)
    assert observe(service, "robot1", desk).body["tentative"] == [CHAIR]
    again = box(CHAIR, 2.06, 1.98, sx=1.22, sy=0.6, yaw=math.pi) + view(
        t + 2 * S // 5, ROOM_A, detects=FURNITURE
    )
    assert observe(service, "robot1", again).body["upserted"] == [CHAIR]
    shape = service.live_maps.shape_of(CHAIR)
    assert shape is not None
    pose = pose_of(shape)
    assert (pose.cx - OX, pose.cy - OY) == (pytest.approx(2.03, abs=1e-3), pytest.approx(1.99, abs=1e-3))
    assert (pose.sx, pose.yaw % math.pi) == (pytest.approx(1.21, abs=1e-3), pytest.approx(0.01, abs=1e-3))
