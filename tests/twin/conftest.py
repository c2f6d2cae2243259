"""Core fixtures: the box lab imported into an in-memory store (no IFC, no ifcopenshell)."""

from __future__ import annotations

import pytest

from tests.conftest import imported
from tests.twin.box_lab import box_lab
from twin.graph.store import GraphStore


@pytest.fixture(scope="session")
def box_store() -> GraphStore:
    return imported(box_lab())


@pytest.fixture(scope="session")
def box_store2() -> GraphStore:
    return imported(box_lab(storeys=2))
