"""A daemon serves the site its store was imported as, and a client without ``--site`` finds it by its
liveliness token (``twin/<site>/daemon``): real daemons as processes, the ``twin`` command as a client."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

from adapters.zenoh.client import TwinClient
from adapters.zenoh.errors import TransportError
from tests.integration.conftest import Daemon, start_daemon, twin

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast


@pytest.fixture(scope="module")
def wing_store_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The sample lab imported from a file named ``North_Wing.ifc``, without ``--site``."""
    root = tmp_path_factory.mktemp("wing")
    assert twin("sample", "lab", root / "North_Wing.ifc", "--storeys", "2").returncode == 0
    r = twin("import", root / "North_Wing.ifc", "--store", root / "store")
    assert r.returncode == 0, r.stderr
    assert "as site 'north-wing'" in r.stdout
    return root / "store"


BOX = ("--box", "16.6,7.0,0.375,0.6,0.6,0.75,0.0", "--class", "IfcFurniture", "--storey", "ground-floor")


def observe(*args: str) -> tuple[int, str]:
    """``twin observe`` of a table in the corridor: (exit code, stdout + stderr)."""
    r = twin("observe", "--robot", "robot1", *BOX, *args, timeout=60)
    return r.returncode, r.stdout + r.stderr


def _daemon(store: Path, tmp_path: Path, name: str) -> Daemon:
    copy = tmp_path / name
    shutil.copytree(store, copy)
    return start_daemon(copy, "--no-record")


@pytest.fixture(scope="module")
def wing(wing_store_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Daemon]:
    """One daemon for the module: its tests read its log and status, and its one observation's table
    does not matter to the others."""
    d = _daemon(wing_store_dir, tmp_path_factory.mktemp("wing"), "wing")
    yield d
    d.stop_cleanly()


def test_a_daemon_serves_the_site_its_store_was_imported_as(wing: Daemon) -> None:
    assert any("serving site 'north-wing'" in line and "twin/north-wing/" in line for line in wing.log)


def test_a_client_without_site_finds_the_one_daemon_running(wing: Daemon) -> None:
    code, out = observe("--connect", wing.endpoint)
    assert code == 0, out
    assert '"ok": true' in out
    with TwinClient.connect([wing.endpoint]) as client:
        assert client.keys.prefix == "twin/north-wing"
        assert client.daemon_alive()
    code, out = observe("--connect", wing.endpoint, "--site", "lab", "--timeout", "2")
    assert code != 0
    assert "twin/lab" in out


def test_a_client_that_sees_two_daemons_asks_for_a_site_naming_both(wing: Daemon, fresh_store: Path) -> None:
    lab = start_daemon(fresh_store, "--no-record")
    both = ("--connect", wing.endpoint, "--connect", lab.endpoint)
    try:
        code, out = observe(*both)
        assert code != 0
        assert "2 daemons are running, for the sites lab, north-wing: choose one with --site" in out
        with pytest.raises(TransportError, match="lab, north-wing"):
            TwinClient.connect([wing.endpoint, lab.endpoint])
        code, out = observe(*both, "--site", "lab")
        assert code == 0, out
    finally:
        lab.stop()
