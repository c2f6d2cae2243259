"""Point-cloud maps for 3D lidars: the points skill, the exact voxels surfaces touch (against a reference
written apart, tests/twin/reference_voxels.py) and one point per voxel, in the storey's frame."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.conftest import examples
from tests.twin.box_lab import element_iri, spec
from tests.twin.reference_voxels import reference_voxels
from twin.errors import MapError, SkillError
from twin.graph.rdf import literal_value
from twin.graph.store import GraphStore
from twin.maps.nearest import nearest_points
from twin.maps.points import (
    PointsPlan,
    Voxels,
    best_per_voxel,
    best_rows,
    build_points,
    plan_points,
    voxels_by_element,
    voxels_of,
)
from twin.maps.scene import Scene, load_scene
from twin.maps.voxels import _max3, _min3, _one_axis, _ten_axes, touched_voxels
from twin.selection.skill_selection import selection_query
from twin.selection.skills import SkillProfile, parse_skill

LIDAR = {
    "kind": "points",
    "exclude_types": [
        "IfcOpeningElement",
        "IfcFurnishingElement",
        "IfcBuildingElementProxy",
        "IfcFlowTerminal",
    ],
    "exclude_materials": ["glass"],
}
LO, HI = (0, 0, -1), (6, 6, 5)


def _coordinates(kind: int) -> st.SearchStrategy[float]:
    if kind == 0:
        return st.floats(-2.0, 7.0, allow_nan=False)
    if kind == 1:
        return st.integers(-2, 7).map(float)  # on the grid: ties on every axis
    return st.integers(-4, 14).map(lambda v: v / 2)  # on faces and half-way


@st.composite
def triangles(draw: st.DrawFn) -> npt.NDArray[np.float64]:
    kind = draw(st.integers(0, 3))
    if kind == 3:  # a sliver: a nearly straight triangle
        a = np.array(draw(st.lists(_coordinates(0), min_size=3, max_size=3)))
        b = np.array(draw(st.lists(_coordinates(0), min_size=3, max_size=3)))
        nudge = draw(st.sampled_from([0.0, 1e-12, 1e-7]))
        return np.array([a, b, (a + b) / 2 + nudge])
    coords = draw(st.lists(_coordinates(kind), min_size=9, max_size=9))
    tri = np.array(coords, dtype=np.float64).reshape(3, 3)
    if draw(st.booleans()):  # in an axis-aligned plane, as building faces are
        axis = draw(st.integers(0, 2))
        tri[:, axis] = draw(_coordinates(kind))
    return tri


BANDS = st.tuples(st.sampled_from([-1.0, -0.5, 0.0, 0.25]), st.sampled_from([3.0, 4.5, 5.0]))


@settings(max_examples=examples(300), deadline=None, suppress_health_check=list(HealthCheck))
@given(triangles(), BANDS)
def test_the_voxels_a_triangle_touches_are_exactly_the_references(
    tri: npt.NDArray[np.float64], band: tuple[float, float]
) -> None:
    _, ijk = touched_voxels(tri[None], lo=LO, hi=HI, w_band=band)
    got = {(int(i), int(j), int(k)) for i, j, k in ijk}
    ref = reference_voxels(tri, LO, HI, band)
    assert sorted(ref - got) == [], "voxels missed"
    assert sorted(got - ref) == [], "extra voxels"


SHIFTS = st.sampled_from([(3.09017e-8, 5e-6), (3.09017e-9, 5e-7), (0.000309017, 0.05)])
"""Faces moved as points maps move them at 0.1 m and 1 m (3.1 nm, 0.5 um), and by a fraction of a cell."""


@settings(max_examples=examples(200), deadline=None, suppress_health_check=list(HealthCheck))
@given(triangles(), BANDS, SHIFTS)
def test_the_voxels_a_snapped_triangle_touches_with_the_faces_moved_are_exactly_the_references(
    tri: npt.NDArray[np.float64], band: tuple[float, float], shift: tuple[float, float]
) -> None:
    # what points maps test: coordinates within the moves of a grid plane are on it (grid_coordinates)
    # first, then the voxel's lower faces are moved out and its upper faces in
    snap = 2 * max(shift)
    tri = np.where(np.abs(tri - np.rint(tri)) <= snap, np.rint(tri), tri)
    for end in band:  # and the band's ends
        tri[:, 2] = np.where(np.abs(tri[:, 2] - end) <= snap, end, tri[:, 2])
    _, ijk = touched_voxels(tri[None], lo=LO, hi=HI, w_band=band, shift=shift)
    got = {(int(i), int(j), int(k)) for i, j, k in ijk}
    ref = reference_voxels(tri, LO, HI, band, shift=shift)
    assert sorted(ref - got) == [], "voxels missed"
    assert sorted(got - ref) == [], "extra voxels"


@settings(max_examples=examples(150), deadline=None, suppress_health_check=list(HealthCheck))
@given(st.lists(_coordinates(2), min_size=9, max_size=9), st.integers(-1, 2), _coordinates(2), BANDS)
def test_on_exact_geometry_the_moved_faces_give_the_half_open_rules_verdict(
    coords: list[float], level: int, value: float, band: tuple[float, float]
) -> None:
    # vertices on halves of a cell (exact in float): through grid edges and corners at every slope these
    # give, the faces moved as points maps move them (3.1 nm and 0.5 um at 0.1 m) change no verdict
    tri = np.array(coords).reshape(3, 3)
    if level >= 0:  # in an axis-aligned plane, as building faces are
        tri[:, level] = value
    _, ijk = touched_voxels(tri[None], lo=LO, hi=HI, w_band=band, shift=(3.09017e-8, 5e-6))
    got = {(int(i), int(j), int(k)) for i, j, k in ijk}
    assert got == reference_voxels(tri, LO, HI, band)


@settings(max_examples=examples(150), deadline=None, suppress_health_check=list(HealthCheck))
@given(triangles(), BANDS)
def test_each_point_lies_in_its_voxel_on_the_triangle_and_no_farther_than_the_centres_projection(
    tri: npt.NDArray[np.float64], band: tuple[float, float]
) -> None:
    t, ijk = touched_voxels(tri[None], lo=LO, hi=HI, w_band=band)
    if not len(t):
        return
    q, d2 = nearest_points(tri[None][t], ijk, w_band=band)
    lo = ijk.astype(float)
    lo[:, 2] = np.maximum(lo[:, 2], band[0])
    hi = ijk + 1.0
    hi[:, 2] = np.minimum(hi[:, 2], band[1])
    assert ((q >= lo) & (q <= hi)).all()
    # on the triangle: barycentric coordinates in [0, 1] (within rounding), or on its line if degenerate
    n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    if np.linalg.norm(n) > 1e-3:  # (a sliver's plane is too ill-conditioned to measure against)
        dist = np.abs((q - tri[0]) @ n) / np.linalg.norm(n)
        assert dist.max() < 1e-8  # cell units: a nanometre at 0.1 m
    centre = (lo + hi) / 2
    assert np.allclose(((q - centre) ** 2).sum(axis=1), d2)
    # no vertex of the triangle inside a voxel is nearer its centre than the chosen point
    for v in tri:
        inside = ((v >= lo) & (v <= hi)).all(axis=1)
        assert (((v - centre[inside]) ** 2).sum(axis=1) >= d2[inside] - 1e-9).all()


@settings(max_examples=examples(100), deadline=None, suppress_health_check=list(HealthCheck))
@given(st.lists(triangles(), min_size=1, max_size=8), st.integers(0, 2**32 - 1))
def test_the_ten_separating_axes_tested_at_once_or_one_by_one_give_the_same_verdicts(
    tris: list[npt.NDArray[np.float64]], seed: int
) -> None:
    # few pairs take the ten axes at once, many take them one by one: the same numbers either way
    rng = np.random.default_rng(seed)
    v = np.repeat(np.array(tris), 20, axis=0)
    m = len(v)
    lo = rng.integers(-1, 6, (m, 3)).astype(np.float64)
    hi = lo + 1.0
    hi[:, 2] = np.minimum(hi[:, 2], 4.5)  # some boxes cut by a band
    rel, size = v - lo[:, None, :], hi - lo
    e = np.stack([v[:, 1] - v[:, 0], v[:, 2] - v[:, 1], v[:, 0] - v[:, 2]], axis=1)
    big_v = 1.0 + _max3(np.maximum(np.abs(_min3(v)), np.abs(_max3(v))))
    big_r = 1.0 + _max3(np.maximum(np.abs(_min3(rel)), np.abs(_max3(rel))))
    reach = 1.0 + _max3(np.maximum(np.abs(_min3(e)), np.abs(_max3(e))))
    apart, near = _ten_axes(e, rel, size, big_v=big_v, big_r=big_r, reach=reach)
    one_apart, one_near = np.zeros(m, dtype=np.bool_), np.zeros((m, 10), dtype=np.bool_)
    for n_axis in range(10):
        _one_axis(n_axis, one_apart, one_near, e=e, rel=rel, size=size, big_v=big_v, big_r=big_r, reach=reach)
    np.testing.assert_array_equal(apart, one_apart)
    np.testing.assert_array_equal(near[~apart], one_near[~apart])  # ties matter where no axis separates


def test_a_points_skill_defaults_to_a_decimetre_and_a_band_from_below_the_floor_to_the_next_storey(
    box_store2: GraphStore,
) -> None:
    skill = parse_skill("lidar3d", LIDAR)
    assert (skill.resolution_m, skill.band_bottom_m, skill.band_top_m) == (0.1, -0.05, None)
    scene = load_scene(box_store2)
    ground, first = scene.storeys
    plan = plan_points(scene, skill, ground.key, _iris(box_store2, skill))
    assert plan.band == (-0.05, pytest.approx(first.elevation_m - ground.elevation_m))
    assert skill.to_json()["kind"] == "points" and "band_top_m" not in skill.to_json()


@pytest.mark.parametrize(
    ("data", "words"),
    [
        ({"kind": "points", "band_bottom_m": 2.0, "band_top_m": 1.0}, r"'band_top_m' \(1.0\) must be above"),
        ({"kind": "points", "resolution_m": 0.001}, "must be >= 0.01"),
        ({"kind": "points", "lidar_height_m": 1.0}, "unknown field 'lidar_height_m'"),
        ({"kind": "points", "band_top_m": "high"}, "'band_top_m' must be a finite number"),
    ],
)
def test_a_bad_points_profile_is_refused_naming_the_field(data: dict[str, object], words: str) -> None:
    with pytest.raises(SkillError, match=words):
        parse_skill("bad", data)


def test_a_2d_skill_cannot_plan_a_points_map(box_store: GraphStore) -> None:
    scene = load_scene(box_store)
    with pytest.raises(MapError, match="not a points skill"):
        plan_points(scene, parse_skill("nav", {"kind": "navigation"}), scene.storeys[0].key, [])


def _iris(store: GraphStore, skill: SkillProfile) -> list[str]:
    return [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]


def _plan(store: GraphStore, **extra: object) -> tuple[Scene, PointsPlan]:
    scene = load_scene(store)
    skill = parse_skill("lidar3d", {**LIDAR, **extra})
    return scene, plan_points(scene, skill, scene.storeys[0].key, _iris(store, skill))


def test_the_lab_cloud_is_every_voxel_its_walls_and_floor_touch_and_nothing_else(
    box_store: GraphStore,
) -> None:
    scene, plan = _plan(box_store, resolution_m=0.25)
    cloud = build_points(scene, plan)
    expected: set[tuple[int, int, int]] = set()
    for tri in plan.cells(scene.elements.triangles_of(plan.selected)[0]):
        expected |= reference_voxels(tri, plan.lo, plan.hi, plan.w_band)
    got = {(int(i), int(j), int(k)) for i, j, k in plan.ijk(cloud.keys)}
    assert (len(got - expected), len(expected - got)) == (0, 0)
    assert np.all(np.diff(cloud.keys) > 0)
    # x, y in the map frame (world), z above the storey: the floor's top is in, at z = 0
    assert cloud.xyz[:, 2].min() == pytest.approx(-0.05) or cloud.xyz[:, 2].min() >= -0.05
    assert np.isclose(cloud.xyz[:, 2], 0.0).sum() > 100


def test_glass_and_furniture_are_left_out_and_the_same_twin_gives_the_same_cloud(
    box_store: GraphStore,
) -> None:
    scene, plan = _plan(box_store)
    one, two = build_points(scene, plan), build_points(scene, plan)
    assert np.array_equal(one.keys, two.keys) and np.array_equal(one.xyz, two.xyz)
    table = scene.elements.index[element_iri(spec("Table"))]
    assert table not in plan.selected
    tri, _ = scene.elements.triangles_of(np.array([table]))
    own = voxels_of(plan, tri)
    assert len(own) and not np.isin(own.keys, one.keys).all()


def test_the_cloud_is_the_union_of_its_elements_voxels_each_with_its_nearest_point(
    box_store: GraphStore,
) -> None:
    scene, plan = _plan(box_store)
    cloud = build_points(scene, plan)
    parts = voxels_by_element(scene.elements, plan.selected, plan)
    merged = best_per_voxel(Voxels.concat(parts))
    assert np.array_equal(merged.keys, cloud.keys)
    assert np.array_equal(plan.to_xyz(merged.q), cloud.xyz)
    # where elements share a voxel (walls meeting the floor), the point is the one nearest its centre
    keys, counts = np.unique(np.concatenate([p.keys for p in parts]), return_counts=True)
    shared = keys[counts > 1]
    assert len(shared) > 50
    for p in parts:
        mine = np.isin(p.keys, shared)
        rows = np.searchsorted(merged.keys, p.keys[mine])
        assert np.all(merged.d2[rows] <= p.d2[mine])
    assert np.array_equal(merged.n, cloud.normals)


def _box(lo: npt.NDArray[np.float64], hi: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """A closed box's 12 triangles, wound counter-clockwise seen from outside (outward normals)."""
    c = np.array([[(hi if (i >> a) & 1 else lo)[a] for a in range(3)] for i in range(8)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    return np.array([c[[a, b, d]] for a, b, e, d in quads] + [c[[b, e, d]] for a, b, e, d in quads])


FACES = np.array([[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]], dtype=np.float32)


@settings(max_examples=examples(40), deadline=None, suppress_health_check=list(HealthCheck))
@given(
    st.tuples(*(st.integers(lo, 16).map(lambda v: v / 8) for lo in (-4, -4, 0))),  # in the band
    st.lists(st.integers(1, 16).map(lambda v: v / 8), min_size=3, max_size=3),
    st.randoms(use_true_random=False),
)
def test_each_point_has_the_outward_normal_of_a_face_it_lies_on_whatever_the_triangles_order(
    box_store: GraphStore, corner: tuple[float, float, float], size: list[float], rnd: object
) -> None:
    import random

    assert isinstance(rnd, random.Random)
    _, plan = _plan(box_store, resolution_m=0.25)
    lo = np.array(corner) + np.array([plan.frame.origin_x + 1.0, plan.frame.origin_y + 1.0, 0.0])
    hi = lo + np.array(size)
    tris = _box(lo, hi)
    v = voxels_of(plan, tris)
    assert len(v)
    # the same cloud, normals included, whatever the order of the triangles and of their vertices
    order = list(range(len(tris)))
    rnd.shuffle(order)
    shuffled = np.array([np.roll(tris[i], rnd.randrange(3), axis=0) for i in order])
    again = voxels_of(plan, shuffled)
    assert np.array_equal(again.keys, v.keys) and np.array_equal(again.q, v.q)
    assert np.array_equal(again.n, v.n)
    # each normal is the outward normal of a face the point lies on (on an edge or a corner of the box,
    # one of the faces there: the point nearest the centre, to the bit, then the smallest normal)
    p = plan.to_xyz(v.q)
    p[:, 2] += plan.storey.elevation_m
    offsets = np.array([-lo[0], hi[0], -lo[1], hi[1], -lo[2], hi[2]])
    on = np.abs(p @ FACES.T.astype(np.float64) - offsets) < 1e-9  # (points, faces)
    face = (v.n[:, None, :] == FACES[None, :, :]).all(axis=2)
    assert (face.sum(axis=1) == 1).all(), "not an axis-aligned unit normal"
    assert on[face].all(), "a normal of a face the point is not on"


def test_the_lab_clouds_normals_are_unit_and_the_floor_seen_from_above_faces_up(
    box_store: GraphStore,
) -> None:
    scene, plan = _plan(box_store)
    cloud = build_points(scene, plan)
    assert cloud.normals.dtype == np.float32 and cloud.normals.shape == (len(cloud), 3)
    assert np.allclose(np.linalg.norm(cloud.normals, axis=1), 1.0, atol=1e-6)
    assert not np.signbit(cloud.normals[cloud.normals == 0]).any()  # no -0.0: equal normals, equal bits
    # the floor's top (z = 0 above the storey) away from the walls: its outward normal is +z
    top = np.isclose(cloud.xyz[:, 2], 0.0)
    up = (cloud.normals[top] == np.array([0, 0, 1], dtype=np.float32)).all(axis=1)
    assert up.mean() > 0.9


def test_a_tie_on_the_point_goes_to_the_smallest_normal_and_a_degenerate_triangles_zero_normal_last() -> None:
    keys = np.array([7, 7, 7, 7, 9, 9], dtype=np.int64)
    q = np.array([[0.5, 0.5, 0.0]] * 4 + [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    d2 = np.array([0.25, 0.25, 0.25, 0.25, 0.5, 0.5])
    n = np.array([[0, 0, 1], [0, 0, 0], [0, 0, -1], [1, 0, 0], [0, 0, 0], [0, 1, 0]], dtype=np.float32)
    for order in ([0, 1, 2, 3, 4, 5], [5, 4, 3, 2, 1, 0], [3, 1, 0, 2, 5, 4]):
        rows = np.array(order)
        best = rows[best_rows(keys[rows], q[rows], d2[rows], n[rows])]
        assert n[best].tolist() == [[0, 0, -1], [0, 1, 0]]


def test_two_boxes_sharing_a_face_give_its_voxels_the_smaller_of_the_two_outward_normals(
    box_store: GraphStore,
) -> None:
    _, plan = _plan(box_store, resolution_m=0.25)
    o = np.array([plan.frame.origin_x + 1.0, plan.frame.origin_y + 1.0, 0.5])
    a = _box(o, o + np.array([1.0, 1.0, 1.0]))
    b = _box(o + np.array([1.0, 0.0, 0.0]), o + np.array([2.0, 1.0, 1.0]))
    one, two = voxels_of(plan, np.concatenate([a, b])), voxels_of(plan, np.concatenate([b, a]))
    assert np.array_equal(one.keys, two.keys) and np.array_equal(one.n, two.n)
    x = plan.to_xyz(one.q)[:, 0]
    shared = np.isclose(x, o[0] + 1.0) & (one.n[:, 0] != 0)  # on the shared face, the faces' normals x
    assert shared.sum() > 10
    assert (one.n[shared] == np.array([-1, 0, 0], dtype=np.float32)).all()  # b's -x, not a's +x
