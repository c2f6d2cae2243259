"""Detector bias: where each robot's detector puts objects against where the other robots put them.

Two robots whose detectors differ by 20 cm (a calibration offset) would move a still desk back and forth
as they pass it in turns, and whichever moved it last leaves free cells where the desk stands. Each
robot's mean sighting position of an element (a moving mean of its raw boxes since the element's last
move) is compared with the median of the recent means of every robot that sees it; the difference,
averaged slowly over every element several robots see, is the robot's **bias**. Once it rests on
:data:`BIAS_MIN_SAMPLES` comparisons, the robot's boxes are shifted by it before anything else looks at
them. The median makes the majority the reference: one biased robot among three or more carries its
whole bias, the others none; with two robots only, each carries half of their difference (the twin
cannot tell which is right, and takes the middle).

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
BIAS_MIN_SAMPLES = 20
"""Comparisons before a robot's bias corrects its boxes."""
RECENT_NS = 10 * 10**9
"""Other robots' means count when their last sighting is at most this old."""


def unbiased(ctx: FusionContext, pose: Pose) -> Pose:
    """``pose`` shifted by the robot's detector bias, once that is known."""
    b = ctx.memory.biases.get(ctx.robot)
    if b is None or b.n < BIAS_MIN_SAMPLES:
        return pose
    return replace(pose, cx=pose.cx - b.x, cy=pose.cy - b.y)


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
    if mine.n >= MEAN_MIN and others:
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
    return {
        robot: [round(b.x, 3), round(b.y, 3)]
        for robot, b in sorted(list(memory.biases.items()))
        if b.n >= BIAS_MIN_SAMPLES
    }
