"""Detector bias: a robot whose detector puts objects 20 cm off is corrected once its bias is known
from the elements other robots also see."""

from __future__ import annotations

import pytest

from tests.twin.box_lab import OX
from tests.twin.fusion.fusion_helpers import box, sensed
from tests.twin.fusion.test_clocks import FakeClock, with_clock
from tests.twin.live_helpers import observe, started
from twin.live.status import service_status

MS = 10**6


def test_a_robot_20_cm_off_is_learnt_from_shared_sightings_and_its_own_finds_land_where_they_stand() -> None:
    service, _ = started()
    clock = FakeClock(service.clock())
    with_clock(service, clock)
    for _ in range(30):  # three robots see one desk; robot3's detector puts it 20 cm further in x
        for robot, x in (("robot1", 5.0), ("robot2", 5.0), ("robot3", 5.2)):
            reply = observe(service, robot, sensed(box(f"urn:{robot}:d", x, 2.0, sx=1.2, sy=0.6), clock.now))
            assert reply.ok
            clock.now += 70 * MS
    assert service.revision == 1  # never moved: robot3's sightings were held, then corrected
    biases = service_status(service)["fusion"]["detector_biases"]  # type: ignore[index]
    assert biases["robot3"][0] == pytest.approx(0.2, abs=0.02) and "robot1" not in biases  # none to apply
    clock.now += 30 * 10**9  # later, robot3 alone finds a chair nobody else has seen, at true x = 7.0
    found = observe(service, "robot3", sensed(box("urn:robot3:c", 7.2, 2.0, sx=0.5, sy=0.5), clock.now))
    assert found.body["upserted"] == ["urn:robot3:c"]
    bounds = service.live_maps.bounds_of("urn:robot3:c")
    assert bounds is not None and (bounds[0] + bounds[3]) / 2 == pytest.approx(OX + 7.0, abs=0.02)


def test_a_robot_that_agrees_with_nobody_is_corrected_by_one_partner_that_agrees_with_a_third() -> None:
    service, _ = started()
    clock = FakeClock(service.clock())
    with_clock(service, clock)
    for _ in range(10):  # robot1 and robot2 agree on a desk: they vouch for each other
        for robot in ("robot1", "robot2"):
            observe(service, robot, sensed(box(f"urn:{robot}:d", 5.0, 2.0, sx=1.2, sy=0.6), clock.now))
            clock.now += 100 * MS
    for _ in range(10):  # robot3, 20 cm off, shares a cabinet with robot1 alone
        for robot, x in (("robot1", 2.0), ("robot3", 2.2)):
            observe(service, robot, sensed(box(f"urn:{robot}:c", x, 1.0, sx=0.8, sy=0.5), clock.now))
            clock.now += 100 * MS
    biases = service_status(service)["fusion"]["detector_biases"]  # type: ignore[index]
    assert list(biases) == ["robot3"] and biases["robot3"][0] == pytest.approx(0.2, abs=0.02)
    bounds = service.live_maps.bounds_of("urn:robot1:c")
    assert bounds is not None and (bounds[0] + bounds[3]) / 2 == pytest.approx(OX + 2.0, abs=0.02)
