"""The view polygon is what the fusion terms ask for: a simple polygon (shapely's validity), around
the sensor, within its range and field of view, never through an occupied cell of the structure."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, Polygon

from adapters.ros.observation_doc import _metres
from adapters.ros.view import OCCUPIED_AT, visibility_polygon
from tests.conftest import examples
from twin.maps.grid import GridFrame, OccupancyGrid

FRAME = GridFrame(0.0, 0.0, 0.1, 80, 60)  # 8 x 6 m


@st.composite
def grids(draw: st.DrawFn) -> OccupancyGrid:
    data = np.zeros((FRAME.height, FRAME.width), dtype=np.int8)
    for _ in range(draw(st.integers(0, 6))):  # walls: random axis-aligned bars
        r0, c0 = draw(st.integers(0, FRAME.height - 1)), draw(st.integers(0, FRAME.width - 1))
        h, w = draw(st.integers(1, 30)), draw(st.integers(1, 30))
        data[r0 : r0 + h, c0 : c0 + w] = draw(st.sampled_from([100, -1, 60]))
    return OccupancyGrid(FRAME, data, "s", "localization", 0.0)


@settings(max_examples=examples(200), deadline=None, suppress_health_check=list(HealthCheck))
@given(
    grid=st.one_of(st.none(), grids()),
    x=st.floats(-1.0, 9.0),
    y=st.floats(-1.0, 7.0),
    heading=st.floats(-10.0, 10.0),
    fov=st.one_of(st.floats(0.05, 6.2), st.just(2 * math.pi)),
    reach=st.floats(0.2, 12.0),
    rays=st.integers(3, 100),
)
def test_the_view_is_a_simple_polygon_within_range_that_crosses_no_wall(  # noqa: PLR0917
    grid: OccupancyGrid | None, x: float, y: float, heading: float, fov: float, reach: float, rays: int
) -> None:
    polygon = visibility_polygon(grid, (x, y), heading_rad=heading, fov_rad=fov, range_m=reach, rays=rays)
    # as written on the wire (0.1 mm): still a valid, simple polygon
    written = [(float(_metres(px)), float(_metres(py))) for px, py in polygon]
    shape = Polygon(written)
    assert shape.is_valid and shape.area > 0
    ends = np.array(polygon if fov >= 2 * math.pi - 1e-9 else polygon[1:])
    assert (np.hypot(ends[:, 0] - x, ends[:, 1] - y) <= reach + 1e-9).all()
    if grid is not None:  # the sensor sees no occupied cell's centre strictly inside its view
        f = grid.frame
        rows, cols = np.nonzero(grid.data >= OCCUPIED_AT)
        centres = np.stack(
            [f.origin_x + (cols + 0.5) * f.resolution_m, f.origin_y + (rows + 0.5) * f.resolution_m], 1
        )
        near = (
            np.hypot(centres[:, 0] - x, centres[:, 1] - y) > 2 * f.resolution_m
        )  # not the sensor's own cell
        inner = shape.buffer(-f.resolution_m)
        assert not any(inner.contains(Point(c)) for c in centres[near][:2000])
