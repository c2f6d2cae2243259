"""Observations handled in batches give what one at a time gives: the acks, the maps, the graph."""

from __future__ import annotations

import types

import numpy as np
import pytest

import twin.live.requests as requests_module
from tests.twin.live_helpers import Recorder, box_turtle, started
from twin.live import Reply, TwinService
from twin.live.events import MapUpdated
from twin.live.requests import ObserveRequest, RequestQueue

ROBOTS = 3


def _rounds(rounds: int) -> list[list[tuple[str, bytes]]]:
    """``fusion_cost.py``'s workload on the box lab: each robot its own small table, every other round
    moving it 0.5 m (a first sighting, held), the next one re-reporting it there (the move)."""
    out = []
    for k in range(rounds):
        spot = (k + 1) // 2 % 2
        out.append(
            [
                (
                    f"robot{i}",
                    box_turtle(f"urn:cost:robot{i}:table", 4.6 + 1.2 * i + 0.5 * spot, 2.0, sx=0.4, sy=0.4),
                )
                for i in range(ROBOTS)
            ]
        )
    return out


def _ack(r: Reply) -> dict[str, object]:
    """What an ack says of the observation (its map rectangles depend on what shared its map pass)."""
    return {k: v for k, v in r.body.items() if k != "maps"}


def _replay(service: TwinService, rec: Recorder, before: dict) -> None:
    """The maps a subscriber holds after applying every update in order equal the service's maps."""
    held = {k: v.copy() for k, v in before.items()}
    versions = {k: m.version for k, m in service.live_maps.skill_maps.items()}
    for u in rec.of(MapUpdated):
        w = u.window
        held[(u.storey, u.skill)][w.row0 : w.row1, w.col0 : w.col1] = u.data
    for key, m in service.live_maps.skill_maps.items():
        np.testing.assert_array_equal(held[key], m.data, err_msg=str(key))
        np.testing.assert_array_equal(m.data, service.live_maps.rebuild(m), err_msg=str(key))
    assert versions


def test_a_batch_of_robots_acks_and_maps_as_one_observation_at_a_time() -> None:
    clock = iter(range(10**9, 10**12, 10**7))
    batched, rec_b = started()
    single, rec_s = started()
    for s in (batched, single):
        s.clock = lambda: next(clock)
    before = {k: m.data.copy() for k, m in batched.live_maps.skill_maps.items()}
    acks_b: list[Reply] = []
    acks_s: list[Reply] = []
    for round_ in _rounds(6):
        for robot, payload in round_:
            batched.submit_observation(robot, payload, acks_b.append)
        assert batched.process() == ROBOTS  # one batch: one commit, one map pass
        for robot, payload in round_:
            single.submit_observation(robot, payload, acks_s.append)
            single.process()
    assert [_ack(r) for r in acks_b] == [_ack(r) for r in acks_s]
    assert sum(bool(r.body.get("unchanged")) for r in acks_b) == 3 * ROBOTS  # the held first sightings
    assert batched.revision == single.revision > 0
    for key, m in batched.live_maps.skill_maps.items():
        np.testing.assert_array_equal(m.data, single.live_maps.skill_maps[key].data, err_msg=str(key))
    _replay(batched, rec_b, before)
    _replay(single, rec_s, before)
    # the robots' tables lie close: a batch's moves are one update of each map they change
    moved = [r for r in acks_b if not r.body.get("unchanged") and r.body["revision"] > ROBOTS]
    assert moved and all(
        len(r.body["maps"]) == len({(m["storey"], m["skill"]) for m in r.body["maps"]}) for r in moved
    )  # type: ignore[union-attr]
    assert len(rec_b.of(MapUpdated)) < len(rec_s.of(MapUpdated))
    triples = "SELECT ?s ?p ?o WHERE { ?s ?p ?o FILTER(?p NOT IN (twin:observedAt, twin:senseTime)) }"
    assert sorted(map(str, batched.store.select(triples))) == sorted(map(str, single.store.select(triples)))


def test_the_writer_waits_its_batch_window_for_observations_that_follow_the_first(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    q = RequestQueue(64, wait_s=0.2)
    q.put(ObserveRequest("robot0", b"0", None, 0))
    waited: list[float] = []

    def window(seconds: float) -> None:  # two observations come while the writer waits its window
        waited.append(seconds)
        for i in (1, 2):
            q.put(ObserveRequest(f"robot{i}", b"", None, 0))

    monkeypatch.setattr(requests_module, "time", types.SimpleNamespace(sleep=window))
    batch = q.take()
    assert waited == [0.2]  # one wait, not one per observation
    assert isinstance(batch, list) and [r.robot for r in batch] == ["robot0", "robot1", "robot2"]
    assert RequestQueue(64).take() is None
    alone = RequestQueue(64)  # no window: only what is queued
    alone.put(ObserveRequest("robot0", b"0", None, 0))
    assert [r.robot for r in alone.take()] == ["robot0"]  # type: ignore[union-attr]
