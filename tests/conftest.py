"""Shared fixtures that need no adapter: configuration, the shared IFC corpus's location (skipped
cleanly when absent) and in-memory stores. IFC fixtures live in ``tests/adapters/conftest.py``; the
core's tests use the box lab (``tests/twin/box_lab.py``) and never import adapters."""

from __future__ import annotations

import importlib.util
import json
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

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


# The order of the test files: slowest first, from the times of a whole run in tests/durations.json, so
# that the two workers of `pytest -n 2 --dist loadfile` (`make test`) finish together instead of one
# running the last slow file alone. A file's tests stay together and in their order (module fixtures
# are built once); files not in the record (new ones) come first. Refresh the record after a change in
# the suite's shape: `pytest -n 2 --dist loadfile --record-durations tests/durations.json`.
DURATIONS = Path(__file__).with_name("durations.json")
SHARED_MODEL_FILES = frozenset(
    f"tests/adapters/ifc/{name}.py"
    for name in (
        "test_boolean_routing", "test_ifc_import", "test_kernels", "test_live_ifc", "test_maps_ifc",
        "test_material_index", "test_points_ifc", "test_translation",
    )
)  # fmt: skip
"""The files that mesh the shared models (``read_cached``: seconds to a minute each): under ``--dist
loadfile`` they run on one worker, one after the other, which reads each model once."""


def file_scope(nodeid: str) -> str:
    """The unit that ``--dist loadfile`` gives one worker: the test's file, or all shared-model files."""
    path = nodeid.split("::", maxsplit=1)[0]
    return "shared IFC models" if path in SHARED_MODEL_FILES else path


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--record-durations", type=Path, metavar="FILE",
        help="write each test file's total time (setup, call, teardown) to FILE as JSON (the order of files)",
    )  # fmt: skip


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    recorded: dict[str, float] = json.loads(DURATIONS.read_text()) if DURATIONS.exists() else {}
    total: dict[str, float] = {}  # each unit's recorded time: a file unknown to the record makes it inf
    first: dict[str, int] = {}  # each unit's place in the collection: ties keep it
    for i, item in enumerate(items):
        path, scope = item.nodeid.split("::")[0], file_scope(item.nodeid)
        if path not in first:
            total[scope] = total.get(scope, 0.0) + recorded.get(path, math.inf)
        first.setdefault(path, i)
        first.setdefault(scope, i)
    items.sort(key=lambda item: (-total[file_scope(item.nodeid)], first[file_scope(item.nodeid)]))


class _FileTimes:
    """Sums each test file's setup, call and teardown times (on the controller: every worker reports)."""

    def __init__(self, out: Path) -> None:
        self.out = out
        self.seconds: dict[str, float] = {}

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        path = report.nodeid.split("::")[0]
        self.seconds[path] = self.seconds.get(path, 0.0) + report.duration

    def pytest_sessionfinish(self) -> None:
        ranked = dict(sorted(((p, round(s, 1)) for p, s in self.seconds.items()), key=lambda kv: -kv[1]))
        self.out.write_text(json.dumps(ranked, indent=1) + "\n")


def pytest_configure(config: pytest.Config) -> None:
    out = config.getoption("--record-durations")
    if out is not None and not hasattr(config, "workerinput"):  # the controller, or a run without xdist
        config.pluginmanager.register(_FileTimes(out), "file-times")


if importlib.util.find_spec("xdist") is not None:
    from xdist.scheduler import LoadFileScheduling

    class _SharedModelsTogether(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return file_scope(nodeid)

    def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
        """``--dist loadfile``, with :data:`SHARED_MODEL_FILES` as one unit."""
        return _SharedModelsTogether(config, log) if config.getvalue("dist") == "loadfile" else None
