"""``benchmarks/fleet_sim.py``'s sampler counts a ghost as *viewed* (fusion should have removed it) only
once views held it as the daemon's absence rule asks: its whole footprint, 0.1 m inside its edges, in a
view, ``misses_to_remove`` times over ``miss_span_s``, since it became a ghost, ``GHOST_VIEWED_S`` ago.
On the lab its old test (the centre in any view 10 s to 60 s old, even one from before the object left)
counted 70 samples of ghosts the rules could not yet have removed."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from twin.fusion.footprints import box_pose

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import fleet_sim  # benchmarks/ is not a package

DESK = box_pose(5.0, 5.0, 0.4, 1.2, 0.6, 0.8, yaw=0.0)  # x 4.4..5.6, y 4.7..5.3


def square(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


def empty_world() -> fleet_sim.World:
    grid = np.zeros((10, 10), dtype=bool)
    return fleet_sim.World(grid, grid, (0.0, 0.0), 1.0, 0.0)


def test_a_view_that_holds_a_ghosts_centre_but_not_its_whole_inset_footprint_is_no_miss() -> None:
    half = square(4.0, 4.0, 5.2, 6.0)  # the centre, not the east end
    whole = square(4.0, 4.0, 6.0, 6.0)
    inset_only = square(4.45, 4.75, 5.55, 5.25)  # the footprint 0.1 m inside its edges, and a little more
    assert fleet_sim.views_holding(DESK, [(1.0, half), (2.0, whole), (3.0, inset_only)]) == [2.0, 3.0]


def test_the_rules_remove_after_three_misses_spread_over_a_second_and_not_before() -> None:
    assert fleet_sim.removable_at([10.0, 10.2, 10.4], 3, 1.0) is None
    assert fleet_sim.removable_at([10.0, 10.2, 10.4, 11.1], 3, 1.0) == 11.1
    assert fleet_sim.removable_at([11.1, 10.0, 10.5], 3, 1.0) == 11.1  # threads append out of order


def test_a_ghost_is_viewed_only_from_ghost_viewed_s_after_the_views_the_rules_need_since_it_became_one() -> (
    None
):
    world, whole = empty_world(), square(4.0, 4.0, 6.0, 6.0)
    views = [(t, whole) for t in (50.0, 60.0, 70.0, 90.0)]  # before it was a ghost: the object stood there
    watch = fleet_sim._watch(world, "urn:e", DESK, views, 100.0)
    assert not fleet_sim.viewed_ghost(watch, 100.0, 3, 1.0)
    views += [(t, whole) for t in (100.5, 101.0, 101.6)]
    watch = fleet_sim._watch(world, "urn:e", DESK, views, 102.0)
    assert watch.held == [100.5, 101.0, 101.6]
    assert not fleet_sim.viewed_ghost(watch, 111.5, 3, 1.0)
    assert fleet_sim.viewed_ghost(watch, 111.7, 3, 1.0)
    moved = box_pose(5.5, 5.0, 0.4, 1.2, 0.6, 0.8, yaw=0.0)  # a new pose: its misses count afresh
    assert fleet_sim._watch(world, "urn:e", moved, views, 112.0).held == []
