"""The writer's fast paths for confirming arrays decide exactly what the general paths decide.

- Confirmations at once (:mod:`twin.fusion.confirm_array`) against the per-report rules, on random
  fleets: robots with their own noise (some beyond the confirmation gates), a biased detector, square
  and oblong tables, flipped headings, arrays seen late (stale), moves and other sizes.
- The bias notes of an array (:func:`twin.fusion.bias.note_sightings_at`, which looks for each robot
  pair's last comparison from the end) against a pass over every comparison.
- :func:`twin.fusion.gates.lies_within` (which rejects a far centre before the polygon test) against the
  polygon test alone.
- The bias notes' effect (which changes the memory's means and pairs in place) while the memory journals:
  undone, the memory as before; kept, as without a journal.
- The alias check of an array whose boxes the confirmation gates check next (sizes only, when those
  gates imply the centre and height gates) against the whole alias check, both followed by the gates;
  the gates at once (sizes against a tolerance that is infinite where an element is not resizable)
  against the gates of an array's first sightings.
"""

from __future__ import annotations

import math
import random
from types import SimpleNamespace

import numpy as np
import pytest

from tests.conftest import imported
from tests.twin.box_lab import OX, OY, box_lab
from tests.twin.fusion.fusion_helpers import Clock, assert_same_shapes, confirmations_at_once
from tests.twin.live_helpers import started
from twin.config import FusionRules, load_config
from twin.fusion.bias import MEAN_MIN, MEAN_WEIGHT, PAIR_WEIGHT, RECENT_NS, note_sightings_at
from twin.fusion.confirm_array import (
    CACHE_SLACK,
    _aliases_fit,
    _cache,
    _canonical,
    _gates,
    _gates_at_once,
    _Held,
    _layout,
)
from twin.fusion.context import FusionContext
from twin.fusion.footprints import Pose, corners, points_in_polygon
from twin.fusion.gates import lies_within
from twin.fusion.memory import FusionMemory, PairTable, RobotMean, Track, memory_from_json
from twin.live import Reply, TwinService
from twin.records import ElementReport, Observation, ObservedBox, ObservedView

ROOM_B = np.array([[OX + x, OY + y] for x, y in ((8.1, 0.1), (11.9, 0.1), (11.9, 3.9), (8.1, 3.9))])
SPOTS = [(8.6 + 0.9 * c, 0.6 + 0.9 * r) for r in range(4) for c in range(4)]
"""16 table spots in Room B, storey frame."""


def _fleet(
    seed: int, shortcut: bool, steps: int, *, batches: bool = False
) -> tuple[list[dict[str, object]], TwinService, int]:
    """``steps`` arrays of a random fleet of six robots on 16 tables (robot0 makes them), to a service
    with confirmations at once on or off (the per-report rules for every report). With ``batches``,
    one to six arrays share a batch (the arrays after a move confirm where it put the table), and some
    moves are certain ones (0.55-0.65 m)."""
    rng = random.Random(seed)
    cut = random.Random(seed + 1)  # where batches end (``batches``)
    robots = [f"robot{k}" for k in range(6)]
    noise = {r: rng.choice((0.002, 0.005, 0.01, 0.08)) for r in robots}  # 0.08 m: beyond the gates at times
    bias = {r: 0.0 for r in robots} | {"robot4": 0.18}
    sizes = [rng.choice(((0.5, 0.4), (0.6, 0.6), (0.8, 0.5))) for _ in SPOTS]
    spots = list(SPOTS)
    clock = Clock()
    service = TwinService(imported(box_lab()), load_config(), clock=clock)
    service.start()
    replies: list[Reply] = []
    with confirmations_at_once(shortcut) as settled:
        for step in range(steps):
            clock.ns += 25_000_000
            robot = robots[0] if step < 2 else rng.choice(robots)
            if rng.random() < (0.03 if batches else 0.01):  # a table moved (short; with batches far too)
                k = rng.randrange(len(spots))
                far = batches and cut.random() < 0.5
                dx = cut.choice((0.55, -0.6, 0.65)) if far else rng.choice((0.25, -0.25))
                spots[k] = (spots[k][0] + dx, spots[k][1])
            reports = []
            for i, (x, y) in enumerate(spots):
                sx, sy = sizes[i]
                if robot == "robot2" and i == 3:
                    sx += 0.15  # other sizes, within the size gate: resize evidence
                yaw = rng.gauss(0, 0.01) + rng.choice((0.0, 0.0, 0.0, math.pi))  # a flipped heading
                if rng.random() < 0.5:
                    sx, sy, yaw = sy, sx, yaw + math.pi / 2  # the same box described turned by a quarter
                b = ObservedBox(
                    OX + x + bias[robot] + rng.gauss(0, noise[robot]),
                    OY + y + rng.gauss(0, noise[robot]),
                    0.375,
                    sx,
                    sy,
                    0.75,
                    yaw,
                )
                reports.append(ElementReport(f"urn:{robot}:t{i}", "IfcFurniture", "ground-floor", b))
            late = rng.random() < 0.15  # seen before the latest arrays: stale where they saw the tables
            sense = clock.ns - (90_000_000 if late else 10_000_000)
            view = ObservedView(
                "ground-floor", (ROOM_B,), ("IfcFurniture",), sense_ns=sense, origin=(OX + 10, OY + 2, 1.2)
            )
            service.submit_observation(robot, Observation(tuple(reports), view), replies.append)
            if not batches or cut.random() < 0.3:
                service.process()
        service.process()
    return [r.body for r in replies], service, settled.arrays


def test_the_confirmations_cache_is_emptied_once_it_outgrows_the_twin() -> None:
    memory = FusionMemory()
    cache = _cache(memory, 10)
    cache.held.update({f"urn:gone{i}": None for i in range(10 + CACHE_SLACK)})  # type: ignore[misc]
    assert _cache(memory, 10) is cache and len(cache.held) == 10 + CACHE_SLACK
    cache.held["urn:one-more"] = None  # type: ignore[assignment]
    assert not _cache(memory, 10).held


@pytest.mark.parametrize("seed", [3, 11])
def test_confirmations_at_once_decide_as_the_rules_do_on_random_fleets(seed: int) -> None:
    fast, a, settled = _fleet(seed, True, 260)
    slow, b, off = _fleet(seed, False, 260)
    assert off == 0
    assert 40 < settled < 250  # the shortcut was taken, and declined (a robot's noise, a move, other sizes)
    assert fast == slow
    assert any("stale" in r for r in fast) and any("resolved" in r for r in fast)
    ma, mb = a.live.fusion.to_json(), b.live.fusion.to_json()
    assert ma["tracks"] == mb["tracks"]
    assert ma == mb  # aliases, pairs (in their order), tentative, ...
    assert a.live.revision == b.live.revision
    assert_same_shapes(a, b)


@pytest.mark.parametrize("seed", [5, 8])
def test_confirmations_at_once_decide_as_the_rules_do_on_random_fleets_in_batches(seed: int) -> None:
    fast, a, settled = _fleet(seed, True, 260, batches=True)
    slow, b, off = _fleet(seed, False, 260, batches=True)
    assert off == 0
    assert 40 < settled < 250
    assert fast == slow
    assert sum("upserted" in r and bool(r["upserted"]) for r in fast) >= 3  # moves (and refinements) applied
    ma, mb = a.live.fusion.to_json(), b.live.fusion.to_json()
    assert ma == mb
    assert a.live.revision == b.live.revision
    assert_same_shapes(a, b)


def _pairs_by_every_comparison(
    memory: FusionMemory, robot: str, far: float, seen: list[tuple[str, float, float, int]]
) -> dict[tuple[str, str], RobotMean]:
    """The bias notes' pairs as a pass over every comparison leaves them (the rule as first written)."""
    last: dict[str, tuple[float, float, int]] = {}
    for iri, x, y, sense in seen:
        track = memory.tracks.get(iri)
        held = track.means if track is not None else {}
        mine = held.get(robot, RobotMean()).added(x, y, sense, weight=MEAN_WEIGHT)
        if mine.n < MEAN_MIN:
            continue
        for other, m in held.items():
            if other != robot and m.n >= MEAN_MIN and sense - m.last_ns <= RECENT_NS:
                dx, dy = mine.x - m.x, mine.y - m.y
                if not math.hypot(dx, dy) > far:
                    last[other] = (dx, dy, sense)
    pairs = {}
    for other, (dx, dy, sense) in last.items():
        there, back = memory.pairs.get((robot, other)), memory.pairs.get((other, robot))
        pairs[robot, other] = (there or RobotMean()).added(dx, dy, sense, weight=PAIR_WEIGHT)
        pairs[other, robot] = (back or RobotMean()).added(-dx, -dy, sense, weight=PAIR_WEIGHT)
    return pairs


def _memory(seed: int, robots: list[str], iris: list[str], now: int) -> FusionMemory:
    """Robots' means of the elements (some with few sightings, some long ago) and a few pairs."""
    rng = random.Random(seed)
    memory = FusionMemory()
    for iri in iris:
        track = memory.tracks[iri] = Track()
        for r in rng.sample(robots, rng.randrange(len(robots))):
            ago = rng.choice((0, 10**9, 2 * RECENT_NS))
            n = rng.randrange(1, 6) if r == robots[0] else rng.randrange(6)
            track.means[r] = RobotMean(n, rng.gauss(0, 0.3), rng.gauss(0, 0.3), now - ago)
    for a in robots[:3]:
        for b in robots[3:5]:
            memory.pairs[a, b] = RobotMean(3, 0.01, 0.0, now)
    return memory


@pytest.mark.parametrize("seed", [0, 1, 3, 4, 5, 6, 7])  # (in 2, no robot compares)
def test_bias_notes_leave_each_pair_as_a_pass_over_every_comparison(seed: int) -> None:
    service, _ = started()
    live, far = service.live, service.config.fusion.certain_move_m
    robots, iris, now = [f"r{k}" for k in range(8)], [f"urn:e{i}" for i in range(12)], 2 * 10**18
    rng = random.Random(100 + seed)
    seen = [(iri, rng.gauss(0, 0.3), rng.gauss(0, 0.3), now + k) for k, iri in enumerate(rng.sample(iris, 9))]
    live.fusion = memory = _memory(seed, robots, iris, now)
    ctx = FusionContext("r0", frozenset(), live, live.states, {}, service.config.fusion, "", {}, now)
    note_sightings_at(ctx, seen)
    assert len(ctx.out.effects) == 1
    ctx.out.effects[0](memory)
    reference = _memory(seed, robots, iris, now)
    pairs = _pairs_by_every_comparison(reference, "r0", far, seen)
    reference.pairs.update(pairs)
    assert pairs  # comparisons were made
    assert list(memory.pairs.items()) == list(reference.pairs.items())  # the same values, in the same order
    for iri, x, y, sense in seen:
        held = reference.tracks[iri].means.get("r0", RobotMean())
        assert memory.tracks[iri].means["r0"] == held.added(x, y, sense, weight=MEAN_WEIGHT)


def test_lies_within_is_the_polygon_test() -> None:
    rng = np.random.default_rng(5)
    inside = 0
    for _ in range(6000):
        sizes = sorted(rng.uniform(0.2, 2.0, 2), reverse=True)
        held = Pose(0.0, 0.0, 0.4, *sizes, 0.8, rng.uniform(0, math.pi))
        margin = float(rng.choice((0.0, 0.1, 0.3)))
        reach = math.hypot(sizes[0] / 2 + margin, sizes[1] / 2 + margin)
        if rng.random() < 0.5:  # anywhere around it
            r, turn = reach * math.sqrt(rng.uniform(0.3, 1.4)), rng.uniform(0, 2 * math.pi)
            x, y = r * math.cos(turn), r * math.sin(turn)
            sx, sy = sorted(rng.uniform(0.01, 0.5, 2), reverse=True)
        else:  # a small box in a corner of the grown footprint, where its centre is farthest
            x, y = corners(held, inset=-margin)[rng.integers(4)] * rng.uniform(0.9, 1.01)
            sx, sy = sorted(rng.uniform(0.002, 0.05, 2), reverse=True)
        seen = Pose(float(x), float(y), 0.4, sx, sy, 0.8, rng.uniform(0, math.pi))
        polygon = bool(points_in_polygon(corners(seen), corners(held, inset=-margin)).all())
        assert lies_within(seen, held, margin_m=margin) == polygon
        inside += polygon
    assert 300 < inside < 5700  # both answers came often


def test_a_robots_partners_are_its_pairs_after_any_change() -> None:
    rng = random.Random(4)
    robots = [f"r{k}" for k in range(6)]
    memory = FusionMemory()
    plain: dict[tuple[str, str], RobotMean] = {}

    def check() -> None:
        assert dict(memory.pairs) == plain
        for robot in robots:
            mine = [(b, d) for (a, b), d in memory.pairs.items() if a == robot]
            assert memory.pairs.partners(robot) == mine
        again = memory_from_json(memory.to_json()).pairs
        assert isinstance(again, PairTable)
        assert all(again.partners(r) == memory.pairs.partners(r) for r in robots)
        for (a, b), d in memory.pairs.items():  # the same objects: a mean changed in place is both
            partners = memory.pairs.of(a)
            assert partners is not None and partners[b] is d

    for step in range(400):
        a, b = rng.sample(robots, 2)
        value = RobotMean(step, rng.random(), rng.random(), step)
        what = rng.random()
        if what < 0.5:
            memory.pairs[a, b] = plain[a, b] = value
        elif what < 0.7:
            memory.pairs.update({(a, b): value, (b, a): value})
            plain.update({(a, b): value, (b, a): value})
        elif what < 0.85:
            assert memory.pairs.pop((a, b), None) == plain.pop((a, b), None)
        else:  # journaled, then undone
            memory.begin()
            memory.changing("pairs", (a, b))
            memory.pairs[a, b] = value
            memory.undo()
        check()


@pytest.mark.parametrize("keep", [False, True])
def test_bias_notes_while_journaled_are_undone_or_kept_as_without_a_journal(keep: bool) -> None:
    service, _ = started()
    live = service.live
    robots, iris, now = [f"r{k}" for k in range(8)], [f"urn:e{i}" for i in range(12)], 2 * 10**18
    seen = [(iri, 0.01 * k, -0.01 * k, now + k) for k, iri in enumerate(iris[:9])]

    def noted(journal: bool) -> FusionMemory:
        live.fusion = memory = _memory(3, robots, iris, now)
        ctx = FusionContext("r0", frozenset(), live, live.states, {}, service.config.fusion, "", {}, now)
        note_sightings_at(ctx, seen)
        if journal:
            memory.begin()
        ctx.out.effects[0](memory)
        if journal:
            memory.keep() if keep else memory.undo()
        return memory

    plain, journaled = noted(False), noted(True)
    before = _memory(3, robots, iris, now).to_json()
    assert plain.to_json() != before  # the notes changed means and pairs
    assert journaled.to_json() == (plain.to_json() if keep else before)
    assert list(journaled.pairs.items()) == list(
        (plain if keep else _memory(3, robots, iris, now)).pairs.items()
    )


def _held_row(rules: FusionRules, pose: Pose, *, resizes: bool) -> _Held:
    c = rules.default
    row = (pose.cx, pose.cy, pose.cz, pose.sx, pose.sy, pose.sz, pose.yaw)
    gates = (c.confirm_distance_m, c.confirm_angle_rad, c.size_ratio, c.min_area_ratio)
    return _Held(None, None, None, pose, None, None, rules, True, True, resizes, row, gates)  # type: ignore[arg-type]


@pytest.mark.parametrize(("height", "jump"), [(0.75, 2.0), (0.75, 0.1), (0.2, 2.0)])
def test_an_arrays_alias_check_before_the_gates_decides_as_the_whole_check(
    height: float, jump: float
) -> None:
    rules = FusionRules(alias_jump_m=jump)
    rng = np.random.default_rng(int(height * 100 + jump * 10))
    outcomes = {True: 0, False: 0}
    relied = 0  # the whole check failed on the centre or the heights, the gates then failed too
    for _ in range(400):
        n = 12
        held = [
            Pose(x, y, height / 2, 0.6, 0.4, height, yaw)
            for x, y, yaw in rng.uniform((0, 0, 0), (10, 10, math.pi), (n, 3)).tolist()
        ]
        helds = [_held_row(rules, p, resizes=bool(rng.random() < 0.7)) for p in held]
        aliased = sorted(rng.choice(n, int(rng.integers(1, n + 1)), replace=False).tolist())
        layout = _layout(_cache(FusionMemory(), n), "r", helds, aliased)
        boxes = layout.held + rng.normal(0, 0.005, (n, 7))
        for i in rng.choice(n, int(rng.integers(0, 3)), replace=False):  # a few boxes off, one way each
            way = int(rng.integers(6))
            if way < 2:  # the centre 3 m off (beyond the jump) or 0.3 m (beyond the gates)
                boxes[i, 0] += (3.0, 0.3)[way] * rng.choice((-1, 1))
            elif way == 2:  # the height
                boxes[i, 2] += rng.choice((0.2, 0.5, 1.0))
            elif way == 3:  # other sizes, or a smaller area
                boxes[i, 3] *= rng.choice((1.2, 1.5, 2.0))
            elif way == 4:
                boxes[i, 5] *= rng.choice((0.3, 0.8))
            else:  # the same box described turned by a quarter
                boxes[i, [3, 4]] = boxes[i, [4, 3]]
                boxes[i, 6] += math.pi / 2
        pose = _canonical(boxes)
        refs = np.hstack((np.full((n, 1), 1e6), 1e6 * layout.held))  # means at the held poses
        gates = _gates_at_once(pose, refs, layout) is not None
        first = SimpleNamespace(targets=[""] * n, refs=np.zeros((n, 8)), pose=pose, layout=layout)
        assert gates == (_gates(SimpleNamespace(rules=rules), first, np.arange(n)) is not None)  # type: ignore[arg-type]
        rows = pose if len(aliased) == n else pose[aliased]
        whole = _aliases_fit(rows, layout, jump) and gates
        fast = _aliases_fit(rows, layout, jump, gated=True) and gates
        assert fast == whole
        outcomes[whole] += 1
        relied += _aliases_fit(rows, layout, jump, gated=True) and not _aliases_fit(rows, layout, jump)
    assert outcomes[True] > 20 and outcomes[False] > 20
    assert relied > 0 if (height, jump) == (0.75, 2.0) else relied == 0  # only where the gates imply them
