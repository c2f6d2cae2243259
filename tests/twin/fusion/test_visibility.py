"""What a sensor could see: footprints inside a view by area (concave views, holes, unions) and sight
lines from the sensor's origin past the elements the twin holds."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.fusion.footprints import box_pose, corners, inside
from twin.fusion.visibility import Solids, in_region, inside_by_area, line_of_sight, visible_in_view

ROOM = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
SLOT = np.array(  # the room less a slot from its north edge down to y = 3 (a shadow carved out)
    [[0, 0], [10, 0], [10, 10], [5.5, 10], [5.5, 3], [4.5, 3], [4.5, 10], [0, 10]], dtype=np.float64
)
BENCH = box_pose(5.0, 6.0, 0.25, 2.4, 0.5, 0.5, yaw=0.0)


def feet(*poses: object, inset: float = 0.1) -> np.ndarray:
    return np.stack([corners(p, inset=inset) for p in poses])  # type: ignore[arg-type]


def test_a_bench_across_a_slot_of_a_concave_view_is_not_in_it_though_its_corners_are() -> None:
    f = feet(BENCH)
    assert inside(f[0], [SLOT])  # the corner test of old says it is
    assert not inside_by_area(f, [SLOT])[0]
    assert inside_by_area(f, [ROOM])[0]


def test_a_hole_under_the_middle_of_a_footprint_takes_it_out_of_the_view() -> None:
    shadow = np.array([[4.9, 5.9], [5.1, 5.9], [5.1, 6.1], [4.9, 6.1]])
    assert not inside_by_area(feet(BENCH), [ROOM], [shadow])[0]
    elsewhere = shadow + np.array([3.0, 3.0])
    assert inside_by_area(feet(BENCH), [ROOM], [elsewhere])[0]


def test_two_polygons_sharing_an_edge_under_a_footprint_hold_it_as_their_union() -> None:
    west = np.array([[0.0, 0.0], [5.0, 0.0], [5.0, 10.0], [0.0, 10.0]])
    east = west + np.array([5.0, 0.0])
    assert inside_by_area(feet(BENCH), [west, east])[0]
    assert not inside_by_area(feet(BENCH), [west])[0]
    gap = east + np.array([0.05, 0.0])  # a 5 cm strip between them was not seen
    assert not inside_by_area(feet(BENCH), [west, gap])[0]


def test_footprints_given_clockwise_or_collapsed_by_the_inset_are_tested_too() -> None:
    cw = feet(BENCH)[:, ::-1]
    assert inside_by_area(cw, [ROOM])[0] and not inside_by_area(cw, [SLOT])[0]
    tiny = feet(box_pose(2.0, 2.0, 0.1, 0.1, 0.1, 0.2, yaw=0.4))  # inset to a point
    assert inside_by_area(tiny, [ROOM])[0] and not inside_by_area(tiny + 20.0, [ROOM])[0]


def test_bad_shapes_are_refused_naming_them() -> None:
    with pytest.raises(ValueError, match=r"\(n, 4, 2\).*\(2, 3\)"):
        inside_by_area(np.zeros((2, 3)), [ROOM])
    with pytest.raises(ValueError, match=r"ring.*\(2, 2\)"):
        inside_by_area(feet(BENCH), [np.zeros((2, 2))])


@settings(max_examples=60, deadline=None)
@given(
    cx=st.floats(0.5, 9.5),
    cy=st.floats(0.5, 9.5),
    sx=st.floats(0.05, 3.0),
    sy=st.floats(0.05, 3.0),
    yaw=st.floats(0.0, 3.2),
)
def test_a_footprint_inside_by_area_has_every_sample_of_it_inside(
    cx: float, cy: float, sx: float, sy: float, yaw: float
) -> None:
    quad = feet(box_pose(cx, cy, 0.5, sx, sy, 1.0, yaw=yaw), inset=0.0)
    u = (np.arange(40) + 0.5) / 40
    uu, vv = (a.ravel()[:, None] for a in np.meshgrid(u, u))
    c = quad[0]
    pts = (1 - uu) * (1 - vv) * c[0] + uu * (1 - vv) * c[1] + uu * vv * c[2] + (1 - uu) * vv * c[3]
    dense = bool(in_region(np.concatenate([pts, c]), [SLOT]).all())
    got = bool(inside_by_area(quad, [SLOT])[0])
    assert dense or not got  # never inside where a sample of it is not


SENSOR = (5.0, 0.5, 0.6)  # 0.6 m above the floor, south of the bench


def test_a_cabinet_taller_than_the_sensor_hides_the_bench_behind_it_and_not_one_beside_it() -> None:
    cabinet = box_pose(5.0, 3.5, 0.9, 3.0, 0.5, 1.8, yaw=0.0)
    beside = box_pose(8.5, 6.0, 0.25, 1.0, 0.5, 0.5, yaw=0.0)
    occ = Solids.of([BENCH, beside, cabinet])
    got = line_of_sight(feet(BENCH, beside), np.array([0.25, 0.25]), SENSOR, occ, own=np.array([0, 1]))
    assert got.tolist() == [False, True]


def test_a_low_box_hides_what_the_sight_lines_pass_below_its_top_only() -> None:
    low = box_pose(5.0, 3.5, 0.2, 3.0, 0.5, 0.4, yaw=0.0)  # 0.4 m: below the sensor's 0.6 m
    occ = Solids.of([low])
    mid = np.array([0.25])  # the bench's mid-height: the line from 0.6 m passes 0.4 m near the box
    assert not line_of_sight(feet(BENCH), mid, SENSOR, occ)[0]
    assert line_of_sight(feet(BENCH), mid, (5.0, 0.5, 2.5), occ)[0]  # seen over it from 2.5 m


def test_what_overlaps_an_element_hides_it_only_from_the_side_it_stands_on() -> None:
    ghost = box_pose(5.0, 6.0, 0.375, 1.2, 0.8, 0.75, yaw=0.0)
    sighting = box_pose(5.8, 6.0, 0.375, 1.2, 0.8, 0.75, yaw=0.0)  # east of it, overlapping
    occ = Solids.of([ghost, sighting])
    mid, own = np.array([0.375]), np.array([0])
    assert line_of_sight(feet(ghost), mid, (1.0, 6.0, 0.6), occ, own=own)[0]  # from the west: seen
    assert not line_of_sight(feet(ghost), mid, (9.0, 6.0, 0.6), occ, own=own)[0]  # from the east: behind


def test_without_an_origin_the_view_is_taken_as_given() -> None:
    wall_of_boxes = Solids.of([box_pose(5.0, 3.5, 1.0, 9.0, 0.5, 2.0, yaw=0.0)])
    f = feet(BENCH)
    assert visible_in_view(f, [ROOM], occluders=wall_of_boxes)[0]
    assert not visible_in_view(f, [ROOM], origin=SENSOR, mid_z=np.array([0.25]), occluders=wall_of_boxes)[0]
    with pytest.raises(ValueError, match="mid_z"):
        visible_in_view(f, [ROOM], origin=SENSOR, occluders=wall_of_boxes)


def test_a_view_s_origin_is_taken_above_its_storey_s_elevation() -> None:
    from twin.fusion.visibility import view_sees
    from twin.records import ObservedView

    up = 3.0  # a first floor: poses are world z, the origin's z is above the storey's floor
    bench = box_pose(5.0, 6.0, up + 0.25, 2.4, 0.5, 0.5, yaw=0.0)
    low = box_pose(5.0, 3.5, up + 0.2, 3.0, 0.5, 0.4, yaw=0.0)
    view = ObservedView("first-floor", (ROOM,), ("IfcFurniture",), origin=(5.0, 0.5, 2.5))
    held = {"bench": bench, "low": low}
    seen = view_sees(view, [bench], iris=["bench"], held=held, elevation_m=up, inset_m=0.1)
    assert seen == [True]  # 2.5 m above the floor: over the low box
    low_sensor = ObservedView("first-floor", (ROOM,), ("IfcFurniture",), origin=(5.0, 0.5, 0.3))
    assert view_sees(low_sensor, [bench], iris=["bench"], held=held, elevation_m=up, inset_m=0.1) == [False]
    far = ObservedView("first-floor", (ROOM + 50.0,), ("IfcFurniture",))
    assert view_sees(far, [bench], iris=["bench"], held=held, elevation_m=up, inset_m=0.1) == [False]
