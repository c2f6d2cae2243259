"""The view is what the camera saw: simple polygons (shapely's validity) within its range, outside its
near blind zone, where its frustum holds the band of heights of what it detects, never through an
occupied cell of the structure nor behind a detection; a pitched camera leaves out the floor under
its frame."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, Polygon
from shapely.ops import unary_union

from adapters.ros.observation_doc import _metres
from adapters.ros.tf import matrix
from adapters.ros.view import (
    MIN_AREA_M2,
    OCCUPIED_AT,
    Camera,
    FloorView,
    Structure,
    ViewCache,
    _box_entry,
    _box_entry_all,
    _first_blocks,
    _march,
    _small,
    camera_view,
    visibility_polygon,
)
from tests.conftest import examples
from twin.maps.grid import GridFrame, OccupancyGrid

FRAME = GridFrame(0.0, 0.0, 0.1, 80, 60)  # 8 x 6 m
OPTICAL = (-0.5, 0.5, -0.5, 0.5)
"""``camera_link_from_camera_optical_frame``: z forward, x right, y down (REP 103)."""


def rpy(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """Quaternion (x, y, z, w) of roll about x, then pitch about y, then yaw about z (fixed axes)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def camera(
    x: float,
    y: float,
    z: float,
    *,
    yaw: float = 0.0,
    pitch: float = 0.0,
    roll: float = 0.0,
    hfov: float = math.radians(87),
    vfov: float | None = None,
    reach: float = 6.0,
    near: float = 0.0,
    optical: bool = False,
) -> Camera:
    body = matrix((x, y, z), rpy(roll, pitch, yaw))
    pose = body @ matrix((0, 0, 0), OPTICAL) if optical else body
    return Camera.from_pose(pose, optical=optical, hfov_rad=hfov, vfov_rad=vfov, range_m=reach, near_m=near)


@st.composite
def grids(draw: st.DrawFn) -> OccupancyGrid:
    data = np.zeros((FRAME.height, FRAME.width), dtype=np.int8)
    for _ in range(draw(st.integers(0, 6))):  # walls: random axis-aligned bars
        r0, c0 = draw(st.integers(0, FRAME.height - 1)), draw(st.integers(0, FRAME.width - 1))
        h, w = draw(st.integers(1, 30)), draw(st.integers(1, 30))
        data[r0 : r0 + h, c0 : c0 + w] = draw(st.sampled_from([100, -1, 60]))
    return OccupancyGrid(FRAME, data, "s", "localization", 0.0)


@settings(max_examples=examples(150), deadline=None, suppress_health_check=list(HealthCheck))
@given(
    grid=st.one_of(st.none(), grids()),
    x=st.floats(-1.0, 9.0),
    y=st.floats(-1.0, 7.0),
    z=st.floats(0.2, 2.0),
    yaw=st.floats(-4.0, 4.0),
    pitch=st.floats(-0.3, 1.2),
    roll=st.floats(-0.2, 0.2),
    hfov=st.one_of(st.floats(0.3, 3.0), st.floats(3.2, 6.2), st.just(2 * math.pi)),
    vfov=st.one_of(st.none(), st.floats(0.3, 2.5)),
    reach=st.floats(0.5, 10.0),
    near=st.floats(0.0, 1.0),
    optical=st.booleans(),
    shadow=st.one_of(st.none(), st.tuples(st.floats(-1, 9), st.floats(-1, 7), st.floats(0.1, 1.0))),
)
@example(  # a tilted camera wider than 180°: its blind wedge's apex is off its xy, between two rays
    grid=OccupancyGrid(FRAME, np.zeros((FRAME.height, FRAME.width), dtype=np.int8), "s", "localization", 0.0),
    x=2.0, y=0.0, z=1.0, yaw=0.0, pitch=1.0, roll=0.1953125, hfov=6.0, vfov=None, reach=1.5, near=0.0,
    optical=False, shadow=None,
)  # fmt: skip
@example(  # the band's top at the camera's height: the blind wedge's apex at its xy, its edges two rays
    grid=None, x=1.0, y=4.0, z=0.5, yaw=0.0, pitch=1.0, roll=0.5, hfov=6.25, vfov=None, reach=1.0, near=0.5,
    optical=False, shadow=None,
)  # fmt: skip
@example(  # and with a blind zone: the two heights' wedges cross between two rays
    grid=OccupancyGrid(FRAME, np.zeros((FRAME.height, FRAME.width), dtype=np.int8), "s", "localization", 0.0),
    x=2.0, y=0.0, z=1.125, yaw=0.0, pitch=0.75, roll=0.1953125, hfov=6.125, vfov=None, reach=1.5, near=0.75,
    optical=False, shadow=None,
)  # fmt: skip
@example(  # a wide camera with a vertical limit: near and far ends within 0.1 mm cross on the wire
    grid=None, x=0.0, y=0.0, z=0.9765625, yaw=0.0, pitch=-0.08203125, roll=0.171875, hfov=5.0, vfov=1.515625,
    reach=1.40625, near=0.0, optical=False, shadow=None,
)  # fmt: skip
def test_the_view_is_simple_polygons_the_frustum_holds_past_no_wall_nor_detection(  # noqa: PLR0917
    grid: OccupancyGrid | None,
    x: float,
    y: float,
    z: float,
    yaw: float,
    pitch: float,
    roll: float,
    hfov: float,
    vfov: float | None,
    reach: float,
    near: float,
    optical: bool,
    shadow: tuple[float, float, float] | None,
) -> None:
    cam = camera(x, y, z, yaw=yaw, pitch=pitch, roll=roll, hfov=hfov, vfov=vfov, reach=reach, near=near,
                 optical=optical)  # fmt: skip
    shadows = [(shadow[0], shadow[1], shadow[2], shadow[2], 0.3)] if shadow is not None else []
    view = camera_view(grid, cam, band_m=(0.1, 0.5), shadows=shadows, rays=16)
    if view is None:
        return
    parts = []
    for ring in view.polygons:  # as written on the wire (0.1 mm): still valid, simple polygons
        shape = Polygon([(float(_metres(px)), float(_metres(py))) for px, py in ring])
        assert shape.is_valid and shape.area > 0
        parts.append(shape)
    region = unary_union(parts)
    for hole in view.holes:
        region = region.difference(Polygon(hole))
    points = np.array([p for ring in view.polygons for p in ring])
    d = np.hypot(points[:, 0] - x, points[:, 1] - y)
    assert (d <= reach + 1e-9).all()
    # every point of the view: in range, out of the blind zone, the band in the frustum
    rng = np.random.default_rng(0)
    lo, hi = np.array(region.bounds[:2]), np.array(region.bounds[2:])
    probe = rng.uniform(lo, hi, size=(400, 2))
    inner = region.buffer(-0.03)
    probe = probe[[inner.contains(Point(p)) for p in probe]]
    if len(probe):
        dist = np.hypot(probe[:, 0] - x, probe[:, 1] - y)
        assert (dist <= reach).all() and (dist >= near * math.cos(math.pi / 16) - 0.03).all()
        assert cam.sees(probe[:, 0], probe[:, 1], 0.1).all() and cam.sees(probe[:, 0], probe[:, 1], 0.5).all()
    if shadow is not None:  # nothing inside the detection's footprint is claimed
        sx, sy, side = shadow
        c, s = math.cos(0.3), math.sin(0.3)
        h = side / 2
        square = ((-h, -h), (h, -h), (h, h), (-h, h))
        box = Polygon([(sx + c * u - s * v, sy + s * u + c * v) for u, v in square])
        if not box.contains(Point(x, y)):
            assert region.intersection(box.buffer(-0.03)).area < 1e-6
    if grid is not None:  # the sensor sees no occupied cell's centre strictly inside its view
        f = grid.frame
        rows, cols = np.nonzero(grid.data >= OCCUPIED_AT)
        centres = np.stack(
            [f.origin_x + (cols + 0.5) * f.resolution_m, f.origin_y + (rows + 0.5) * f.resolution_m], 1
        )
        far = np.hypot(centres[:, 0] - x, centres[:, 1] - y) > 2 * f.resolution_m  # not the sensor's cell
        shrunk = region.buffer(-f.resolution_m)
        assert not any(shrunk.contains(Point(c)) for c in centres[far][:2000])


def test_a_camera_pitched_down_leaves_out_the_floor_under_its_frame_and_beyond_where_the_band_leaves_it() -> (
    None
):
    # 1.2 m up, pitched 35 deg down, 60 deg vertical field of view: the band 0.1 .. 0.5 m is in the frame
    # from (1.2 - 0.1) / tan(65 deg) = 0.51 m out to (1.2 - 0.5) / tan(5 deg) = 8.0 m (range 6 m)
    cam = camera(0.0, 0.0, 1.2, pitch=math.radians(35), vfov=math.radians(60), hfov=math.radians(60))
    view = camera_view(None, cam, band_m=(0.1, 0.5))
    assert view is not None and len(view.polygons) == 1 and not view.holes
    ring = np.array(view.polygons[0])
    d = np.hypot(ring[:, 0], ring[:, 1])
    assert 0.5 <= d.min() <= 0.6 and 5.9 <= d.max() <= 6.0 + 1e-9
    assert not Polygon(ring).contains(Point(0.3, 0.0))  # the blind zone under the frame
    assert Polygon(ring).contains(Point(1.0, 0.0))
    # pitched 60 deg down: on its axis, the band's top leaves the frame at (1.2 - 0.5) / tan(30 deg) = 1.21 m
    steep = camera(0.0, 0.0, 1.2, pitch=math.radians(60), vfov=math.radians(60), hfov=math.radians(60))
    seen = camera_view(None, steep, band_m=(0.1, 0.5))
    assert seen is not None
    ring = np.array(seen.polygons[0])
    ahead = np.abs(np.arctan2(ring[:, 1], ring[:, 0])) < 0.05  # along the axis (off it, farther)
    far = np.hypot(ring[ahead, 0], ring[ahead, 1]).max()
    assert 1.1 <= far <= 1.25


def test_the_optical_axis_comes_from_the_setting_not_the_frame_s_name() -> None:
    base = matrix((0.0, 0.0, 1.0), rpy(0.0, 0.0, 0.0)) @ matrix((0, 0, 0), OPTICAL)  # z along map +x
    forward = Camera.from_pose(base, optical=True, hfov_rad=1.5, range_m=4.0)
    sideways = Camera.from_pose(base, optical=False, hfov_rad=1.5, range_m=4.0)  # x: map -y
    a, b = camera_view(None, forward), camera_view(None, sideways)
    assert a is not None and b is not None
    assert np.array(a.polygons[0])[1:, 0].min() > 0  # ahead: +x
    assert np.array(b.polygons[0])[1:, 1].max() < 1e-9  # its x axis points along map -y


def test_a_full_circle_with_a_blind_zone_is_a_ring_and_its_hole() -> None:
    cam = camera(2.0, 2.0, 0.5, hfov=2 * math.pi, reach=3.0, near=0.8)
    view = camera_view(None, cam, band_m=(0.1, 0.4))
    assert view is not None and len(view.polygons) == 1 and len(view.holes) == 1
    region = Polygon(view.polygons[0]).difference(Polygon(view.holes[0]))
    assert region.contains(Point(3.5, 2.0)) and not region.contains(Point(2.5, 2.0))
    assert math.isclose(region.area, math.pi * (3.0**2 - 0.8**2), rel_tol=0.03)


def test_a_level_sensor_s_polygon_starts_at_the_sensor_and_a_sliver_claims_nothing() -> None:
    polygon = visibility_polygon(None, (1.0, 1.0), heading_rad=0.0, fov_rad=math.radians(90), range_m=4.0)
    assert polygon[0] == (1.0, 1.0) and math.isclose(Polygon(polygon).area, math.pi * 16 / 4, rel_tol=0.05)
    assert visibility_polygon(None, (0.0, 0.0), heading_rad=0.0, fov_rad=0.05, range_m=0.3) == ()


def test_a_structure_made_once_cuts_views_as_its_grid_does_and_stops_rays_at_the_grid_s_edge() -> None:
    data = np.zeros((FRAME.height, FRAME.width), dtype=np.int8)
    data[:, 40] = 100  # a wall across the grid at x = 4.0 m
    grid = OccupancyGrid(FRAME, data, "s", "localization", 0.0)
    structure = Structure.of(grid)
    for cam in (camera(2.0, 3.0, 1.0, yaw=yaw, reach=12.0) for yaw in (0.0, 1.5, math.pi, 4.0)):
        a, b = camera_view(grid, cam), camera_view(structure, cam)
        assert a is not None and b is not None
        assert a.polygons == b.polygons and a.holes == b.holes
        seen = unary_union([Polygon(p) for p in b.polygons])
        assert seen.bounds[0] >= -0.1 and seen.bounds[2] <= 4.0 + 1e-9  # not past the wall, nor the edge
        assert seen.bounds[1] >= -0.1 and seen.bounds[3] <= 6.1


def _same(a: FloorView | None, b: FloorView | None) -> bool:
    def floats(v: FloorView | None) -> object:
        return None if v is None else (v.polygons, v.holes)

    return repr(floats(a)) == repr(floats(b))  # the polygons' floats, bit for bit (None alike)


@settings(max_examples=examples(60), deadline=None, suppress_health_check=list(HealthCheck))
@given(
    grids=st.tuples(grids(), grids()),
    x=st.floats(-1.0, 9.0),
    y=st.floats(-1.0, 7.0),
    yaw=st.floats(-4.0, 4.0),
    pitch=st.floats(-0.3, 1.2),
    hfov=st.one_of(st.floats(0.3, 3.0), st.floats(3.2, 6.2)),
    vfov=st.one_of(st.none(), st.floats(0.3, 2.5)),
    near=st.floats(0.0, 1.0),
    shadows=st.lists(
        st.lists(st.tuples(st.floats(-1, 9), st.floats(-1, 7), st.floats(0.1, 1.0)), max_size=4),
        min_size=2,
        max_size=3,
    ),
)
def test_a_view_cache_gives_the_views_a_fresh_march_gives_whatever_the_shadows_and_a_new_map_misses_it(  # noqa: PLR0917
    grids: tuple[OccupancyGrid, OccupancyGrid],
    x: float,
    y: float,
    yaw: float,
    pitch: float,
    hfov: float,
    vfov: float | None,
    near: float,
    shadows: list[list[tuple[float, float, float]]],
) -> None:
    cam = camera(x, y, 1.0, yaw=yaw, pitch=pitch, hfov=hfov, vfov=vfov, reach=6.0, near=near)
    cache = ViewCache()
    for grid in grids:
        structure = Structure.of(grid)  # a new map version: a new object, never the old march
        for boxes in shadows:
            rows = [(bx, by, s, s, 0.0) for bx, by, s in boxes]
            fresh = camera_view(structure, cam, band_m=(0.1, 0.5), shadows=rows)
            cached = camera_view(structure, cam, band_m=(0.1, 0.5), shadows=rows, cache=cache)
            assert _same(fresh, cached)
    assert cache.misses == 2 and cache.hits == 2 * len(shadows) - 2


def _full_first_block(
    structure: Structure, ox: float, oy: float, angles: np.ndarray, dist: np.ndarray
) -> np.ndarray:
    """The whole march: every ray to the frustum's farthest reach, its first blocking sample."""
    xs = np.multiply.outer(np.cos(angles), dist) + ox
    ys = np.multiply.outer(np.sin(angles), dist) + oy
    f = structure.grid.frame
    cols = np.clip(np.floor((xs - f.origin_x) / f.resolution_m).astype(np.intp), -1, f.width)
    rows = np.clip(np.floor((ys - f.origin_y) / f.resolution_m).astype(np.intp), -1, f.height)
    blocked = structure.blocked[(rows + 1) * (f.width + 2) + cols + 1]
    step = f.resolution_m / 2
    return np.where(blocked.any(axis=1), dist[blocked.argmax(axis=1)] - step, np.inf)


@settings(max_examples=examples(150), deadline=None, suppress_health_check=list(HealthCheck))
@given(
    grid=grids(),
    x=st.floats(-1.0, 9.0),
    y=st.floats(-1.0, 7.0),
    z=st.floats(0.2, 2.0),
    yaw=st.floats(-4.0, 4.0),
    pitch=st.floats(-0.3, 1.2),
    hfov=st.floats(0.3, 3.1),
    vfov=st.one_of(st.none(), st.floats(0.3, 2.5)),
    reach=st.floats(0.5, 10.0),
)
def test_a_pinhole_march_in_chunks_stops_each_ray_where_the_whole_march_does(  # noqa: PLR0917
    grid: OccupancyGrid,
    x: float,
    y: float,
    z: float,
    yaw: float,
    pitch: float,
    hfov: float,
    vfov: float | None,
    reach: float,
) -> None:
    cam = camera(x, y, z, yaw=yaw, pitch=pitch, hfov=hfov, vfov=vfov, reach=reach)
    structure = Structure.of(grid)
    marched = _march(structure, cam, (0.1, 0.5), 64)
    if marched.count == 0:
        return
    step = marched.step
    reach_m = float(marched.far.max())
    dist = np.arange(marched.near0, reach_m + step, step)
    dist = dist[dist <= reach_m + 1e-9]
    full = _full_first_block(structure, x, y, marched.angles, dist)
    # the floor each ray claims ends at the same place, bit for bit (beyond its far end a wall is moot)
    assert np.array_equal(np.minimum(marched.far, marched.first_block), np.minimum(marched.far, full))
    assert np.array_equal(marched.first_block <= marched.far, full <= marched.far)


@settings(max_examples=examples(100), deadline=None, suppress_health_check=list(HealthCheck))
@given(
    x=st.floats(-5.0, 5.0),
    y=st.floats(-5.0, 5.0),
    rays=st.integers(1, 700),
    first=st.floats(0.0, 6.3),
    span=st.floats(0.0, 6.3),
    boxes=st.lists(
        st.tuples(
            st.floats(-6.0, 6.0), st.floats(-6.0, 6.0), st.floats(0.0, 3.0), st.floats(0.0, 3.0),
            st.floats(-4.0, 4.0),
        ),
        max_size=12,
    ),
)
def test_the_boxes_rays_enter_are_found_among_the_pairs_that_can_meet_as_among_all_pairs(  # noqa: PLR0917
    x: float, y: float, rays: int, first: float, span: float, boxes: list[tuple[float, ...]]
) -> None:
    angles = np.sort((first + span * np.arange(rays) / rays) % (2 * math.pi))  # as a march covers them
    near = [(x + 0.05, y - 0.02, 0.3, 0.2, 0.5), (x + 0.4, y, 0.5, 0.5, 0.0)]  # holds, touches the sensor
    shadows = np.array([*boxes, *near[: len(boxes) % 3]], dtype=np.float64).reshape(-1, 5)
    got, want = _box_entry(x, y, angles, shadows), _box_entry_all(x, y, angles, shadows)
    assert got.tobytes() == want.tobytes()


@settings(max_examples=examples(80), deadline=None, suppress_health_check=list(HealthCheck))
@given(
    cells=st.lists(st.tuples(st.integers(0, 119), st.integers(0, 159)), max_size=400),
    x=st.floats(-2.5, 7.5),
    y=st.floats(-0.5, 7.0),
    first=st.floats(0.0, 6.3),
    span=st.floats(0.0, 6.3),
    reach=st.floats(0.1, 9.0),
    limit=st.floats(0.0, 9.0),
)
def test_rays_skip_the_blocks_far_from_structure_and_still_stop_at_the_first_blocking_sample(  # noqa: PLR0917
    cells: list[tuple[int, int]], x: float, y: float, first: float, span: float, reach: float, limit: float
) -> None:
    frame = GridFrame(-1.3, 0.7, 0.05, 160, 120)  # single blocking cells strewn over an 8 x 6 m grid
    data = np.zeros((frame.height, frame.width), dtype=np.int8)
    for row, col in cells:
        data[row, col] = 100
    structure = Structure.of(OccupancyGrid(frame, data, "s", "localization", 0.0))
    angles = np.sort((first + span * np.arange(97) / 97) % (2 * math.pi))
    step = frame.resolution_m / 2
    dist = np.arange(0.05, reach + step, step)
    upto = np.where(np.arange(len(angles)) % 3 == 0, limit, np.inf)  # some rays end early
    got = _first_blocks(structure, x, y, angles, dist, upto=upto, step=step)
    for ray, limit_m in enumerate(upto.tolist()):  # the whole march of each ray, to its limit
        within = dist[dist <= limit_m]
        want = _full_first_block(structure, x, y, angles[ray : ray + 1], within) if len(within) else [np.inf]
        assert got[ray] == want[0], (ray, got[ray], want[0])


@settings(max_examples=examples(200), deadline=None, suppress_health_check=list(HealthCheck))
@given(
    points=st.integers(3, 60),
    seed=st.integers(0, 2**32 - 1),
    scale=st.one_of(st.floats(0.01, 3.0), st.floats(0.05, 0.07)),
    hole=st.booleans(),
)
def test_a_view_is_too_small_exactly_when_its_area_is_under_the_limit(
    points: int, seed: int, scale: float, hole: bool
) -> None:
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0.0, 2 * math.pi, points))
    r = scale * rng.uniform(0.5, 1.5, points)
    ring = np.stack([12.3 + np.cos(t) * r, -4.1 + np.sin(t) * r], axis=1)
    view = FloorView((ring,), (ring * 0.1 + (12.3 * 0.9, -4.1 * 0.9),) if hole else ())
    assert _small(view) == (view.area < MIN_AREA_M2)
    exact = FloorView((ring / math.sqrt(view.area / MIN_AREA_M2),))  # scaled to the limit itself
    assert _small(exact) == (exact.area < MIN_AREA_M2)


def test_a_view_cache_is_not_reused_after_the_robot_moves_a_centimetre_or_the_map_changes() -> None:
    data = np.zeros((FRAME.height, FRAME.width), dtype=np.int8)
    grid = OccupancyGrid(FRAME, data, "s", "localization", 0.0)
    walled = data.copy()
    walled[:, 45] = 100  # a wall across the view at x = 4.5 m
    shadows = [(3.0, 3.2, 0.3, 0.3, 0.0)]
    cache = ViewCache()
    seen = []
    for structure, x in [
        (Structure.of(grid), 1.0),
        (Structure.of(grid), 1.0),  # a new map version (the same cells): marched again
        (Structure.of(OccupancyGrid(FRAME, walled, "s", "localization", 0.0)), 1.0),  # a wall: marched again
        (Structure.of(grid), 1.01),  # moved 1 cm
    ]:
        cam = camera(x, 3.0, 1.0)
        cached = camera_view(structure, cam, band_m=(0.1, 0.5), shadows=shadows, cache=cache)
        assert _same(cached, camera_view(structure, cam, band_m=(0.1, 0.5), shadows=shadows))
        seen.append(cached)
    assert cache.hits == 0 and cache.misses == 4
    assert seen[0] is not None and seen[2] is not None and seen[3] is not None
    assert max(x for ring in seen[2].polygons for x, _ in ring) <= 4.5  # stops at the new wall
    assert max(x for ring in seen[0].polygons for x, _ in ring) > 6.0  # the old view did not
    assert not _same(seen[0], seen[3])
