"""The store fails under a running daemon: a full disk (the store, its snapshot and the recording on a
small tmpfs, mounted here as root) and a remote store that goes away. The daemon refuses what it
cannot make durable, keeps answering, says the store's state in ``status``, and takes writes again on
its own once the store works."""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import time
from collections.abc import Iterator
from pathlib import Path

import pyoxigraph as ox
import pytest

from adapters.sparql.remote_store import RemoteStore
from adapters.zenoh.client import TwinClient
from adapters.zenoh.errors import RemoteError
from tests.integration.conftest import Daemon, free_port, start_daemon
from tests.small_disk import small_tmpfs
from tests.sparql_server import start_sparql_server
from twin.graph.store import EmbeddedStore

pytestmark = pytest.mark.slow

TWIN = "https://w3id.org/building-twin#"
TABLE = "urn:twin:robot1:disk-table"


def _table(x: float) -> str:
    return (f'<{TABLE}> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "ground-floor" ; '
            f'<{TWIN}box> "{x:.2f} 7.0 0.375 0.6 0.6 0.75 0.0" .')  # fmt: skip


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 24 MiB tmpfs (root only: skipped otherwise)."""
    with small_tmpfs(tmp_path / "disk", 24) as disk:
        yield disk


def _fill(disk: Path) -> Path:
    """Fill ``disk`` to the last byte."""
    filler = disk / "filler"
    fd = os.open(filler, os.O_WRONLY | os.O_CREAT | os.O_APPEND)
    try:
        for size in (1 << 16, 1):
            with contextlib.suppress(OSError):
                while True:
                    os.write(fd, b"\0" * size)
    finally:
        os.close(fd)
    return filler


def _wait_store(client: TwinClient, prefix: str, timeout_s: float = 15.0) -> dict[str, object]:
    deadline = time.monotonic() + timeout_s
    while True:
        status = client.status()
        if str(status["store"]).startswith(prefix) or time.monotonic() > deadline:
            return status
        time.sleep(0.2)


def test_a_full_disk_refuses_observations_keeps_answering_and_takes_writes_again_once_space_is_back(
    fresh_store: Path, small_disk: Path
) -> None:
    store = small_disk / "store"
    shutil.copytree(fresh_store, store)
    d = start_daemon(store, "--record", str(small_disk / "run.rrd"), "-v")
    snapshot = small_disk / "store.snapshot"
    deadline = time.monotonic() + 20
    while not snapshot.exists() and time.monotonic() < deadline:  # the rebuilt start's, in the background
        time.sleep(0.1)
    assert snapshot.exists()
    acked: list[int] = []
    try:
        with TwinClient.connect([d.endpoint], prefix="twin/lab", timeout_s=20) as robot:
            acked.append(robot.observe("robot1", _table(16.0))["revision"])
            assert robot.status()["store"] == "ok"
            filler = _fill(small_disk)
            refusals = []
            for i in range(40):  # the first write past the last free byte is refused
                try:
                    acked.append(robot.observe("robot1", _table(16.1 + 0.05 * i))["revision"])
                except RemoteError as err:
                    refusals.append(str(err))
                    break
            assert refusals and "No space left on device" in refusals[0], refusals
            status = _wait_store(robot, "read-only")
            assert str(status["store"]).startswith("read-only: ") and "No space left" in str(status["store"])
            assert status["revision"] == acked[-1]
            grid, revision, _ = robot.get_map("ground-floor", "navigation")  # maps, SPARQL, status answer
            assert revision == acked[-1] and grid.data.size > 0
            assert isinstance(robot.sparql(f"ASK {{ <{TABLE}> ?p ?o }}"), dict)
            with pytest.raises(RemoteError, match="No space left on device"):
                robot.observe("robot1", _table(17.5))  # still refused: nothing is acked that is not kept

            filler.unlink()  # space is back: the daemon reopens the store on its own
            assert _wait_store(robot, "ok")["store"] == "ok"
            acked.append(robot.observe("robot1", _table(17.0))["revision"])
            assert acked[-1] == acked[-2] + 1

            _fill(small_disk)  # full again, and stopped: the snapshot fails, the previous one stays
        code, seconds = d.stop(timeout=60)
        assert code == 0, "\n".join(d.log[-30:])
        assert seconds < 20, "\n".join(d.log[-30:])  # a recorder on the full disk may take the timeout
        assert any("Could not write the snapshot" in line for line in d.log), d.log[-30:]
        assert not any("FATAL" in line for line in d.log)
        filler.unlink()
        again = start_daemon(store, "--no-record")
        try:
            assert any("from the snapshot of revision 0" in line for line in again.log), again.log
            with TwinClient.connect([again.endpoint], prefix="twin/lab") as robot:
                assert robot.status()["revision"] == acked[-1]  # every ack kept
                rows = robot.sparql(f"SELECT ?r WHERE {{ <{TABLE}> <{TWIN}revision> ?r }}")
                assert isinstance(rows, dict)
                assert rows["results"]["bindings"][0]["r"]["value"] == str(acked[-1])  # the last move
        finally:
            again.stop_cleanly()
    finally:
        with contextlib.suppress(FileNotFoundError):
            (small_disk / "filler").unlink()
        d.stop_cleanly()


def test_status_answers_while_the_remote_store_is_down_and_says_ok_once_it_is_back(
    lab_store_dir: Path, tmp_path: Path
) -> None:
    port = free_port()
    server = start_sparql_server(tmp_path / "oxigraph", port=port)
    buf = io.BytesIO()
    with EmbeddedStore.open(lab_store_dir, read_only=True) as embedded:
        embedded.dump_turtle(buf)
    with RemoteStore.open(server.url) as remote:
        remote.bulk_add(ox.parse(buf.getvalue(), format=ox.RdfFormat.TURTLE))
    d: Daemon | None = None
    try:
        d = start_daemon(None, "--store-url", server.url, "--no-record")
        with TwinClient.connect([d.endpoint], prefix="twin/lab", timeout_s=20) as robot:
            assert robot.status()["store"] == "ok"
            server.stop()
            t0 = time.monotonic()
            status = robot.status()  # answered at once
            assert time.monotonic() - t0 < 5
            assert str(status["store"]).startswith("unreachable: ") and status["triples"] is None
            assert robot.get_map("ground-floor", "navigation")[0].data.size > 0
            with pytest.raises(RemoteError, match=server.url):
                robot.observe("robot1", _table(16.6))
            server = start_sparql_server(tmp_path / "oxigraph", port=port)
            assert _wait_store(robot, "ok")["store"] == "ok"
            assert robot.observe("robot1", _table(16.6))["ok"]
        d.stop_cleanly()
        assert not any("Traceback" in line for line in d.log), "\n".join(d.log)
    finally:
        if d is not None:
            d.stop_cleanly()
        server.stop()
