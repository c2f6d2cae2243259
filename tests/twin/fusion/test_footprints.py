"""Footprints: the convex hull (shapely's, with the monotone chain for degenerate cases)."""

from __future__ import annotations

import numpy as np

from twin.fusion.footprints import _monotone_chain, convex_hull, min_area_rectangle


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
