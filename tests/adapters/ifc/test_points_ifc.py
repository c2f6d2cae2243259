"""The points maps of the shared models are exact: on every storey of each model, the voxels a sample of
the selected triangles touch are those of the reference written apart (tests/twin/reference_voxels.py:
per-triangle exact separating axes on a shrunk box, every voxel of the triangle's bounding box):
0 missed, 0 extra. (That a cloud is the union of its triangles' voxels, one point each, is
tests/twin/maps/test_points.py's.) Slow: the models are read with ifcopenshell (skipped when ../shared is
absent)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import SHARED_MODELS, imported, shared_model
from tests.twin.reference_voxels import reference_voxels
from twin.graph.rdf import literal_value
from twin.maps.points import _near_band, plan_points
from twin.maps.scene import load_scene
from twin.maps.voxels import touched_voxels
from twin.records import BuildingModel
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
        tri, ijk = touched_voxels(cells[pick], lo=plan.lo, hi=plan.hi, w_band=plan.w_band)
        for n, t in enumerate(pick):
            got = {(int(i), int(j), int(k)) for i, j, k in ijk[tri == n]}
            ref = reference_voxels(cells[t], plan.lo, plan.hi, plan.w_band)
            assert (sorted(ref - got), sorted(got - ref)) == ([], []), f"{name} {storey.key} triangle {t}"
            checked += 1
    assert checked >= min(SAMPLE, 20)
