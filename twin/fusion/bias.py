"""Detector bias: where each robot's detector puts objects against where the other robots put them.

Two robots whose detectors differ by 20 cm (a calibration offset) would move a still desk back and forth
as they pass it in turns, and whichever moved it last leaves free cells where the desk stands. Each
robot's mean position of an element (a moving mean of its raw boxes since the element's last move) is
compared with each other robot's recent mean of it: per pair of robots, the mean difference over the
elements both see. A robot that differs by more than :data:`DEADBAND_M` from most of its partners (at
least :data:`MIN_PARTNERS`, each with :data:`PAIR_MIN_SAMPLES` comparisons) is off: its **bias** is the
median of those differences, and its boxes are shifted by it before anything else looks at them. A robot
20 cm off differs from every partner; each of its partners differs from it and from no one else, so
only the biased one is corrected. A robot that agrees with no partner and differs from one that agrees
with a third robot is off too (the two that agree vouch for each other): a biased robot is corrected as
soon as it shares elements with one vouched partner. Two robots alone never correct each other (they
cannot tell which one is off).

Example::

    pose = unbiased(ctx, pose)                     # a robot's box as the others would see it
    note_sighting(ctx, state, raw_pose, sense_ns)  # its means and pair differences, once accepted
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

from twin.fusion.footprints import Pose
from twin.fusion.memory import FusionMemory, RobotMean

if TYPE_CHECKING:
    from twin.fusion.context import FusionContext
    from twin.live.state import ElementState

MEAN_WEIGHT = 0.2
"""The weight of a new sighting in a robot's mean of an element (after the first five, a plain mean)."""
PAIR_WEIGHT = 0.05
"""The weight of a new comparison in a pair's mean difference (after the first 20)."""
MEAN_MIN = 3
"""Sightings in a robot's mean of an element before it is compared."""
PAIR_MIN_SAMPLES = 5
"""Comparisons before a pair's difference counts."""
MIN_PARTNERS = 2
"""Partners a robot's bias needs (with one, the twin cannot tell which of the two is off)."""
DEADBAND_M = 0.05
"""A bias this small is the detectors' noise, not a calibration error: not applied."""
RECENT_NS = 60 * 10**9
"""Other robots' means of an element count when their last sighting is at most this old (a move of
the element starts its means again)."""


_MEAN_PLAIN = round(1 / MEAN_WEIGHT) + 1
_PAIR_PLAIN = round(1 / PAIR_WEIGHT) + 1
"""From this many values on, a mean's weight is :data:`MEAN_WEIGHT` (:data:`PAIR_WEIGHT`): 1 / (n + 1) is
smaller (what :meth:`~twin.fusion.memory.RobotMean.added`'s ``max`` gives, without the call)."""

_NO_MEAN = RobotMean()
"""No sightings yet (only read: :meth:`~twin.fusion.memory.RobotMean.added` makes a new mean)."""
_NO_MEANS: dict[str, RobotMean] = {}
"""An element without a track: no robot's mean (only read)."""


def applied_bias(memory: FusionMemory, robot: str) -> tuple[float, float] | None:
    """The bias a robot's boxes are corrected by (None: none): the median of its differences with its
    partners, when it differs by more than :data:`DEADBAND_M` from most of them (at least
    :data:`MIN_PARTNERS`), or, when it agrees with none, from the partners that agree with a third robot
    (:func:`vouched`). A robot that agrees with some partners and differs from one is not the one that
    is off."""
    mine = memory.pairs.of(robot)
    if not mine:
        return None
    diffs = 0  # partners with enough comparisons, and those of them it differs from
    differing: list[tuple[str, RobotMean]] = []
    for b, d in mine.items():
        if d.n >= PAIR_MIN_SAMPLES:
            diffs += 1
            if math.hypot(d.x, d.y) > DEADBAND_M:
                differing.append((b, d))
    if len(differing) >= MIN_PARTNERS and 2 * len(differing) > diffs:
        chosen = [d for _, d in differing]
    elif differing and len(differing) == diffs:
        pairs = list(memory.pairs.items())
        chosen = [d for b, d in differing if vouched(pairs, b, robot)]
        if not chosen:
            return None
    else:
        return None
    return statistics.median(d.x for d in chosen), statistics.median(d.y for d in chosen)


def vouched(pairs: list[tuple[tuple[str, str], RobotMean]], robot: str, but: str) -> bool:
    """Whether ``robot`` agrees (within :data:`DEADBAND_M`, over :data:`PAIR_MIN_SAMPLES` comparisons)
    with a robot other than ``but``: two detectors that agree are both right, or both off by the same
    offset (far less likely than one robot off). A robot that agrees with nobody and differs from such a
    partner is the one that is off, even while it has only one partner on the elements it sees now."""
    return any(
        a == robot and b != but and d.n >= PAIR_MIN_SAMPLES and math.hypot(d.x, d.y) <= DEADBAND_M
        for (a, b), d in pairs
    )


def unbiased(ctx: FusionContext, pose: Pose) -> Pose:
    """``pose`` shifted by the robot's detector bias, once that is known."""
    if not ctx.bias_known:  # the memory changes only once the observation is accepted
        ctx.bias, ctx.bias_known = applied_bias(ctx.memory, ctx.robot), True
    b = ctx.bias
    if b is None:
        return pose
    return replace(pose, cx=pose.cx - b[0], cy=pose.cy - b[1])


def note_sighting(ctx: FusionContext, state: ElementState, raw: Pose, sense: int) -> None:
    """Count a sighting (uncorrected) in the robot's mean of the element and, against the other robots'
    recent means of it, in the robot's bias (effects, applied once the observation is accepted)."""
    robot, iri, memory = ctx.robot, state.iri, ctx.memory
    track = memory.tracks.get(iri)
    means = track.means if track is not None else {}
    mine = means.get(robot, RobotMean()).added(raw.cx, raw.cy, sense, weight=MEAN_WEIGHT)
    others = [
        (r, m) for r, m in means.items() if r != robot and m.n >= MEAN_MIN and sense - m.last_ns <= RECENT_NS
    ]
    pairs = {}
    if mine.n >= MEAN_MIN:
        for other, m in others:
            dx, dy = mine.x - m.x, mine.y - m.y
            if math.hypot(dx, dy) > ctx.rules.certain_move_m:
                continue  # a move the other has not seen yet
            pairs[robot, other] = memory.pairs.get((robot, other), RobotMean()).added(
                dx, dy, sense, weight=PAIR_WEIGHT
            )
            pairs[other, robot] = memory.pairs.get((other, robot), RobotMean()).added(
                -dx, -dy, sense, weight=PAIR_WEIGHT
            )

    def run(m: FusionMemory) -> None:
        m.track(iri).means[robot] = mine
        for pair in pairs:
            m.changing("pairs", pair)
        m.pairs.update(pairs)

    ctx.out.effects.append(run)


def note_sightings(ctx: FusionContext, seen: Sequence[tuple[ElementState, Pose, int]]) -> None:
    """:func:`note_sighting` of each (state, raw pose, sense time) in ``seen`` (distinct elements), in
    order, as one effect with the same result: each element's mean, and each pair's difference as the
    last sighting that compares the pair leaves it (every comparison starts from the memory as it was,
    and a later one replaces an earlier), made once per pair instead of once per sighting."""
    note_sightings_at(ctx, [(state.iri, raw.cx, raw.cy, sense) for state, raw, sense in seen])


MeanUpdate = tuple[str, RobotMean | None, int, float, float, int]
"""(element, the robot's mean the memory held when noted (None: none), its new n, x, y, last_ns)."""
PairUpdate = tuple[str, float, float, int]
"""(other robot, the difference x, y, sense time): a comparison that updates both of the pair's means."""


def note_sightings_at(ctx: FusionContext, seen: Sequence[tuple[str, float, float, int]]) -> None:
    """:func:`note_sightings` of (element, raw x, raw y, sense time) tuples. Each pair's difference is
    taken from the last sighting that compares it, found from the end (each robot's search stops at its
    first comparison; the pairs in the order the first comparisons came, as in a forward pass). The
    effect updates the means and pairs the memory holds in place (no new objects per robot pair and
    array), but for pairs while the memory journals (its value before is kept, not a copy)."""
    robot = ctx.robot
    means, diffs = sightings_noted(ctx, seen)

    def run(m: FusionMemory) -> None:
        journaled, tracks = m.journal is not None, m.tracks
        for iri, old, n, mx, my, last in means:
            t = m.track(iri) if journaled else tracks.get(iri)  # (journaled: a copy of the track is kept)
            set_mean((t if t is not None else m.track(iri)).means, robot, old, n, mx, my, last)
        update_pairs(m, robot, diffs)

    ctx.out.effects.append(run)


def set_mean(  # noqa: PLR0917 (a MeanUpdate)
    held: dict[str, RobotMean], robot: str, old: RobotMean | None, n: int, x: float, y: float, last_ns: int
) -> None:
    """The robot's mean in ``held`` (a track's means) as noted: ``old`` changed in place while held."""
    mean = held.get(robot)
    if mean is not None and mean is old:
        mean.n, mean.x, mean.y, mean.last_ns = n, x, y, last_ns
    else:
        held[robot] = RobotMean(n, x, y, last_ns)


def sightings_noted(
    ctx: FusionContext, seen: Sequence[tuple[str, float, float, int]]
) -> tuple[list[MeanUpdate], list[PairUpdate]]:
    """What :func:`note_sightings_at` applies: each element's new mean, each pair's comparison (in
    order); :func:`set_mean` and :func:`update_pairs` apply them, once the observation is accepted."""
    robot, memory = ctx.robot, ctx.memory
    far = ctx.rules.certain_move_m
    means: list[MeanUpdate] = []
    compared: list[tuple[float, float, dict[str, RobotMean], int]] = []  # my mean (x, y), the others', sense
    tracks = memory.tracks
    for iri, x, y, sense in seen:
        track = tracks.get(iri)
        held = track.means if track is not None else _NO_MEANS
        old = held.get(robot)
        o = _NO_MEAN if old is None else old  # (RobotMean.added, without the new object)
        k = o.n
        a = MEAN_WEIGHT if k >= _MEAN_PLAIN else 1.0 if k == 0 else max(MEAN_WEIGHT, 1.0 / (k + 1))
        last = o.last_ns if o.last_ns > sense else sense
        n, mx, my = k + 1, o.x + a * (x - o.x), o.y + a * (y - o.y)
        means.append((iri, old, n, mx, my, last))
        if n >= MEAN_MIN and len(held) > (old is not None):
            compared.append((mx, my, held, sense))

    everyone = set().union(*(held for _, _, held, _ in compared)) - {robot}
    order: dict[str, None] = {}  # the first comparison of each robot, in order
    for mx, my, held, sense in compared:
        for other, m in held.items():
            if (
                other not in order
                and other != robot
                and m.n >= MEAN_MIN
                and sense - m.last_ns <= RECENT_NS
                and not math.hypot(mx - m.x, my - m.y) > far  # farther: a move not seen yet
            ):
                order[other] = None
        if len(order) == len(everyone):
            break
    last_of: dict[str, tuple[float, float, int]] = {}
    for mx, my, held, sense in reversed(compared):
        for other, m in held.items():
            if other in last_of or other == robot or m.n < MEAN_MIN or sense - m.last_ns > RECENT_NS:
                continue
            dx, dy = mx - m.x, my - m.y
            if not math.hypot(dx, dy) > far:
                last_of[other] = (dx, dy, sense)
        if len(last_of) == len(order):
            break
    return means, [(other, *last_of[other]) for other in order]


def update_pairs(m: FusionMemory, robot: str, diffs: list[PairUpdate]) -> None:
    """Each comparison in ``diffs`` added to the robot's pair with the other (both ways), in order: in
    place, or new values while the memory journals."""
    pairs, journaled = m.pairs, m.journal is not None
    if not journaled:  # RobotMean.added of each pair, in place
        mine = pairs.of(robot) or {}
        for other, dx, dy, sense in diffs:
            d = mine.get(other)
            if d is None:
                pairs[robot, other] = d = RobotMean()
                mine = pairs.of(robot) or {}
            k = d.n
            a = PAIR_WEIGHT if k >= _PAIR_PLAIN else 1.0 if k == 0 else max(PAIR_WEIGHT, 1.0 / (k + 1))
            d.n, d.x, d.y = k + 1, d.x + a * (dx - d.x), d.y + a * (dy - d.y)
            if sense > d.last_ns:  # noqa: PLR1730 (max is a call: 48 pairs an array with 25 robots)
                d.last_ns = sense
            theirs = pairs.of(other)
            d = None if theirs is None else theirs.get(robot)
            if d is None:
                pairs[other, robot] = d = RobotMean()
            k = d.n
            a = PAIR_WEIGHT if k >= _PAIR_PLAIN else 1.0 if k == 0 else max(PAIR_WEIGHT, 1.0 / (k + 1))
            d.n, d.x, d.y = k + 1, d.x + a * (-dx - d.x), d.y + a * (-dy - d.y)
            if sense > d.last_ns:  # noqa: PLR1730
                d.last_ns = sense
        return
    for other, dx, dy, sense in diffs:  # new values: the journal keeps the old ones
        there, back = pairs.get((robot, other)) or _NO_MEAN, pairs.get((other, robot)) or _NO_MEAN
        m.changing("pairs", (robot, other))
        pairs[robot, other] = there.added(dx, dy, sense, weight=PAIR_WEIGHT)
        m.changing("pairs", (other, robot))
        pairs[other, robot] = back.added(-dx, -dy, sense, weight=PAIR_WEIGHT)


def detector_biases(memory: FusionMemory) -> dict[str, list[float]]:
    """Each robot's detector bias (x, y, metres) once known (``twin status``)."""
    out = {}
    for robot in sorted({a for a, _ in list(memory.pairs)}):
        b = applied_bias(memory, robot)
        if b is not None:
            out[robot] = [round(b[0], 3), round(b[1], 3)]
    return out
