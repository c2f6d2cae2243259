"""Detector bias: where each robot's detector puts objects against where the other robots put them.

Two robots whose detectors differ by 20 cm (a calibration offset) would move a still desk back and forth
as they pass it in turns, and whichever moved it last leaves free cells where the desk stands. Each
robot's mean position of an element (a moving mean of its raw boxes since the element's last move) is
compared with the median of the means of every robot that saw the element within :data:`RECENT_NS`
(at least :data:`MIN_ROBOTS` robots: the majority is the reference; two alone cannot tell which one
is off); the difference, averaged slowly over every element robots see together, is the robot's
**bias**. Once it rests on :data:`BIAS_MIN_SAMPLES` comparisons and exceeds :data:`DEADBAND_M`, the
robot's boxes are shifted by it before anything else looks at them: one robot 20 cm off among others
that agree is corrected by 20 cm, the others by none.

Example::

    pose = unbiased(ctx, pose)                     # a robot's box as the others would see it
    note_sighting(ctx, state, raw_pose, sense_ns)  # its means and bias, updated once accepted
"""

from __future__ import annotations

import math
import statistics
from dataclasses import replace
from typing import TYPE_CHECKING

from twin.fusion.footprints import Pose
from twin.fusion.memory import FusionMemory, RobotMean

if TYPE_CHECKING:
    from twin.fusion.context import FusionContext
    from twin.live.state import ElementState

MEAN_WEIGHT = 0.2
"""The weight of a new sighting in a robot's mean of an element (after the first five, a plain mean)."""
BIAS_WEIGHT = 0.02
"""The weight of a new comparison in a robot's bias (after the first 50)."""
MEAN_MIN = 3
"""Sightings in a robot's mean of an element before it is compared."""
BIAS_MIN_SAMPLES = 10
"""Comparisons before a robot's bias corrects its boxes."""
MIN_ROBOTS = 3
"""Robots whose means of an element are compared, at least (two alone cannot tell which one is off)."""
DEADBAND_M = 0.05
"""A bias this small is the detectors' noise, not a calibration error: not applied."""
RECENT_NS = 60 * 10**9
"""Other robots' means of an element count when their last sighting is at most this old (a move of
the element starts its means again)."""


def applied_bias(memory: FusionMemory, robot: str) -> tuple[float, float] | None:
    """The bias a robot's boxes are corrected by, once known (None: none)."""
    b = memory.biases.get(robot)
    if b is None or b.n < BIAS_MIN_SAMPLES or math.hypot(b.x, b.y) <= DEADBAND_M:
        return None
    return b.x, b.y


def unbiased(ctx: FusionContext, pose: Pose) -> Pose:
    """``pose`` shifted by the robot's detector bias, once that is known."""
    b = applied_bias(ctx.memory, ctx.robot)
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
    bias = None
    if mine.n >= MEAN_MIN and len(others) + 1 >= MIN_ROBOTS:
        everyone = [mine, *(m for _, m in others)]
        dx = mine.x - statistics.median(m.x for m in everyone)
        dy = mine.y - statistics.median(m.y for m in everyone)
        if math.hypot(dx, dy) <= ctx.rules.certain_move_m:  # not a move the others have not seen yet
            bias = memory.biases.get(robot, RobotMean()).added(dx, dy, sense, weight=BIAS_WEIGHT)

    def run(m: FusionMemory) -> None:
        m.track(iri).means[robot] = mine
        if bias is not None:
            m.biases[robot] = bias

    ctx.out.effects.append(run)


def detector_biases(memory: FusionMemory) -> dict[str, list[float]]:
    """Each robot's detector bias (x, y, metres) once known (``twin status``)."""
    out = {}
    for robot in sorted(list(memory.biases)):
        b = applied_bias(memory, robot)
        if b is not None:
            out[robot] = [round(b[0], 3), round(b[1], 3)]
    return out
