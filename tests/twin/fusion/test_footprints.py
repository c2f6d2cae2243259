"""Footprints: the convex hull (shapely's, with the monotone chain for degenerate cases); a box's pose in
Python floats, its box test remembered while it moves."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from twin.fusion.footprints import (
    Pose,
    _is_box_mesh,
    _monotone_chain,
    _pose,
    box_pose,
    box_sizes,
    convex_hull,
    min_area_rectangle,
    placed_pose,
    pose_of,
)
from twin.fusion.memory import FusionMemory
from twin.maps.shapes import box_mesh, box_placement
from twin.records import Mesh


def test_the_hull_is_the_monotone_chains_counter_clockwise_and_degenerate_points_still_give_one() -> None:
    rng = np.random.default_rng(5)
    for _ in range(50):
        pts = rng.normal(0, 1, (rng.integers(3, 400), 2))
        hull = convex_hull(pts)
        chain = _monotone_chain(np.unique(np.round(pts, 9), axis=0))
        assert sorted(map(tuple, np.round(hull, 9))) == sorted(map(tuple, np.round(chain, 9)))
        x, y = hull[:, 0], hull[:, 1]
        assert 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)) > 0  # counter-clockwise
    line = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]])
    assert len(convex_hull(line)) == 2
    cx, cy, sx, sy, _ = min_area_rectangle(np.array([[0, 0], [2, 0], [2, 1], [0, 1], [1, 0.5]], dtype=float))
    assert (round(cx, 6), round(cy, 6), round(sx, 6), round(sy, 6)) == (1.0, 0.5, 2.0, 1.0)


def _numpy_box_pose(mesh: Mesh, placement: np.ndarray) -> Pose | None:
    """The box path as it was, in numpy (the reference of the float path)."""
    sizes = _is_box_mesh(mesh.vertices)
    if sizes is None or abs(placement[2, 0]) >= 1e-9 or abs(placement[2, 1]) >= 1e-9:
        return None
    scale = np.linalg.norm(placement[:3, :3], axis=0)
    cx, cy, cz = (float(v) for v in placement[:3, 3])
    sx, sy, sz = (float(v) for v in sizes * scale)
    return box_pose(cx, cy, cz, sx, sy, sz, yaw=math.atan2(placement[1, 0], placement[0, 0]))


def test_a_box_pose_in_floats_is_the_numpy_pose_bit_for_bit_with_its_sizes_given_or_tested() -> None:
    rng = np.random.default_rng(42)
    for k in range(3000):
        mesh = box_mesh(*(float(v) for v in rng.uniform(0.01, 5.0, 3)))
        centre = (float(v) for v in rng.uniform(-300, 300, 3))
        placement = box_placement(*centre, yaw=float(rng.uniform(-7, 7)))
        if k % 3 == 0:  # scaled, as an imported placement may be
            placement[:3, :3] = placement[:3, :3] @ np.diag(rng.uniform(0.1, 3.0, 3))
        if k % 7 == 0:
            placement[2, 0] = float(rng.choice([1e-10, 1e-8, -1e-10]))  # tilted a little, or not enough
        expected = _numpy_box_pose(mesh, placement)
        if expected is None:
            continue
        assert pose_of((mesh, placement)) == expected
        assert placed_pose((mesh, placement), box_sizes(mesh.vertices)) == expected


def test_the_memory_tests_a_moving_mesh_once_and_gives_the_pose_of_its_new_placement() -> None:
    memory = FusionMemory()
    mesh, not_a_box = box_mesh(1.2, 0.8, 0.75), Mesh(np.zeros((3, 3)), np.array([[0, 1, 2]], np.int32), False)
    first = memory.pose("e", (mesh, box_placement(1.0, 2.0, 0.375)))
    assert memory.shape_poses["e"][3] == (1.2, 0.8, 0.75)
    moved = box_placement(3.0, 2.5, 0.375, yaw=0.4)
    assert memory.pose("e", (mesh, moved)) == pose_of((mesh, moved)) != first
    assert memory.pose("e", (not_a_box, moved)) == pose_of((not_a_box, moved))  # a new mesh: tested again
    assert memory.shape_poses["e"][3] is None


def test_a_pose_made_through_its_slots_is_the_frozen_record_its_constructor_makes() -> None:
    made, built = _pose(1.0, 2.0, 0.375, 0.8, 0.6, 0.75, 3.0), Pose(1.0, 2.0, 0.375, 0.8, 0.6, 0.75, 3.0)
    assert made == built and hash(made) == hash(built) and repr(made) == repr(built)
    with pytest.raises(dataclasses.FrozenInstanceError):
        made.cx = 2.0  # type: ignore[misc]
    assert type(box_pose(1.0, 2.0, 0.375, 0.6, 0.8, 0.75, yaw=3.1)) is Pose
