"""A moved box's overlay element, made from what its mesh's facts keep, is the element made afresh."""

from __future__ import annotations

import random

from twin.live.overlay import OverlayElement
from twin.live.same import quantised
from twin.maps.raster.boxes import box_footprint
from twin.maps.shapes import box_mesh, box_placement


def test_a_moved_box_keeps_its_footprint_and_bounds_bit_for_bit() -> None:
    rng = random.Random(9)
    for _ in range(3_000):
        mesh = box_mesh(rng.uniform(0.01, 3), rng.uniform(0.01, 3), rng.uniform(0.01, 3))
        before = OverlayElement.of((mesh, quantised(box_placement(1.0, 2.0, 0.5, yaw=rng.uniform(-4, 4)))))
        yaw = rng.choice([0.0, rng.uniform(-7, 7)])
        placement = quantised(
            box_placement(rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(0, 3), yaw=yaw)
        )
        moved = OverlayElement.of((mesh, placement), previous=before)
        fresh = OverlayElement.of((mesh, placement))
        assert moved.footprint is not None and fresh.footprint is not None
        assert moved.footprint.tobytes() == fresh.footprint.tobytes()
        assert moved.footprint.tobytes() == box_footprint(mesh.vertices, placement).tobytes()
        assert moved.bounds is not None and fresh.bounds is not None
        assert moved.bounds.tobytes() == fresh.bounds.tobytes()


def test_a_tilted_box_has_no_footprint_whether_moved_or_made_afresh() -> None:
    mesh = box_mesh(1.0, 1.0, 1.0)
    upright = OverlayElement.of((mesh, box_placement(0.0, 0.0, 0.5)))
    tilted = box_placement(0.0, 0.0, 0.5)
    tilted[:3, :3] = [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]  # a quarter turn about x
    assert upright.footprint is not None
    assert OverlayElement.of((mesh, tilted), previous=upright).footprint is None
