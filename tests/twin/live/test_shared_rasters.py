"""An upright box is rasterised once per grid frame for every map whose band it crosses: the maps stay
equal to a rebuild from the triangles, bit for bit."""

from __future__ import annotations

import random

import numpy as np

from tests.twin.live_helpers import box_turtle, observe, started


def test_boxes_moved_and_turned_leave_every_map_equal_to_a_rebuild_with_one_raster_per_frame() -> None:
    service, _ = started()
    rng = random.Random(7)
    shared = 0
    for i in range(60):
        table = f"urn:robot1:t{i % 3}"
        x, y = rng.uniform(4.5, 7.5), rng.uniform(1.5, 2.5)
        height = rng.choice([0.3, 0.75, 1.2, 2.0])  # under, across and above the 0.5 m band
        reply = observe(service, "robot1", box_turtle(table, x, y, sz=height, yaw=rng.uniform(-3.1, 3.1)))
        assert reply.ok, reply.body
        shared = max(shared, len(service.live_maps._rasters.shared))
    maps = service.live_maps.skill_maps
    for key, m in maps.items():
        np.testing.assert_array_equal(m.data, service.live_maps.rebuild(m), err_msg=str(key))
    frames = {m.plan.frame for k, m in maps.items() if k[1] in ("navigation", "lab-navigation")}
    assert len(frames) == 1  # the two navigation skills share one frame: the case this shares
    assert shared > 0  # some rasters were shared
