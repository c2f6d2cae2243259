"""Shared fixtures that need no adapter: configuration, the shared IFC corpus's location (skipped
cleanly when absent) and in-memory stores. IFC fixtures live in ``tests/adapters/conftest.py``; the
core's tests use the box lab (``tests/twin/box_lab.py``) and never import adapters."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.sparql_server import SparqlServer, start_sparql_server
from twin.config import Config, load_config
from twin.import_model import import_model
from twin.records import BuildingModel
from twin.store import EmbeddedStore, GraphStore

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


def imported(model: BuildingModel) -> GraphStore:
    store = EmbeddedStore.open(None)
    import_model(store, model, base_iri=BASE, site="test")
    return store


@pytest.fixture(scope="session")
def sparql_server() -> Iterator[SparqlServer]:
    """One in-memory Oxigraph server per test session (per xdist worker); tests clear it first."""
    server = start_sparql_server()
    yield server
    server.stop()
