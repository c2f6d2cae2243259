"""Grid planes decided in the model's coordinates: a coordinate within 1 um of a plane is on it (the
planes being origin + i * resolution as the decimals they print as), then the half-open rule decides;
frames, band ends and the ties between points of a voxel follow."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.conftest import examples
from twin.maps.grid import GridFrame, grid_coordinate, grid_coordinates, grid_units
from twin.maps.points import PointsPlan, best_rows
from twin.maps.scene import StoreyInfo
from twin.selection.skills import parse_skill


def test_a_coordinate_on_a_grid_line_is_on_it_whatever_float64_says() -> None:
    # the sample lab's grid: origin (8.8, 3.7), 0.1 m; float64 puts these in the cell below
    assert 133.9999 < (22.2 - 8.8) / 0.1 < 134
    assert (4.8 - 3.7) / 0.1 < 11
    assert grid_coordinates([22.2, 9.8], 8.8, 0.1).tolist() == [134.0, 10.0]
    assert grid_coordinates(4.8, 3.7, 0.1).tolist() == 11.0
    assert grid_coordinates(2.8, 0.0, 0.1).tolist() == 28.0


def test_a_coordinate_within_a_micrometre_of_a_line_is_on_it_and_one_beyond_is_not() -> None:
    got = grid_coordinates([1.0 + 0.9e-6, 1.0 - 0.9e-6, 1.0 + 1.1e-6, 1.05], 0.0, 0.1)
    assert got[:2].tolist() == [10.0, 10.0]
    assert 10.0 < got[2] < 10.0001 and got[3] == pytest.approx(10.5)


@settings(max_examples=examples(300), deadline=None)
@given(
    k=st.integers(-100_000, 100_000),
    off=st.sampled_from([0.0, 1e-9, -1e-9, 0.99e-6, -0.99e-6, 1.01e-6, 0.5, 0.49999999, 3e-7]),
    origin=st.sampled_from([0.0, 8.8, -3.7, 1e5 + 0.05, -2.0]),
    res=st.sampled_from([0.05, 0.1, 0.025, 0.3, 1.0]),
    noise=st.floats(-1e3, 1e3, allow_nan=False),
)
def test_one_coordinate_in_python_floats_is_the_arrays_coordinate_bit_for_bit(
    k: int, off: float, origin: float, res: float, noise: float
) -> None:
    for v in (origin + k * res + off * res, noise, origin + (k + 0.5) * res):
        assert grid_coordinate(v, origin, res) == float(grid_coordinates(v, origin, res)), v


def test_a_coordinate_near_a_bands_end_is_on_it() -> None:
    got = grid_coordinates([0.7 - 0.05 + 1e-9, 0.7 + 3.3000000000000007], 0.7, 0.1, ends=(-0.05, 9.9 - 6.6))
    assert got.tolist() == [-0.5, 33.0]


@settings(max_examples=examples(200), deadline=None)
@given(
    st.integers(-200, 200),
    st.integers(-200, 200),
    st.sampled_from([(0, 0), (-11, 3), (100_000, 50_000), (7, -13)]),
    st.sampled_from([0.1, 0.05, 0.25]),
)
def test_a_frame_moved_by_whole_cells_moves_by_as_many_cells(
    lo: int, size: int, offset: tuple[int, int], res: float
) -> None:
    xmin, ymin = lo * 0.1 + 0.05, lo * 0.1  # on and off the cells' lines
    xmax, ymax = xmin + abs(size) * 0.1 + 0.3, ymin + abs(size) * 0.1
    base = GridFrame.around(xmin, ymin, xmax, ymax, resolution_m=res, margin_m=1.0)
    dx, dy = offset[0] * res, offset[1] * res
    moved = GridFrame.around(xmin + dx, ymin + dy, xmax + dx, ymax + dy, resolution_m=res, margin_m=1.0)
    assert (moved.width, moved.height) == (base.width, base.height)
    assert round((moved.origin_x - base.origin_x) / res) == offset[0]
    assert round((moved.origin_y - base.origin_y) / res) == offset[1]
    assert moved.origin_x == pytest.approx(base.origin_x + dx, abs=1e-9)


def test_storeys_at_6_6_and_9_9_metres_give_a_band_of_33_layers_not_a_sliver_more() -> None:
    assert 9.9 - 6.6 == 3.3000000000000007
    skill = parse_skill("lidar3d", {"kind": "points"})
    storey = StoreyInfo("https://example.org/s", "third-floor", "Third", 6.6, (0.0, 0.0, 4.0, 4.0))
    frame = GridFrame.around(0.0, 0.0, 4.0, 4.0, resolution_m=0.1)
    plan = PointsPlan(skill, storey, frame, (-0.05, 9.9 - 6.6), np.empty(0, dtype=np.int64))
    assert plan.w_band == (-0.5, 33.0) and plan.layers == (-1, 33)
    # the floor above (its underside at 9.9 m) is on the band's top: out of the half-open band
    floor_above = np.array([[[1.0, 1.0, 9.9], [2.0, 1.0, 9.9], [1.0, 2.0, 9.9]]])
    assert plan.cells(floor_above)[0, :, 2].tolist() == [33.0, 33.0, 33.0]
    assert grid_units(9.9 - 6.6, 0.1) == 33.0


def test_points_equal_but_for_rounding_are_ranked_by_their_normal_not_their_noise() -> None:
    keys = np.array([4, 4], dtype=np.int64)
    n = np.array([[0, 0, 1], [0, 0, -1]], dtype=np.float32)
    for noise in (1e-15, -1e-15, 3e-12):
        q = np.array([[0.5, 0.5, 1.0], [0.5, 0.5, 1.0 + noise]])
        d2 = ((q - 0.5) ** 2).sum(axis=1)
        for order in ([0, 1], [1, 0]):
            rows = np.array(order)
            best = rows[best_rows(keys[rows], q[rows], d2[rows], n[rows])]
            assert n[best].tolist() == [[0, 0, -1]], (noise, order)


def test_points_a_quantum_apart_are_ranked_by_distance_then_by_point() -> None:
    keys = np.array([4, 4, 4], dtype=np.int64)
    q = np.array([[0.5, 0.5, 1.0], [0.5, 0.5, 1.0 - 2e-6], [0.5 - 2e-6, 0.5, 1.0]])
    d2 = ((q - 0.5) ** 2).sum(axis=1)
    n = np.zeros((3, 3), dtype=np.float32)
    assert best_rows(keys, q, d2, n).tolist() == [1]  # nearer by more than the quantum
    assert best_rows(keys[[0, 2]], q[[0, 2]], d2[[0, 2]], n[[0, 2]]).tolist() == [1]  # equal: smaller x
