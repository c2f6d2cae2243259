"""Shared fixtures: the sample lab (generated), the shared IFC corpus (skipped cleanly when absent),
and imported stores (in memory, cached per session because meshing dominates)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from adapters.ifc import read_model
from adapters.sample_lab import LabLayout, write_lab
from twin.config import Config, load_config
from twin.import_model import import_model
from twin.records import BuildingModel
from twin.store import GraphStore

SHARED_IFC = Path(__file__).resolve().parents[2] / "shared" / "data" / "ifc"
SHARED_MODELS = (
    "AC20-FZK-Haus.ifc",
    "Duplex_A_20110907.ifc",
    "AC11-Institute-Var-2-IFC.ifc",
    "LargeBuilding.ifc",
    "revit2012_janesville_restaurant.ifc",
)
BASE = "https://example.org/test#"


@pytest.fixture(scope="session")
def config() -> Config:
    return load_config()


def shared_model(name: str) -> Path:
    path = SHARED_IFC / name
    if not path.exists():
        pytest.skip(f"shared IFC model {name} not found at {SHARED_IFC} (../shared is absent)")
    return path


@pytest.fixture(scope="session")
def read_cached(config: Config) -> Callable[[Path], BuildingModel]:
    cache: dict[Path, BuildingModel] = {}

    def read(path: Path) -> BuildingModel:
        if path not in cache:
            cache[path] = read_model(path, static_types=config.import_.static_types)
        return cache[path]

    return read


@pytest.fixture(scope="session")
def lab(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, LabLayout]:
    path = tmp_path_factory.mktemp("lab") / "lab.ifc"
    return path, write_lab(path)


@pytest.fixture(scope="session")
def lab2(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, LabLayout]:
    path = tmp_path_factory.mktemp("lab2") / "lab2.ifc"
    return path, write_lab(path, storeys=2)


def imported(model: BuildingModel) -> GraphStore:
    store = GraphStore.open(None)
    import_model(store, model, base_iri=BASE, site="test")
    return store


@pytest.fixture(scope="session")
def lab_model(lab: tuple[Path, LabLayout], read_cached: Callable[[Path], BuildingModel]) -> BuildingModel:
    return read_cached(lab[0])


@pytest.fixture(scope="session")
def lab_store(lab_model: BuildingModel) -> GraphStore:
    return imported(lab_model)
