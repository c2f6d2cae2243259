"""The per-storey index of the poses of the elements fusion may match (dynamic, not zones).

Association, merge and absence look up the elements of one storey many times a second; the index
holds, per storey, each candidate element's :class:`~twin.fusion.footprints.Pose`. The writer keeps it
current after each commit (:func:`index_element`).

Example::

    build_poses(live)                        # at start-up, before the daemon serves
    storey_poses(live, "ground-floor")       # element -> pose
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from twin.fusion.footprints import Pose
from twin.fusion.gates import is_candidate
from twin.fusion.memory import FusionMemory, PastPose
from twin.records import FloatArray

if TYPE_CHECKING:
    from twin.live.state import ElementState, LiveState

STOREY_TOLERANCE_M = 0.3
"""An element contained in a space (not a storey) stands on the highest storey whose elevation is at
most this far above its lowest point."""


def storey_at(live: LiveState, z: float) -> str | None:
    """The storey an element whose lowest point is at world ``z`` stands on."""
    best: tuple[float, str] | None = None
    for key, s in live.site.storeys.items():
        if s.elevation_m <= z + STOREY_TOLERANCE_M and (best is None or s.elevation_m > best[0]):
            best = (s.elevation_m, key)
    return None if best is None else best[1]


@dataclass(frozen=True, slots=True)
class StoreyArrays:
    """One storey's indexed poses as arrays, in the index's order: to pick the few near a view at once."""

    iris: tuple[str, ...]
    poses: tuple[Pose, ...]
    cx: FloatArray
    cy: FloatArray
    reach: FloatArray
    """Half the sum of each footprint's sizes (at least half its diagonal)."""

    def near(self, lo: FloatArray, hi: FloatArray) -> npt.NDArray[np.intp]:
        """Indices of the poses whose centre lies within their ``reach`` of the box ``lo``..``hi``."""
        r = self.reach
        ok = (lo[0] - r <= self.cx) & (self.cx <= hi[0] + r) & (lo[1] - r <= self.cy) & (self.cy <= hi[1] + r)
        found: npt.NDArray[np.intp] = ok.nonzero()[0]  # (np.flatnonzero of a 1-d mask, without the wrapper)
        return found


def storey_arrays(live: LiveState, storey: str) -> StoreyArrays:
    """:func:`storey_poses` as arrays (cached until the storey's poses change)."""
    poses = storey_poses(live, storey)
    cached = live.fusion.pose_arrays.get(storey)
    if isinstance(cached, StoreyArrays) and len(cached.iris) == len(poses):
        return cached
    held = tuple(poses.values())
    arrays = StoreyArrays(
        tuple(poses),
        held,
        np.array([p.cx for p in held], dtype=np.float64),
        np.array([p.cy for p in held], dtype=np.float64),
        np.array([(p.sx + p.sy) / 2 for p in held], dtype=np.float64),
    )
    live.fusion.pose_arrays[storey] = arrays
    return arrays


def build_poses(live: LiveState) -> None:
    """Index the pose of every candidate element, per storey (start-up code calls it once)."""
    live.fusion.poses = {}
    live.fusion.pose_arrays.clear()
    for iri, state in live.states.items():
        index_element(live, iri, state)


def storey_poses(live: LiveState, storey: str) -> dict[str, Pose]:
    """Element -> pose of the candidate elements on ``storey`` (built here if start-up did not)."""
    if live.fusion.poses is None:
        build_poses(live)
    assert live.fusion.poses is not None
    return live.fusion.poses.get(storey, {})


def index_element(live: LiveState, iri: str, state: ElementState | None) -> None:
    """Keep the per-storey poses of candidate elements current after ``iri`` changed."""
    memory = live.fusion
    if memory.poses is None:
        return  # built on first use
    before = [(storey, poses.pop(iri)) for storey, poses in memory.poses.items() if iri in poses]
    for old, _ in before:
        memory.pose_arrays.pop(old, None)
    if state is None or not is_candidate(state):
        _remember(memory, iri, before, None, state)
        memory.shape_poses.pop(iri, None)  # a removed element's shape is gone: no pose cached for it
        return
    shape = live.maps.shape_of(iri)
    if shape is None:
        memory.shape_poses.pop(iri, None)
        return
    pose = memory.pose(iri, shape)
    storey = state.storey or storey_at(live, pose.zmin)
    _remember(memory, iri, before, pose, state)
    if storey is not None:
        memory.poses.setdefault(storey, {})[iri] = pose
        memory.pose_arrays.pop(storey, None)


def _remember(
    memory: FusionMemory,
    iri: str,
    before: list[tuple[str, Pose]],
    now: Pose | None,
    state: ElementState | None,
) -> None:
    """Keep where ``iri`` stood before a change that moved or removed it (late news is checked against
    it: :mod:`twin.fusion.history`)."""
    for storey, pose in before:
        if pose != now:
            memory.remember(iri, PastPose(storey, pose, state.sensed_ns if state is not None else 0))
