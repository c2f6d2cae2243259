"""Shared fixtures that need no adapter: configuration, the shared IFC corpus's location (skipped
cleanly when absent) and in-memory stores. IFC fixtures live in ``tests/adapters/conftest.py``; the
core's tests use the box lab (``tests/twin/box_lab.py``) and never import adapters."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import settings

from tests.sparql_server import SparqlServer, start_sparql_server
from twin.config import Config, load_config
from twin.graph.import_model import import_model
from twin.graph.store import EmbeddedStore, GraphStore
from twin.records import BuildingModel

SHARED_IFC = Path(__file__).resolve().parents[2] / "shared" / "data" / "ifc"
SHARED_MODELS = (
    "AC20-FZK-Haus.ifc",
    "Duplex_A_20110907.ifc",
    "AC11-Institute-Var-2-IFC.ifc",
    "LargeBuilding.ifc",
    "revit2012_janesville_restaurant.ifc",
)
BASE = "https://example.org/test#"

# Longer fuzz runs: HYPOTHESIS_PROFILE=long (500 examples per fuzz test, or HYPOTHESIS_MAX_EXAMPLES).
settings.register_profile(
    "long", max_examples=int(os.environ.get("HYPOTHESIS_MAX_EXAMPLES", "500")), deadline=None
)
if os.environ.get("HYPOTHESIS_PROFILE"):
    settings.load_profile(os.environ["HYPOTHESIS_PROFILE"])


def examples(n: int) -> int:
    """``n`` examples in the default suite; the loaded profile's count when HYPOTHESIS_PROFILE is set."""
    return settings.default.max_examples if os.environ.get("HYPOTHESIS_PROFILE") else n


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
