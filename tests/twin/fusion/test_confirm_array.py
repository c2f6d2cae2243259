"""Confirmations at once (:mod:`twin.fusion.confirm_array`) decide what the per-report rules decide.

The same robots' arrays (typed records with views, as the ROS ingest submits them) go to two services
on the box lab with the same simulated clock: one settles all-confirmation arrays at once, the other
has the shortcut turned off and fuses every report by the per-report rules. Replies, fusion's memory
(sightings, refinements, detector means and biases, aliases, size evidence, decided rules) and the
graph must come out the same, while most arrays take the shortcut.
"""

from __future__ import annotations

import random
from dataclasses import replace

import numpy as np
import pytest

from tests.conftest import imported
from tests.twin.box_lab import OX, OY, box_lab
from tests.twin.fusion.fusion_helpers import Clock, assert_same_shapes, confirmations_at_once
from twin.config import load_config
from twin.live import Reply, TwinService
from twin.records import ElementReport, Observation, ObservedBox, ObservedView

SX, SY, SZ = 0.5, 0.4, 0.75
SPOTS = [(8.5 + 0.9 * c, 0.6 + 1.0 * r) for r in range(3) for c in range(4)]
"""12 table spots in Room B (x 8..12, y 0..4), storey frame."""
ROOM_B = np.array([[OX + x, OY + y] for x, y in ((8.1, 0.1), (11.9, 0.1), (11.9, 3.9), (8.1, 3.9))])
BIAS = {"robot1": 0.0, "robot2": 0.0, "robot3": 0.2}
"""robot3's detector puts everything 20 cm east (a bias the others' sightings reveal)."""


def _array(rng: random.Random, robot: str, spots: list[tuple[float, float]], sense: int) -> Observation:
    reports = []
    for i, (x, y) in enumerate(spots):
        wide = i == 5 and robot == "robot2"  # other sizes (resize evidence; the size gate passes)
        sizes = (SX + 0.16, SY, SZ) if wide else (SX, SY, SZ)
        box = ObservedBox(
            OX + x + BIAS[robot] + rng.gauss(0, 0.01),
            OY + y + rng.gauss(0, 0.01),
            SZ / 2,
            *sizes,
            rng.gauss(0, 0.01) + (np.pi if rng.random() < 0.2 else 0.0),  # a flipped heading now and then
        )
        reports.append(ElementReport(f"urn:{robot}:t{i}", "IfcFurniture", "ground-floor", box))
    origin = (OX + 10, OY + 2, 1.2)
    view = ObservedView("ground-floor", (ROOM_B,), ("IfcFurniture",), sense_ns=sense, origin=origin)
    return Observation(tuple(reports), view)


def _run(shortcut: bool) -> tuple[list[dict[str, object]], TwinService, int]:
    """The script: robot1 makes the tables, robots 2 and 3 see them through aliases; 600 arrays in
    turns, some seen before the previous one (stale), tables moved (far, and short moves that are held)
    and one seen larger by robot2."""
    clock = Clock()
    service = TwinService(imported(box_lab()), load_config(), clock=clock)
    service.start()
    replies: list[Reply] = []
    with confirmations_at_once(shortcut) as settled:
        rng = random.Random(7)
        spots = list(SPOTS)
        for step in range(600):
            clock.ns += 30_000_000
            robot = ("robot1", "robot2", "robot3")[step % 3]
            if step in {150, 390}:
                dy = 2.9 if step == 150 else -2.9
                spots[2] = (spots[2][0], spots[2][1] + dy)  # a certain move, into free floor and back
            if step == 270:
                spots[7] = (spots[7][0] + 0.25, spots[7][1])  # a short move: held until sightings agree
            late = step % 7 == 3  # seen before the previous robot's array: stale where that one saw it
            obs = _array(rng, robot, spots, clock.ns - (70_000_000 if late else 20_000_000))
            service.submit_observation(robot, obs, replies.append)
            service.process()
    return [r.body for r in replies], service, settled.arrays


@pytest.fixture(scope="module")
def both() -> tuple[tuple[list[dict[str, object]], TwinService, int], ...]:
    return _run(True), _run(False)


def test_the_shortcut_settles_most_arrays(both) -> None:  # type: ignore[no-untyped-def]
    (_, _, settled), (_, _, off) = both
    assert off == 0
    assert settled > 300  # robot2 reports one table at other sizes: its arrays take the rules


def test_replies_are_the_same_with_and_without_the_shortcut(both) -> None:  # type: ignore[no-untyped-def]
    (fast, _, _), (slow, _, _) = both
    assert len(fast) == len(slow) == 600
    assert fast == slow
    assert any("resolved" in r for r in fast)  # robots 2 and 3 went through aliases
    assert sum("stale" in r for r in fast) > 50  # arrays seen before another robot's, taken after it


def test_fusion_memory_is_the_same_with_and_without_the_shortcut(both) -> None:  # type: ignore[no-untyped-def]
    (_, a, _), (_, b, _) = both
    ma, mb = a.live.fusion.to_json(), b.live.fusion.to_json()
    assert ma["tracks"] == mb["tracks"]
    assert ma == mb
    assert any(t["sizes"] for t in ma["tracks"].values()) or any(
        "pending_resize" in t.as_json() for t in a.live.fusion.tracks.values()
    )
    assert {r for r, *_ in ma["pairs"]} == {"robot1", "robot2", "robot3"}  # detector biases compared


def test_the_twin_is_the_same_with_and_without_the_shortcut(both) -> None:  # type: ignore[no-untyped-def]
    (_, a, _), (_, b, _) = both
    assert a.live.revision == b.live.revision > 1
    assert set(a.live.states) == set(b.live.states)
    assert_same_shapes(a, b)


def _seen_by(robot: str, obs: Observation) -> Observation:
    """``obs`` (robot1's boxes) as ``robot`` reports it: its own IRIs."""
    return replace(obs, reports=tuple(replace(r, iri=r.iri.replace("robot1", robot)) for r in obs.reports))


def _moved_in_a_batch(shortcut: bool) -> tuple[list[dict[str, object]], TwinService, int]:
    """robot1 makes the tables, robot4 (noise as robot1's) sees them (aliases); then, in one batch,
    robot1 sees table 2 moved 2.9 m (a certain move) and robot4 confirms it there."""
    clock = Clock()
    service = TwinService(imported(box_lab()), load_config(), clock=clock)
    service.start()
    replies: list[Reply] = []
    rng = random.Random(3)
    spots = list(SPOTS)
    with confirmations_at_once(shortcut) as settled:
        for step in range(30):
            clock.ns += 30_000_000
            robot = ("robot1", "robot4")[step % 2]
            obs = _seen_by(robot, _array(rng, "robot1", spots, clock.ns - 20_000_000))
            service.submit_observation(robot, obs, replies.append)
            service.process()
        before = settled.arrays
        spots[2] = (spots[2][0], spots[2][1] + 2.9)
        clock.ns += 30_000_000
        for k, robot in enumerate(("robot1", "robot4")):
            obs = _seen_by(robot, _array(rng, "robot1", spots, clock.ns - 20_000_000 + k * 1_000_000))
            service.submit_observation(robot, obs, replies.append)
        service.process()
    return [r.body for r in replies], service, settled.arrays - before


def test_an_array_that_confirms_a_move_made_earlier_in_its_batch_is_settled_at_once() -> None:
    fast, a, settled = _moved_in_a_batch(True)
    slow, b, _ = _moved_in_a_batch(False)
    assert settled == 1  # robot4's array; robot1's moved the table (the per-report rules)
    assert fast[-2]["unchanged"] and fast[-1]["upserted"]  # (the move is acked after its commit)
    assert fast == slow
    assert a.live.fusion.to_json() == b.live.fusion.to_json()
