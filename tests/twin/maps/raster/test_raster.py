"""Slab rasterising (twin.maps.raster) against an independent shapely reference.

The reference clips every triangle to the slab in plain Python, takes the convex hull of the clipped
points (for a closed convex part: of all its clipped points, which is the projection of the part's
solid within the slab) and tests each cell box, shrunk by the tolerance for positive-area geometry
and grown by it for degenerate open surfaces, with shapely.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from twin.errors import MapError
from twin.maps.grid import GridFrame, Window
from twin.maps.raster import TOLERANCES, RasterSettings, rasterize, rasterize_slab, slab_geometry

TOL = TOLERANCES.cell_m
FAST = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# -- scenes ----------------------------------------------------------------------------------------


def box(centre, extents, yaw=0.0, tilt=0.0) -> np.ndarray:
    """``(12, 3, 3)`` triangles of a closed box: rotated by ``tilt`` about x, then ``yaw`` about z."""
    mesh = trimesh.creation.box(extents=extents)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(tilt, [1, 0, 0]))
    mesh.apply_transform(trimesh.transformations.rotation_matrix(yaw, [0, 0, 1]))
    mesh.apply_translation(centre)
    return np.asarray(mesh.triangles)


def quad(start, end, z0, z1) -> np.ndarray:
    """``(2, 3, 3)`` triangles of a vertical rectangle from XY ``start`` to ``end``: an open surface."""
    (x0, y0), (x1, y1) = start, end
    a, b, c, d = (x0, y0, z0), (x1, y1, z0), (x1, y1, z1), (x0, y0, z1)
    return np.array([[a, b, c], [a, c, d]], dtype=float)


def sphere(centre, radius) -> np.ndarray:
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=radius)
    mesh.apply_translation(centre)
    return np.asarray(mesh.triangles)


class Scene:
    """Elements made of parts; each part is convex (closed elements) or a bare surface (open ones)."""

    def __init__(self) -> None:
        self.parts: list[tuple[int, np.ndarray]] = []
        self.closed: list[bool] = []

    def add(self, closed: bool, *parts: np.ndarray) -> int:
        self.closed.append(closed)
        for p in parts:
            self.parts.append((len(self.closed) - 1, p))
        return len(self.closed) - 1

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        tri = np.concatenate([p for _, p in self.parts]) if self.parts else np.empty((0, 3, 3))
        el = (
            np.concatenate([np.full(len(p), e, dtype=np.intp) for e, p in self.parts])
            if self.parts
            else (np.empty(0, np.intp))
        )
        return tri, el, np.array(self.closed, dtype=bool)

    def only(self, element: int) -> Scene:
        one = Scene()
        one.closed = [c and i == element for i, c in enumerate(self.closed)]
        one.parts = [(e, p) for e, p in self.parts if e == element]
        return one


# -- the reference ---------------------------------------------------------------------------------


def clip_points(triangle: np.ndarray, z_lo: float, z_hi: float) -> list[tuple[float, float]]:
    """XY of the vertices of one triangle's part with ``z_lo <= z <= z_hi`` (Sutherland-Hodgman)."""
    poly = [tuple(v) for v in triangle]
    for keep, plane in ((lambda z: z >= z_lo, z_lo), (lambda z: z <= z_hi, z_hi)):
        out = []
        for i, p in enumerate(poly):
            q = poly[(i + 1) % len(poly)]
            if keep(p[2]):
                out.append(p)
            if keep(p[2]) != keep(q[2]) and p[2] != q[2]:
                t = (plane - p[2]) / (q[2] - p[2])
                out.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1]), plane))
        poly = out
        if not poly:
            return []
    return [(p[0], p[1]) for p in poly]


def degenerate(geom: shapely.Geometry) -> bool:
    if geom.is_empty:
        return True
    x0, y0, x1, y1 = geom.bounds
    return geom.area <= TOL * max(x1 - x0, y1 - y0)


def reference(scene: Scene, z_lo: float, z_hi: float, frame: GridFrame) -> np.ndarray:
    res = frame.resolution_m
    cols, rows = np.meshgrid(np.arange(frame.width), np.arange(frame.height))
    x0, y0 = frame.origin_x + cols * res, frame.origin_y + rows * res
    shrunk = shapely.box(x0 + TOL, y0 + TOL, x0 + res - TOL, y0 + res - TOL)
    grown = shapely.box(x0 - TOL, y0 - TOL, x0 + res + TOL, y0 + res + TOL)
    out = np.zeros(frame.shape, dtype=bool)
    for element, given_part in scene.parts:
        part = given_part.copy()  # a z within 1 um of the band's end is on it
        part[..., 2][np.abs(part[..., 2] - z_lo) <= 1e-6] = z_lo
        part[..., 2][np.abs(part[..., 2] - z_hi) <= 1e-6] = z_hi
        clipped = [clip_points(t, z_lo, z_hi) for t in part]
        if scene.closed[element]:
            if z_lo < z_hi and (part[..., 2].max() <= z_lo or part[..., 2].min() >= z_hi):
                continue  # a solid only touching the band's end occupies no space in it
            points = [p for c in clipped for p in c]
            if points:
                out |= shapely.intersects(shapely.MultiPoint(points).convex_hull, shrunk)
            continue
        for c in clipped:
            if c:
                hull = shapely.MultiPoint(c).convex_hull
                out |= shapely.intersects(hull, grown if degenerate(hull) else shrunk)
    return out


def run(scene: Scene, z_lo: float, z_hi: float, frame: GridFrame, window: Window | None = None) -> np.ndarray:
    tri, el, closed = scene.arrays()
    return rasterize_slab(tri, el, closed, z_lo, z_hi, frame, window)


# -- strategies ------------------------------------------------------------------------------------

FRAME = GridFrame(origin_x=-0.013, origin_y=0.027, resolution_m=0.05, width=64, height=56)
coord_x = st.floats(0.2, 3.0)
coord_y = st.floats(0.2, 2.6)
angles = st.floats(0.0, math.pi)
slabs = st.tuples(st.floats(-0.5, 2.5), st.floats(0.0, 1.5)).map(lambda t: (t[0], t[0] + t[1]))


@st.composite
def boxes(draw, thin: bool = False) -> np.ndarray:
    centre = (draw(coord_x), draw(coord_y), draw(st.floats(0.0, 2.0)))
    width = draw(st.floats(0.002, 0.04)) if thin else draw(st.floats(0.01, 1.5))
    extents = (width, draw(st.floats(0.01, 1.5)), draw(st.floats(0.01, 3.0)))
    tilt = draw(st.sampled_from([0.0, 0.0, draw(st.floats(-1.2, 1.2))]))
    return box(centre, extents, yaw=draw(angles), tilt=tilt)


@st.composite
def open_quads(draw) -> np.ndarray:
    x0, y0 = draw(coord_x), draw(coord_y)
    if draw(st.booleans()):  # vertical: anywhere, along y, or along y exactly on a grid line
        kind = draw(st.sampled_from(["any", "along y", "on a grid line"]))
        if kind == "on a grid line":
            x0 = FRAME.origin_x + draw(st.integers(4, 60)) * FRAME.resolution_m
        end = (draw(coord_x) if kind == "any" else x0, draw(coord_y))
        return quad((x0, y0), end, draw(st.floats(-0.5, 1.0)), draw(st.floats(1.0, 3.0)))
    z = [draw(st.floats(-0.5, 3.0)) for _ in range(4)]
    x1, y1 = draw(coord_x), draw(coord_y)
    a, b, c, d = (x0, y0, z[0]), (x1, y0, z[1]), (x1, y1, z[2]), (x0, y1, z[3])
    return np.array([[a, b, c], [a, c, d]], dtype=float)


@st.composite
def scenes(draw, max_elements: int = 5) -> Scene:
    scene = Scene()
    for _ in range(draw(st.integers(1, max_elements))):
        kind = draw(st.sampled_from(["box", "thin", "quad", "sphere"]))
        if kind == "quad":
            scene.add(False, draw(open_quads()))
        elif kind == "sphere":
            scene.add(
                True,
                sphere((draw(coord_x), draw(coord_y), draw(st.floats(0.0, 2.0))), draw(st.floats(0.05, 0.8))),
            )
        else:
            scene.add(True, draw(boxes(thin=kind == "thin")))
    return scene


# -- exactness against the reference ---------------------------------------------------------------


@FAST
@given(part=boxes(), slab=slabs)
def test_a_random_box_occupies_exactly_the_cells_its_slab_section_touches(part, slab):
    scene = Scene()
    scene.add(True, part)
    np.testing.assert_array_equal(run(scene, *slab, FRAME), reference(scene, *slab, FRAME))


@FAST
@given(part=boxes(thin=True), slab=st.floats(-0.5, 1.5).map(lambda z: (z, z + 0.2)))
def test_thin_walls_never_vanish_and_match_the_reference(part, slab):
    scene = Scene()
    scene.add(True, part)
    got = run(scene, *slab, FRAME)
    np.testing.assert_array_equal(got, reference(scene, *slab, FRAME))
    z = part[:, :, 2]
    if z.min() < slab[0] and z.max() > slab[1]:  # it crosses the slab: somewhere (maybe off FRAME) it shows
        lo, hi = part.reshape(-1, 3).min(axis=0), part.reshape(-1, 3).max(axis=0)
        around = GridFrame.around(lo[0], lo[1], hi[0], hi[1], resolution_m=0.05)
        assert run(scene, *slab, around).any()


@FAST
@given(part=open_quads(), slab=slabs)
def test_open_surfaces_match_the_reference(part, slab):
    scene = Scene()
    scene.add(False, part)
    np.testing.assert_array_equal(run(scene, *slab, FRAME), reference(scene, *slab, FRAME))


@FAST
@given(scene=scenes(), slab=slabs)
def test_mixed_scenes_match_the_reference(scene, slab):
    np.testing.assert_array_equal(run(scene, *slab, FRAME), reference(scene, *slab, FRAME))


@FAST
@given(centre=st.tuples(coord_x, coord_y, st.floats(0.2, 1.5)), radius=st.floats(0.05, 0.9), slab=slabs)
def test_a_sphere_is_filled_exactly(centre, radius, slab):
    scene = Scene()
    scene.add(True, sphere(centre, radius))
    np.testing.assert_array_equal(run(scene, *slab, FRAME), reference(scene, *slab, FRAME))


@FAST
@given(
    centre=st.tuples(coord_x, coord_y, st.floats(0.0, 1.5)),
    slope=st.floats(0.1, 0.8),
    yaw=angles,
    slab=slabs,
)
def test_a_ramp_is_filled_exactly(centre, slope, yaw, slab):
    scene = Scene()
    scene.add(True, box(centre, (0.9, 2.0, 0.15), yaw=yaw, tilt=slope))
    np.testing.assert_array_equal(run(scene, *slab, FRAME), reference(scene, *slab, FRAME))


def test_a_table_shows_its_legs_below_the_top_and_its_top_above():
    legs = [box((x, y, 0.37), (0.06, 0.06, 0.74)) for x in (0.63, 1.57) for y in (0.53, 1.27)]
    top = box((1.1, 0.9, 0.76), (1.2, 0.9, 0.05))
    scene = Scene()
    scene.add(True, top, *legs)
    low = run(scene, 0.05, 0.5, FRAME)
    np.testing.assert_array_equal(low, reference(scene, 0.05, 0.5, FRAME))
    assert low.sum() == sum(run_single(leg, 0.05, 0.5).sum() for leg in legs)  # four separate legs
    high = run(scene, 0.05, 1.5, FRAME)
    np.testing.assert_array_equal(high, reference(scene, 0.05, 1.5, FRAME))
    np.testing.assert_array_equal(high, run_single(top, 0.05, 1.5))  # the top covers the legs


def run_single(part: np.ndarray, z_lo: float, z_hi: float) -> np.ndarray:
    scene = Scene()
    scene.add(True, part)
    return run(scene, z_lo, z_hi, FRAME)


def test_overlapping_closed_parts_of_one_element_do_not_cancel():
    # A cross of two boxes, one element: the middle lies inside both shells (winding number 2).
    a = box((1.5, 1.3, 1.0), (2.0, 0.6, 2.0), yaw=0.3)
    b = box((1.5, 1.3, 1.0), (0.6, 2.0, 2.0), yaw=0.3)
    scene = Scene()
    scene.add(True, a, b)
    got = run(scene, 0.5, 0.6, FRAME)
    np.testing.assert_array_equal(got, reference(scene, 0.5, 0.6, FRAME))
    res = FRAME.resolution_m
    centre = (int((1.3 - FRAME.origin_y) / res), int((1.5 - FRAME.origin_x) / res))
    assert got[centre]


@FAST
@given(yaw=st.floats(0.0, 90.0), shift=st.tuples(st.floats(0.0, 0.5), st.floats(0.0, 0.5)), slab=slabs)
def test_a_concave_solid_from_a_boolean_union_is_filled_exactly(yaw, shift, slab):
    manifold3d = pytest.importorskip("manifold3d")

    def triangles(solid) -> np.ndarray:
        mesh = solid.rotate([0.0, 0.0, yaw]).translate([shift[0], shift[1], 0.1]).to_mesh()
        return np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3][np.asarray(mesh.tri_verts)]

    arm = manifold3d.Manifold.cube([2.0, 0.5, 2.0]).translate([0.5, 0.5, 0.0])
    leg = manifold3d.Manifold.cube([0.5, 1.5, 2.0]).translate([0.5, 0.5, 0.0])
    solid = Scene()
    solid.add(True, triangles(arm + leg))  # one watertight L-shaped shell
    parts = Scene()
    parts.add(True, triangles(arm), triangles(leg))  # the same solid as two convex parts
    np.testing.assert_array_equal(run(solid, *slab, FRAME), reference(parts, *slab, FRAME))


def test_overlapping_elements_do_not_cancel():
    scene = Scene()
    scene.add(True, box((1.4, 1.3, 1.0), (1.0, 1.0, 2.0)))
    scene.add(True, box((1.6, 1.3, 1.0), (1.0, 1.0, 2.0), yaw=0.2))
    np.testing.assert_array_equal(run(scene, 0.5, 0.6, FRAME), reference(scene, 0.5, 0.6, FRAME))


# -- grid alignment, thin and touching geometry ----------------------------------------------------

ALIGNED = GridFrame(origin_x=0.0, origin_y=0.0, resolution_m=0.05, width=60, height=70)


def test_a_wall_on_grid_lines_occupies_exactly_its_four_columns():
    scene = Scene()
    scene.add(True, box((1.1, 1.5, 1.5), (0.2, 2.0, 3.0)))  # x in [1.0, 1.2], y in [0.5, 2.5]
    got = run(scene, 0.1, 1.5, ALIGNED)
    assert np.flatnonzero(got.any(axis=0)).tolist() == [20, 21, 22, 23]
    assert np.flatnonzero(got.any(axis=1)).tolist() == list(range(10, 50))
    assert got.sum() == 4 * 40


def test_an_open_quad_exactly_on_a_grid_line_still_occupies_both_neighbours():
    scene = Scene()
    scene.add(False, quad((1.0, 0.31), (1.0, 0.69), 0.0, 2.0))
    got = run(scene, 0.1, 1.5, ALIGNED)
    assert np.flatnonzero(got.any(axis=0)).tolist() == [19, 20]
    assert np.flatnonzero(got.any(axis=1)).tolist() == list(range(6, 14))


def test_geometry_within_a_micrometre_of_grid_lines_is_on_them():
    # a wall 0.4 um to either side of its lines, and a horizontal open sliver 0.6 um wide across x = 1.5
    scene = Scene()
    scene.add(True, box((1.1 + 4e-7, 1.5 - 4e-7, 1.5), (0.2, 2.0, 3.0)))
    moved = run(scene, 0.1, 1.5, ALIGNED)
    on = Scene()
    on.add(True, box((1.1, 1.5, 1.5), (0.2, 2.0, 3.0)))
    np.testing.assert_array_equal(moved, run(on, 0.1, 1.5, ALIGNED))
    sliver = np.array([[[1.5 - 2e-7, 0.31, 0.7], [1.5 + 4e-7, 0.31, 0.7], [1.5 + 4e-7, 0.69, 0.7]]])
    open_ = Scene()
    open_.add(False, sliver)
    got = run(open_, 0.1, 1.5, ALIGNED)  # flattened onto the line: degenerate, so it keeps both sides
    assert np.flatnonzero(got.any(axis=0)).tolist() == [29, 30]


def test_a_horizontal_open_face_on_grid_lines_stays_inside_them():
    face = np.array(
        [
            [[1.0, 0.5, 0.7], [1.2, 0.5, 0.7], [1.2, 1.0, 0.7]],
            [[1.0, 0.5, 0.7], [1.2, 1.0, 0.7], [1.0, 1.0, 0.7]],
        ]
    )
    scene = Scene()
    scene.add(False, face)
    got = run(scene, 0.0, 1.0, ALIGNED)
    assert got.sum() == 4 * 10
    assert got[10:20, 20:24].all()


@FAST
@given(x=st.floats(0.5, 2.0), width=st.floats(0.005, 0.3), yaw=st.sampled_from([0.0, 0.4, math.pi / 2]))
def test_walls_that_touch_leave_no_gap(x, width, yaw):
    # Two boxes sharing the face x = x (in the rotated frame) cover what one box of both widths covers.
    def slab_box(x0, x1):
        centre = np.array([(x0 + x1) / 2 - 1.25, 0.0])
        c, s = math.cos(yaw), math.sin(yaw)
        cx, cy = 1.5 + c * centre[0] - s * centre[1], 1.3 + s * centre[0] + c * centre[1]
        return box((cx, cy, 1.0), (x1 - x0, 1.2, 2.0), yaw=yaw)

    two = Scene()
    two.add(True, slab_box(x - width, x))
    two.add(True, slab_box(x, x + width))
    one = Scene()
    one.add(True, slab_box(x - width, x + width))
    got = run(two, 0.4, 0.9, FRAME)
    np.testing.assert_array_equal(got, reference(two, 0.4, 0.9, FRAME))
    assert (got | run(one, 0.4, 0.9, FRAME)).sum() == got.sum()  # nothing of the whole is missing


# -- composition, windows, slabs -------------------------------------------------------------------


@FAST
@given(scene=scenes(), slab=slabs)
def test_the_map_of_many_elements_is_the_union_of_single_element_maps(scene, slab):
    union = np.zeros(FRAME.shape, dtype=bool)
    for e in range(len(scene.closed)):
        single = scene.only(e)
        single.closed = [scene.closed[e] if i == e else False for i in range(len(scene.closed))]
        union |= run(single, *slab, FRAME)
    np.testing.assert_array_equal(run(scene, *slab, FRAME), union)


@FAST
@given(scene=scenes(), slab=slabs, data=st.data())
def test_any_window_equals_the_same_slice_of_the_full_map_bit_for_bit(scene, slab, data):
    r0 = data.draw(st.integers(0, FRAME.height))
    c0 = data.draw(st.integers(0, FRAME.width))
    win = Window(r0, c0, data.draw(st.integers(r0, FRAME.height)), data.draw(st.integers(c0, FRAME.width)))
    full = run(scene, *slab, FRAME)
    want = full[win.row0 : win.row1, win.col0 : win.col1]
    np.testing.assert_array_equal(run(scene, *slab, FRAME, win), want)
    tri, el, closed = scene.arrays()
    geometry = slab_geometry(tri, el, closed, *slab, FRAME)
    np.testing.assert_array_equal(rasterize(geometry, FRAME, win), want)
    np.testing.assert_array_equal(rasterize(geometry, FRAME), full)
    # Only the elements whose bounds meet the window (grown by a cell) matter there.
    res = FRAME.resolution_m
    x0, y0 = FRAME.origin_x + (win.col0 - 1) * res, FRAME.origin_y + (win.row0 - 1) * res
    x1, y1 = FRAME.origin_x + (win.col1 + 1) * res, FRAME.origin_y + (win.row1 + 1) * res
    lo = np.full((len(closed), 2), np.inf)
    hi = np.full((len(closed), 2), -np.inf)
    np.minimum.at(lo, el, tri[:, :, :2].min(axis=1))
    np.maximum.at(hi, el, tri[:, :, :2].max(axis=1))
    meets = (hi[:, 0] >= x0) & (hi[:, 1] >= y0) & (lo[:, 0] <= x1) & (lo[:, 1] <= y1)
    near = meets[el]
    np.testing.assert_array_equal(rasterize_slab(tri[near], el[near], closed, *slab, FRAME, win), want)


TINY = RasterSettings(chunk_triangles=7, chunk_polygons=5, chunk_pairs=16, tile_m=0.3, block=3)


@settings(max_examples=20, deadline=None)
@given(scene=scenes(max_elements=8), slab=slabs)
def test_small_chunks_and_index_blocks_give_the_same_map(scene, slab):
    full = run(scene, *slab, FRAME)
    tri, el, closed = scene.arrays()
    win = Window(7, 11, 40, 50)
    np.testing.assert_array_equal(rasterize_slab(tri, el, closed, *slab, FRAME, settings=TINY), full)
    np.testing.assert_array_equal(
        rasterize_slab(tri, el, closed, *slab, FRAME, win, settings=TINY), full[7:40, 11:50]
    )
    geometry = slab_geometry(tri, el, closed, *slab, FRAME, settings=TINY)
    np.testing.assert_array_equal(rasterize(geometry, FRAME, settings=TINY), full)
    np.testing.assert_array_equal(rasterize(geometry, FRAME, win, settings=TINY), full[7:40, 11:50])
    # the geometry keeps its own index block size, whatever chunk sizes rasterise it
    np.testing.assert_array_equal(rasterize(geometry, FRAME, win), full[7:40, 11:50])


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"chunk_triangles": 0}, r"chunk_triangles must be a positive integer, got 0"),
        ({"block": 2.5}, r"block must be a positive integer, got 2.5"),
        ({"chunk_pairs": True}, r"chunk_pairs must be a positive integer, got True"),
        ({"tile_m": float("nan")}, r"tile_m must be a positive, finite number of metres, got nan"),
        ({"tile_m": 0.0}, r"tile_m must be a positive, finite number of metres, got 0.0"),
    ],
)
def test_unusable_raster_settings_are_refused(change, match):
    with pytest.raises(MapError, match=match):
        RasterSettings(**change)


def test_an_element_entirely_above_or_below_the_slab_contributes_nothing():
    scene = Scene()
    scene.add(True, box((1.0, 1.0, 2.5), (0.5, 0.5, 0.9)))  # z in [2.05, 2.95]
    scene.add(False, quad((0.5, 0.5), (1.5, 0.6), -1.0, -0.2))
    assert not run(scene, 0.0, 2.0, FRAME).any()
    assert not run(scene, 3.0, 3.5, FRAME).any()


def test_a_box_straddling_the_slab_counts_and_one_only_touching_its_end_does_not():
    scene = Scene()
    scene.add(True, box((1.0, 1.0, 1.0), (0.5, 0.5, 2.0)))  # z in [0, 2]
    footprint = run(scene, 0.5, 0.6, FRAME)
    assert footprint.any()
    np.testing.assert_array_equal(run(scene, -1.0, 3.0, FRAME), footprint)
    np.testing.assert_array_equal(run(scene, 1.9, 2.5, FRAME), footprint)  # its top lies in the slab
    np.testing.assert_array_equal(run(scene, 1.0, 1.0, FRAME), footprint)  # a zero-thickness slab
    assert not run(scene, 2.0, 2.5, FRAME).any()  # resting on the slab's bottom: no space in it
    assert not run(scene, -0.5, 0.0, FRAME).any()  # hanging from its top


def test_an_open_surface_lying_on_the_slabs_end_is_in_it():
    scene = Scene()
    sheet = np.array(
        [
            [[0.5, 0.5, 1.0], [1.5, 0.5, 1.0], [1.5, 1.0, 1.0]],
            [[0.5, 0.5, 1.0], [1.5, 1.0, 1.0], [0.5, 1.0, 1.0]],
        ]
    )
    scene.add(False, sheet)  # a flat sheet at z = 1
    assert run(scene, 1.0, 1.5, FRAME).any()
    assert run(scene, 0.5, 1.0, FRAME).any()
    assert run(scene, 0.5, 1.0 - 6e-7, FRAME).any()  # within a micrometre
    assert not run(scene, 0.5, 1.0 - 2e-6, FRAME).any()


def test_a_solid_within_a_micrometre_of_the_slabs_end_is_on_it_and_one_farther_into_it_counts():
    # Boxes reaching 0.6 um into the slab only touch its end (no space in it); 2 um into it, they count.
    def reaching(depth: float) -> tuple[Scene, Scene]:
        below, above = Scene(), Scene()
        below.add(True, box((1.0, 1.0, 0.5 + depth / 2), (0.5, 0.5, 1.0 + depth)))  # z in [0, 1 + depth]
        above.add(True, box((1.0, 1.0, 2.5 - depth / 2), (0.5, 0.5, 1.0 + depth)))  # z in [2 - depth, 3]
        return below, above

    below, above = reaching(6e-7)
    assert not run(below, 1.0, 1.5, FRAME).any()
    assert not run(above, 1.5, 2.0, FRAME).any()
    below, above = reaching(2e-6)
    footprint = run(below, 0.0, 1.0, FRAME)
    assert footprint.any()
    np.testing.assert_array_equal(run(below, 1.0, 1.5, FRAME), footprint)
    np.testing.assert_array_equal(run(above, 1.5, 2.0, FRAME), footprint)


@FAST
@given(
    gap=st.sampled_from([-9e-7, -3e-7, 0.0, 2e-7, 8e-7, 3e-6, -3e-6, 0.01]),
    lift=st.sampled_from([0.0, 3.7, 1234.567, 1.0e4]),
    parts=st.lists(boxes(), min_size=1, max_size=3),
)
def test_a_building_raised_by_any_height_gives_the_same_cells_at_the_bands_ends(gap, lift, parts):
    # Parts reaching ``gap`` into the band from below and from above (or short of it), within or beyond
    # a micrometre, give the same cells with the storey at z = 0 and raised by ``lift``.
    z_lo, z_hi = 0.35, 1.2

    def scene_at(dz: float) -> Scene:
        scene = Scene()
        for part in parts:
            bottom, top = part[..., 2].min(), part[..., 2].max()
            resting = part.copy()
            resting[..., 2] += (z_lo + gap) - top + dz  # its top at the band's bottom (+ gap)
            hanging = part.copy()
            hanging[..., 2] += (z_hi - gap) - bottom + dz  # its bottom at the band's top (- gap)
            scene.add(True, resting)
            scene.add(True, hanging)
        return scene

    base = run(scene_at(0.0), z_lo, z_hi, FRAME)
    raised = run(scene_at(lift), lift + z_lo, lift + z_hi, FRAME)
    np.testing.assert_array_equal(raised, base)
    assert base.any() == (gap > 1e-6)  # within a micrometre of the end is on it: touching, no space


def test_no_triangles_give_an_empty_map():
    got = rasterize_slab(np.empty((0, 3, 3)), np.empty(0, np.intp), np.empty(0, bool), 0.0, 1.0, FRAME)
    assert got.shape == FRAME.shape
    assert not got.any()
    assert rasterize_slab(*Scene().arrays(), 0.0, 1.0, FRAME, Window(3, 3, 3, 9)).shape == (0, 6)


# -- validation ------------------------------------------------------------------------------------

GOOD = box((1.0, 1.0, 1.0), (0.5, 0.5, 2.0))
EL = np.zeros(12, np.intp)
CL = np.array([True])


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (
            (GOOD[:, :2], EL, CL, 0.0, 1.0),
            r"triangles must be an array of shape \(n, 3, 3\), got \(12, 2, 3\)",
        ),
        ((GOOD.tolist(), EL, CL, 0.0, 1.0), r"triangles must be an array of shape \(n, 3, 3\), got list"),
        ((GOOD.astype(np.float32), EL, CL, 0.0, 1.0), r"triangles must be float64, got float32"),
        ((GOOD, EL[:5], CL, 0.0, 1.0), r"element must be an array of shape \(12,\).*got \(5,\)"),
        ((GOOD, EL.astype(float), CL, 0.0, 1.0), r"element must have an integer dtype, got float64"),
        ((GOOD, EL, np.array([1]), 0.0, 1.0), r"closed must be a 1-d bool array.*int64"),
        ((GOOD, EL + 1, CL, 0.0, 1.0), r"element indices must lie in \[0, 1\), got \[1, 1\]"),
        ((GOOD, EL, CL, 1.0, 0.0), r"z_lo <= z_hi, got z_lo=1.0, z_hi=0.0"),
        ((GOOD, EL, CL, float("nan"), 1.0), r"Slab must be finite.*z_lo=nan"),
    ],
)
def test_malformed_arguments_raise_a_map_error_naming_them(args, match):
    with pytest.raises(MapError, match=match):
        rasterize_slab(*args, FRAME)


def test_a_non_finite_vertex_is_named():
    bad = GOOD.copy()
    bad[7, 1, 0] = np.inf
    with pytest.raises(MapError, match=r"triangles must be finite, triangle 7 is"):
        rasterize_slab(bad, EL, CL, 0.0, 1.0, FRAME)


def test_a_window_outside_the_grid_is_refused():
    with pytest.raises(MapError, match=r"Window .* must lie inside the grid of 56x64 cells"):
        rasterize_slab(GOOD, EL, CL, 0.0, 1.0, FRAME, Window(0, 0, 57, 10))


@pytest.mark.parametrize(
    "extent",
    [(-1e308, 0.0, 1e308, 10.0), (0.0, 0.0, 1e6, 1e6), (0.0, 0.0, math.inf, 1.0)],
    ids=["overflowing", "too-many-cells", "infinite"],
)
def test_a_frame_around_an_absurd_extent_raises_a_map_error(
    extent: tuple[float, float, float, float],
) -> None:
    with pytest.raises(MapError, match="Grid extent"):
        GridFrame.around(*extent, resolution_m=0.05)
