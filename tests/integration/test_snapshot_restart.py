"""The daemon restarted from its snapshot, after a clean stop and after kill -9, serves the maps a
rebuild from the store gives."""

from __future__ import annotations

import signal
import time
from pathlib import Path

import numpy as np
import pytest

from adapters.zenoh.client import TwinClient
from tests.integration.conftest import Daemon, start_daemon
from twin.config import load_config
from twin.graph.store import EmbeddedStore
from twin.live import TwinService

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

TWIN = "https://w3id.org/building-twin#"


def _box(iri: str, x: float, y: float) -> str:
    return (
        f'<{iri}> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "ground-floor" ; '
        f'<{TWIN}box> "{x} {y} 0.375 0.6 0.6 0.75 0.3" .'
    )


def _change(daemon: Daemon, n: int) -> int:
    """Add ``n`` boxes, move the first, open a door: the revision of the last ack."""
    with TwinClient.connect([daemon.endpoint]) as client:
        rows = client.sparql('SELECT ?door WHERE { ?door twin:ifcClass "IfcDoor" } ORDER BY ?door LIMIT 1')
        assert isinstance(rows, dict)
        door = str(rows["results"]["bindings"][0]["door"]["value"])
        for i in range(n):
            assert client.observe("robot1", _box(f"urn:robot1:box-{n}-{i}", 14.0 + i, 7.0))["ok"]
        assert client.observe("robot1", _box(f"urn:robot1:box-{n}-0", 16.6, 7.2))["ok"]
        return int(client.observe("robot1", f"<{door}> <{TWIN}isOpen> true .")["revision"])


def _served(daemon: Daemon) -> dict[tuple[str, str], np.ndarray]:
    with TwinClient.connect([daemon.endpoint]) as client:
        return {(s, k): client.get_map(s, k)[0].data for s, k in client.list_maps()}


def _assert_equal_to_a_rebuild(store: Path, served: dict[tuple[str, str], np.ndarray]) -> None:
    with EmbeddedStore.open(store) as st:
        service = TwinService(st, load_config())
        service.start()
        assert sorted(served) == sorted(service.live_maps.skill_maps)
        for key, m in service.live_maps.skill_maps.items():
            np.testing.assert_array_equal(served[key], m.data, err_msg=str(key))


@pytest.mark.slow
def test_a_daemon_restarted_after_a_clean_stop_and_after_kill_9_serves_maps_equal_to_a_rebuild(
    fresh_store: Path,
) -> None:
    snapshot = fresh_store.with_name("store.snapshot")
    daemon = start_daemon(fresh_store, "--no-record")
    assert daemon.log[-1].endswith("(built from the store)")
    revision = _change(daemon, 3)
    assert daemon.stop()[0] == 0
    assert snapshot.exists()

    daemon = start_daemon(fresh_store, "--no-record")  # after a clean stop: the snapshot is current
    try:
        assert daemon.log[-1].endswith(f"(from the snapshot of revision {revision})"), daemon.log[-1]
        served = _served(daemon)
        killed_at = _change(daemon, 2)
    finally:
        daemon.process.send_signal(signal.SIGKILL)
        daemon.process.wait(timeout=10)
    _assert_equal_to_a_rebuild(fresh_store, served)

    daemon = start_daemon(fresh_store, "--no-record")  # after kill -9: older than the store, replayed
    try:
        assert f"at revision {killed_at} " in daemon.log[-1]
        assert daemon.log[-1].endswith(f"(from the snapshot of revision {revision})"), daemon.log[-1]
        time.sleep(0.5)
        served = _served(daemon)
    finally:
        assert daemon.stop()[0] == 0
    _assert_equal_to_a_rebuild(fresh_store, served)

    snapshot.write_bytes(snapshot.read_bytes()[:-100])  # damaged: rebuilt, never trusted
    daemon = start_daemon(fresh_store, "--no-record")
    try:
        assert daemon.log[-1].endswith("(built from the store)"), daemon.log[-1]
        served = _served(daemon)
    finally:
        assert daemon.stop()[0] == 0
    _assert_equal_to_a_rebuild(fresh_store, served)
