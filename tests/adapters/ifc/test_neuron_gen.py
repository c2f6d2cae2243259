"""The Neuron-size building generator (``benchmarks/neuron_gen.py``) on a small instance: one storey,
two rooms a side, in metres and in millimetres, read back with ifcopenshell and the twin's import."""

from __future__ import annotations

import importlib.util
import math
import sys
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import ifcopenshell
import ifcopenshell.util.element
import numpy as np
import pytest

from tests.conftest import imported
from twin.graph.stats import model_stats
from twin.records import BuildingModel, Element

GENERATOR = Path(__file__).resolve().parents[3] / "benchmarks" / "neuron_gen.py"
SMALL: dict[str, Any] = {"seed": 7, "storeys": 2, "scale": 0.05}
"""Two storeys (the stairs lead from one to the other), two rooms a side: about 300 elements."""
PAPER_ELEMENTS = 11_500
NO_BODY = ("IfcCurtainWall", "IfcStair")
"""Containers whose body is their parts' (plates and members, flights and landings)."""


def _load() -> ModuleType:
    spec = importlib.util.spec_from_file_location("neuron_gen", GENERATOR)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["neuron_gen"] = module  # dataclasses look their module up while the class is made
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def gen() -> ModuleType:
    return _load()


@pytest.fixture(scope="module")
def small(gen: ModuleType, tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, Any]]:
    """The small building in both units: unit -> (path, summary)."""
    folder = tmp_path_factory.mktemp("neuron")
    out = {}
    for unit in ("m", "mm"):
        path = folder / f"small-{unit}.ifc"
        out[unit] = (path, gen.generate(path, gen.Options(unit=unit, **SMALL)))
    return out


@pytest.fixture(scope="module")
def small_file(small: dict[str, tuple[Path, Any]]) -> ifcopenshell.file:
    return ifcopenshell.open(str(small["m"][0]))


def _world_bounds(e: Element) -> np.ndarray:
    assert e.geometry is not None
    v = e.geometry.world_vertices()
    return np.concatenate([v.min(axis=0), v.max(axis=0)])


def _volume(e: Element) -> float:
    assert e.geometry is not None
    v = e.geometry.world_vertices()[e.geometry.mesh.faces]
    return abs(float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum()) / 6)


def test_the_small_building_has_every_kind_of_element_the_benchmark_needs(
    small: dict[str, tuple[Path, Any]], small_file: ifcopenshell.file
) -> None:
    summary = small["m"][1]
    for cls in (
        "IfcWall", "IfcPlate", "IfcCurtainWall", "IfcMember", "IfcDoor", "IfcWindow", "IfcOpeningElement",
        "IfcColumn", "IfcBeam", "IfcSlab", "IfcStair", "IfcStairFlight", "IfcRailing", "IfcFurniture",
        "IfcCovering", "IfcLightFixture", "IfcSpaceHeater", "IfcSanitaryTerminal", "IfcSpace",
        "IfcRelSpaceBoundary", "IfcBooleanClippingResult", "IfcMappedItem",
    ):  # fmt: skip
        assert summary.count(cls) > 0, cls
    assert summary.elements == len(small_file.by_type("IfcElement"))
    assert summary.count("IfcBuildingStorey") == 2


def test_every_door_and_window_fills_an_opening_that_voids_a_wall(small_file: ifcopenshell.file) -> None:
    fillings = [*small_file.by_type("IfcDoor"), *small_file.by_type("IfcWindow")]
    assert fillings
    for filling in fillings:
        (fills,) = filling.FillsVoids
        (voids,) = fills.RelatingOpeningElement.VoidsElements
        assert voids.RelatingBuildingElement.is_a("IfcWall")
    # the only openings without a filling are the stairwells in the upper floor's slab
    empty = [o for o in small_file.by_type("IfcOpeningElement") if not o.HasFillings]
    assert len(empty) == 2
    assert all(o.VoidsElements[0].RelatingBuildingElement.is_a("IfcSlab") for o in empty)


def test_every_room_is_bounded_by_its_walls_door_and_facade(small_file: ifcopenshell.file) -> None:
    for space in small_file.by_type("IfcSpace"):
        bounded = {b.RelatedBuildingElement.is_a() for b in space.BoundedBy}
        assert "IfcWall" in bounded, space.Name
        assert "IfcDoor" in bounded, space.Name


def test_glass_partitions_and_curtain_walls_are_made_of_glass(small_file: ifcopenshell.file) -> None:
    def glass(e: Any) -> bool:
        m = ifcopenshell.util.element.get_material(e)
        return m is not None and m.Name == "Glass"

    assert any(glass(w) for w in small_file.by_type("IfcWall"))
    for cw in small_file.by_type("IfcCurtainWall"):
        parts = ifcopenshell.util.element.get_decomposition(cw)
        assert {p.is_a() for p in parts} == {"IfcPlate", "IfcMember"}
        assert all(glass(p) for p in parts if p.is_a("IfcPlate"))


def test_chairs_share_one_mapped_body_through_their_type(small_file: ifcopenshell.file) -> None:
    typed = [(f, ifcopenshell.util.element.get_type(f)) for f in small_file.by_type("IfcFurniture")]
    chairs = [f for f, t in typed if t is not None and t.Name == "Chair"]
    assert len(chairs) >= 4
    sources = {
        item.MappingSource.id()
        for c in chairs
        for rep in c.Representation.Representations
        for item in rep.Items
        if item.is_a("IfcMappedItem")
    }
    assert len(sources) == 1


def test_the_same_seed_writes_the_same_file(gen: ModuleType, tmp_path: Path) -> None:
    paths = [tmp_path / d / "n.ifc" for d in ("a", "b")]
    for p in paths:
        p.parent.mkdir()
        gen.generate(p, gen.Options(**SMALL))
    assert paths[0].read_bytes() == paths[1].read_bytes()
    other = tmp_path / "other.ifc"
    gen.generate(other, gen.Options(**{**SMALL, "seed": 8}))
    assert other.read_bytes() != paths[0].read_bytes()


@pytest.fixture(scope="module")
def models(
    small: dict[str, tuple[Path, Any]], read_cached: Callable[[Path], BuildingModel]
) -> dict[str, BuildingModel]:
    return {unit: read_cached(path) for unit, (path, _) in small.items()}


def test_the_twin_imports_every_element_and_meshes_all_but_the_containers(
    models: dict[str, BuildingModel], small: dict[str, tuple[Path, Any]]
) -> None:
    model, summary = models["m"], small["m"][1]
    stats = model_stats(imported(model), turtle=False)
    assert stats.elements == summary.elements
    assert stats.spaces == summary.spaces
    assert stats.mesh_failures == 0
    assert stats.meshes == summary.elements - sum(summary.count(c) for c in NO_BODY)


def test_clipped_walls_come_out_cut_by_their_half_space(
    models: dict[str, BuildingModel], small_file: ifcopenshell.file, gen: ModuleType
) -> None:
    clipped = {
        w.GlobalId
        for w in small_file.by_type("IfcWall")
        if any(i.is_a("IfcBooleanClippingResult") for r in w.Representation.Representations for i in r.Items)
    }
    assert len(clipped) >= 2  # the gable walls at least
    walls = {e.guid: e for e in models["m"].elements if e.guid in clipped}
    for guid, wall in walls.items():
        lo, hi = _world_bounds(wall)[:3], _world_bounds(wall)[3:]
        size = sorted(hi - lo)
        thickness, height, length = size[0], gen.WALL_H, size[2]
        assert hi[2] - lo[2] == pytest.approx(height, abs=1e-6)
        chamfer = 0.8 if "gable" in small_file.by_guid(guid).Name else 0.6
        expected = thickness * (length * height - chamfer**2 / 2)
        assert _volume(wall) == pytest.approx(expected, rel=1e-3), small_file.by_guid(guid).Name


def test_millimetres_give_the_same_geometry_in_metres(models: dict[str, BuildingModel]) -> None:
    metre = {e.guid: e for e in models["m"].elements if e.geometry is not None}
    milli = {e.guid: e for e in models["mm"].elements if e.geometry is not None}
    assert metre.keys() == milli.keys()
    worst = max(float(np.abs(_world_bounds(metre[g]) - _world_bounds(milli[g])).max()) for g in metre)
    assert worst < 1e-3  # the manifold kernel grows openings by 10x its precision in file units
    assert [s.elevation_m for s in models["m"].storeys] == [s.elevation_m for s in models["mm"].storeys]


def test_a_full_width_storey_holds_a_sixth_of_the_papers_elements(gen: ModuleType, tmp_path: Path) -> None:
    summary = gen.generate(tmp_path / "storey.ifc", gen.Options(storeys=1))  # the default width
    assert summary.elements >= math.ceil(PAPER_ELEMENTS / 6)
