"""The points maps of the sample lab and the shared models are exact against a reference in world
coordinates written apart (tests/twin/world_reference.py: the grid as exact decimals, a coordinate
within 1 um of a plane on it, rational separating axes, half-open voxels): every triangle of the lab,
and a sample of each shared model's storeys (faces lying in grid planes included) give 0 missed, 0
extra. The older check in cell coordinates (tests/twin/reference_voxels.py) stays. (That a cloud is the
union of its triangles' voxels, one point each, is tests/twin/maps/test_points.py's.) Slow: the models
are read with ifcopenshell (skipped when ../shared is absent)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import SHARED_MODELS, imported, shared_model
from tests.twin.reference_voxels import reference_voxels
from tests.twin.world_reference import WorldGrid
from twin.graph.rdf import literal_value
from twin.maps.points import PointsPlan, _near_band, build_points, estimate_points, plan_points
from twin.maps.scene import load_scene
from twin.maps.voxels import IntArray, touched_voxels
from twin.records import BuildingModel
from twin.samples.lab_layout import LabLayout
from twin.selection.skill_selection import selection_query
from twin.selection.skills import parse_skill

pytestmark = pytest.mark.slow

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
SAMPLE = 40
"""Triangles per storey checked against the reference (its Python loops take ~40 us per voxel)."""
MAX_BOX_VOXELS = 600
"""Sampled triangles have at most this many voxels in their bounding box (the reference tests each)."""


def _world_grid(plan: PointsPlan) -> WorldGrid:
    f = plan.frame
    return WorldGrid((f.origin_x, f.origin_y), plan.storey.elevation_m, plan.resolution_m, plan.band)


def _ijk(tri: IntArray, ijk: IntArray, n: int) -> set[tuple[int, int, int]]:
    return {(int(i), int(j), int(k)) for i, j, k in ijk[tri == n]}


def test_every_triangle_of_the_sample_lab_touches_exactly_the_voxels_of_the_world_reference(
    lab2: tuple[Path, LabLayout], read_cached: Callable[[Path], BuildingModel]
) -> None:
    store = imported(read_cached(lab2[0]))
    scene = load_scene(store)
    skill = parse_skill("lidar3d", LIDAR)
    iris = [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]
    for storey in scene.storeys:
        plan = plan_points(scene, skill, storey.key, iris)
        got = {(int(i), int(j), int(k)) for i, j, k in plan.ijk(build_points(scene, plan).keys)}
        triangles, _ = scene.elements.triangles_of(plan.selected)
        ref = _world_grid(plan).voxels(triangles, lo=plan.lo, hi=plan.hi)
        assert (len(ref - got), len(got - ref)) == (0, 0), storey.key
        assert len(ref) > 20_000
        # the reference sees what cell coordinates taken from float64 as they come (the old way) did
        origin = np.array([plan.frame.origin_x, plan.frame.origin_y, storey.elevation_m])
        naive = (triangles - origin) / plan.resolution_m
        w_band = (plan.band[0] / plan.resolution_m, plan.band[1] / plan.resolution_m)
        tri, ijk = touched_voxels(naive, lo=plan.lo, hi=plan.hi, w_band=w_band)
        old = _ijk(np.zeros(len(tri), dtype=np.int64), ijk, 0)
        assert len(ref ^ old) > 1000, storey.key


@pytest.mark.parametrize("name", SHARED_MODELS)
def test_sampled_triangles_of_every_shared_model_touch_exactly_the_voxels_of_the_world_reference(
    name: str, read_cached: Callable[[Path], BuildingModel]
) -> None:
    """Small triangles anywhere, and faces lying in a grid plane (ties on every voxel they touch)."""
    store = imported(read_cached(shared_model(name)))
    scene = load_scene(store)
    skill = parse_skill("lidar3d", LIDAR)
    iris = [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]
    rng = np.random.default_rng(40)
    checked = on_plane = 0
    for storey in scene.storeys:
        plan = plan_points(scene, skill, storey.key, iris)
        triangles, _ = _near_band(scene.elements, plan.selected, plan)
        cells = plan.cells(triangles)
        span = np.floor(cells.max(axis=1)) - np.floor(cells.min(axis=1)) + 1
        small = span.prod(axis=1) <= MAX_BOX_VOXELS
        flat = (cells == cells[:, :1]).all(axis=1) & (cells[:, 0] == np.rint(cells[:, 0]))  # (t, axis)
        planar = np.flatnonzero(small & flat.any(axis=1))
        picks = [
            rng.choice(planar, size=min(SAMPLE // 2, len(planar)), replace=False),
            rng.choice(np.flatnonzero(small), size=min(SAMPLE, int(small.sum())), replace=False),
        ]
        pick = np.concatenate(picks).astype(np.int64)
        tri, ijk = touched_voxels(cells[pick], lo=plan.lo, hi=plan.hi, w_band=plan.w_band, shift=plan.shift)
        grid = _world_grid(plan)
        for n, t in enumerate(pick):
            ref = grid.triangle_voxels(triangles[t], lo=plan.lo, hi=plan.hi)
            got = _ijk(tri, ijk, n)
            assert (sorted(ref - got), sorted(got - ref)) == ([], []), f"{name} {storey.key} triangle {t}"
        checked += len(pick)
        on_plane += len(picks[0])
    assert checked >= min(SAMPLE, 20) and on_plane >= 10


@pytest.mark.parametrize("name", SHARED_MODELS)
def test_every_storeys_voxels_equal_the_reference_on_a_sample_of_triangles(
    name: str, read_cached: Callable[[Path], BuildingModel]
) -> None:
    store = imported(read_cached(shared_model(name)))
    scene = load_scene(store)
    skill = parse_skill("lidar3d", LIDAR)
    iris = [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]
    rng = np.random.default_rng(32)
    checked = 0
    for storey in scene.storeys:
        plan = plan_points(scene, skill, storey.key, iris)
        triangles, _ = _near_band(scene.elements, plan.selected, plan)
        cells = plan.cells(triangles)
        span = np.floor(cells.max(axis=1)) - np.floor(cells.min(axis=1)) + 1
        small = np.flatnonzero(span.prod(axis=1) <= MAX_BOX_VOXELS)
        pick = rng.choice(small, size=min(SAMPLE, len(small)), replace=False) if len(small) else small
        tri, ijk = touched_voxels(cells[pick], lo=plan.lo, hi=plan.hi, w_band=plan.w_band, shift=plan.shift)
        for n, t in enumerate(pick):
            got = {(int(i), int(j), int(k)) for i, j, k in ijk[tri == n]}
            ref = reference_voxels(cells[t], plan.lo, plan.hi, plan.w_band, shift=plan.shift)
            assert (sorted(ref - got), sorted(got - ref)) == ([], []), f"{name} {storey.key} triangle {t}"
            checked += 1
    assert checked >= min(SAMPLE, 20)


@pytest.mark.parametrize("name", ["lab", *SHARED_MODELS])
def test_the_estimated_points_are_within_a_factor_of_two_of_the_built_cloud(
    name: str, lab2: tuple[Path, LabLayout], read_cached: Callable[[Path], BuildingModel]
) -> None:
    store = imported(read_cached(lab2[0] if name == "lab" else shared_model(name)))
    scene = load_scene(store)
    skills = [parse_skill("lidar3d", LIDAR), parse_skill("all3d", {"kind": "points", "resolution_m": 0.2})]
    if "janesville" in name:  # (its clouds of every element, 2 M triangles of furniture, take 25 s)
        skills = [parse_skill("lidar3d", {**LIDAR, "resolution_m": 0.2})]
    for skill in skills:
        iris = [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]
        for storey in scene.storeys:
            plan = plan_points(scene, skill, storey.key, iris)
            built, estimate = len(build_points(scene, plan)), estimate_points(scene, plan)
            assert built / 2 <= estimate <= 2 * built, (skill.name, storey.key, estimate, built)
