"""IFC fixtures: the generated sample lab and reading models with ifcopenshell (cached per session,
because meshing dominates)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from adapters.ifc import read_model
from adapters.ifc.sample_lab import write_lab
from tests.conftest import imported
from twin.config import Config
from twin.graph.store import GraphStore
from twin.records import BuildingModel
from twin.samples.lab_layout import LabLayout


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


@pytest.fixture(scope="session")
def lab_model(lab: tuple[Path, LabLayout], read_cached: Callable[[Path], BuildingModel]) -> BuildingModel:
    return read_cached(lab[0])


@pytest.fixture(scope="session")
def lab_store(lab_model: BuildingModel) -> GraphStore:
    return imported(lab_model)
