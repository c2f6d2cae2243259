"""An upright box's footprint cells equal the general slab rasteriser's, cell for cell."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.maps.grid import GridFrame, Window
from twin.maps.raster import rasterize_slab
from twin.maps.raster.boxes import box_footprint, footprint_cells
from twin.maps.shapes import box_mesh, box_placement

FRAME = GridFrame(origin_x=-2.0, origin_y=-3.0, resolution_m=0.05, width=160, height=140)


Box = tuple[float, float, float, float, float]  # cx cy sx sy yaw


def _general(box: Box, window: Window) -> np.ndarray:
    cx, cy, sx, sy, yaw = box
    mesh = box_mesh(sx, sy, 1.0)
    p = box_placement(cx, cy, 0.5, yaw=yaw)
    world = mesh.vertices @ p[:3, :3].T + p[:3, 3]
    triangles = world[mesh.faces]
    owner = np.zeros(len(triangles), dtype=np.intp)
    return rasterize_slab(triangles, owner, np.array([True]), 0.2, 0.6, FRAME, window)


def _fast(box: Box, window: Window) -> np.ndarray:
    cx, cy, sx, sy, yaw = box
    mesh = box_mesh(sx, sy, 1.0)
    return footprint_cells(box_footprint(mesh.vertices, box_placement(cx, cy, 0.5, yaw=yaw)), FRAME, window)


def _window(cx: float, cy: float, sx: float, sy: float) -> Window:
    r = math.hypot(sx, sy)
    w = FRAME.window_for(cx - r, cy - r, cx + r, cy + r)
    return Window(w.row0 - 1, w.col0 - 1, w.row1 + 1, w.col1 + 1).intersect(FRAME.full)


# ties: offsets and turns of float noise's size and of the tolerances' (cell_m 1e-9, grid_m 1e-6)
tiny = st.sampled_from([0.0, 1e-9, -1e-9, 1e-12, 3e-10, 2e-9, -2e-9, 5e-7, -9.9e-7, 1.5e-6])
on_grid = st.integers(-20, 50).map(lambda k: k * 0.05)  # the frame spans x -2..6, y -3..4
near_grid = st.tuples(on_grid, tiny).map(sum)
anywhere = st.floats(-1.0, 2.5, allow_nan=False)
size = st.one_of(st.floats(0.001, 2.0), st.integers(1, 30).map(lambda k: k * 0.05))
turns = st.sampled_from([0.0, math.pi / 2, math.pi, -math.pi / 4, math.pi / 4, math.atan2(3, 4)])
yaw = st.one_of(st.floats(-math.pi, math.pi), turns, st.tuples(turns, tiny).map(sum))
centre = st.one_of(near_grid, anywhere)


@settings(max_examples=400, deadline=None)
@given(cx=centre, cy=centre, sx=size, sy=size, yaw=yaw)
def test_a_box_anywhere_at_any_turn_fills_the_cells_the_general_rasteriser_fills(
    cx: float, cy: float, sx: float, sy: float, yaw: float
) -> None:
    window = _window(cx, cy, sx, sy)
    box = (cx, cy, sx, sy, yaw)
    np.testing.assert_array_equal(_fast(box, window), _general(box, window))


@pytest.mark.parametrize(
    "box",
    [
        (1e-09, 0.0, 0.6, 1.0, 1e-09),  # a corner 1.5 nm past the line x = 0.3: on it
        (0.0, 1e-09, 1.0, 1.0, 0.0),  # an edge 1 nm above the line y = -0.5: on it
        (0.0, 0.0, 1.0, 2.0, 1e-09),  # a side turned by 1 nm over its length: on the line x = 0.5
    ],
)
def test_a_box_within_a_micrometre_of_grid_lines_is_on_them_in_both_rasterisers(box: Box) -> None:
    cx, cy, sx, sy, _ = box
    got = _fast(box, Window(0, 0, 140, 160))
    np.testing.assert_array_equal(got, _general(box, Window(0, 0, 140, 160)))
    exact = _fast((round(cx, 6), round(cy, 6), sx, sy, 0.0), Window(0, 0, 140, 160))
    np.testing.assert_array_equal(got, exact)  # the cells of the box on the grid lines


def test_a_box_edge_on_a_grid_line_does_not_spill_into_the_next_cell() -> None:
    window = Window(50, 50, 70, 70)
    # x from 0.5 to 1.0 exactly: columns 50..59 (cells [0.5, 0.55) ... [0.95, 1.0)), not column 60
    box = (0.75, 0.0, 0.5, 0.3, 0.0)
    cols = np.flatnonzero(_fast(box, Window(0, 0, 140, 160)).any(axis=0))
    assert (cols.min(), cols.max()) == (50, 59)
    np.testing.assert_array_equal(_fast(box, window), _general(box, window))


def test_a_box_thinner_than_a_cell_still_occupies_the_cells_it_crosses() -> None:
    cells = _fast((1.0, 1.0, 0.002, 1.0, 0.3), Window(0, 0, 140, 160))
    assert cells.sum() >= 20  # a 1 m long sliver at 0.05 m cells
