"""The twin on a remote SPARQL 1.1 server (a real ``oxigraph serve`` process): the commands work
against it as against the embedded store, and the daemon acks an observation once it is on the server."""

from __future__ import annotations

import io
import json
import time
from collections.abc import Iterator
from pathlib import Path

import pyoxigraph as ox
import pytest

from adapters.sparql.remote_store import RemoteStore
from tests.integration.conftest import start_daemon, twin
from tests.sparql_server import SparqlServer, start_sparql_server
from twin.graph.store import EmbeddedStore

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

TWIN = "https://w3id.org/building-twin#"
TABLE = "urn:twin:robot1:remote-table"


@pytest.fixture
def lab_server(lab_store_dir: Path) -> Iterator[SparqlServer]:
    """A server of this test's own holding the imported lab (copied from the embedded store)."""
    server = start_sparql_server()
    buf = io.BytesIO()
    with EmbeddedStore.open(lab_store_dir, read_only=True) as embedded:
        embedded.dump_turtle(buf)
    with RemoteStore.open(server.url) as remote:
        remote.bulk_add(ox.parse(buf.getvalue(), format=ox.RdfFormat.TURTLE))
    yield server
    server.stop()


def test_the_lab_imported_into_a_server_gives_the_same_stats_queries_and_maps_cell_for_cell(
    lab_store_dir: Path, sparql_server: SparqlServer, tmp_path: Path
) -> None:
    with RemoteStore.open(sparql_server.url) as store:
        store.clear()
    url = sparql_server.url
    lab = lab_store_dir.parent / "lab.ifc"
    r = twin("import", lab, "--store-url", url)
    assert r.returncode == 0, r.stderr
    assert f"into {url} as site 'lab'" in r.stdout
    r = twin("import", lab, "--store-url", url)
    assert r.returncode == 1 and "already holds a model" in r.stderr

    remote, embedded = ("--store-url", url), ("--store", str(lab_store_dir))
    stats = [json.loads(twin("stats", *where, "--json").stdout) for where in (remote, embedded)]
    assert stats[0] == stats[1] and stats[0]["triples"] > 500
    query = "SELECT ?e ?cls WHERE { ?e twin:ifcClass ?cls } ORDER BY ?e"
    answers = [twin("query", *where, query, "--json").stdout for where in (remote, embedded)]
    assert answers[0] == answers[1] and "IfcWall" in answers[0]

    for where, out in ((remote, tmp_path / "remote"), (embedded, tmp_path / "embedded")):
        r = twin("map", *where, "--all-skills", "--out", out)
        assert r.returncode == 0, r.stderr
    grids = sorted(p.name for p in (tmp_path / "embedded").glob("*.pgm"))
    assert len(grids) == 8  # 4 skills x 2 storeys
    for name in grids:  # trinary PGM: one byte per cell, free / occupied / unknown
        assert (tmp_path / "remote" / name).read_bytes() == (tmp_path / "embedded" / name).read_bytes(), name
        yaml = name.replace(".pgm", ".yaml")
        assert (tmp_path / "remote" / yaml).read_text() == (tmp_path / "embedded" / yaml).read_text()


def test_the_daemon_on_a_server_acks_an_observation_once_it_is_on_the_server(
    lab_server: SparqlServer,
) -> None:
    daemon = start_daemon(None, "--store-url", lab_server.url, "--no-record")
    try:
        assert any(f"revision 0 on {daemon.endpoint}" in line for line in daemon.log), daemon.log
        r = twin(
            "observe", "--connect", daemon.endpoint, "--robot", "robot1", "--id", TABLE,
            "--box", "16.6,7.0,0.375,0.6,0.6,0.75,0.0", "--class", "IfcFurniture", "--storey", "ground-floor",
            timeout=60,
        )  # fmt: skip
        assert r.returncode == 0, r.stderr + r.stdout
        ack = json.loads(r.stdout)
        assert ack["ok"] and ack["revision"] == 1 and ack["upserted"] == [TABLE]
        # Straight to the server over HTTP: the element, its geometry and its provenance are there.
        seen = lab_server.query_json(
            f"SELECT ?cls ?robot ?rev WHERE {{ <{TABLE}> <{TWIN}ifcClass> ?cls ; <{TWIN}observedBy> ?robot ;"
            f" <{TWIN}revision> ?rev ; <https://w3id.org/omg#hasGeometry> ?g }}"
        )
        rows = seen["results"]["bindings"]  # type: ignore[index]
        assert [(b["cls"]["value"], b["robot"]["value"], b["rev"]["value"]) for b in rows] == [
            ("IfcFurniture", "robot1", "1")
        ]

        lab_server.stop()  # the server goes away: the next observation is refused, promptly and clearly
        t0 = time.monotonic()
        r = twin(
            "observe", "--connect", daemon.endpoint, "--robot", "robot1", "--id", TABLE + "-2",
            "--box", "17.6,7.0,0.375,0.6,0.6,0.75,0.0", "--class", "IfcFurniture", "--storey", "ground-floor",
            timeout=60,
        )  # fmt: skip
        assert r.returncode == 1
        refusal = json.loads(r.stdout)
        assert not refusal["ok"] and f"{lab_server.url}/update" in refusal["error"]
        assert time.monotonic() - t0 < 15
        assert daemon.process.poll() is None  # the daemon keeps serving
        code, _ = daemon.stop()
        assert code == 0, "\n".join(daemon.log)
    finally:
        if daemon.process.poll() is None:
            daemon.process.kill()
            daemon.process.wait(timeout=10)


def test_serve_on_an_unreachable_server_fails_at_once_naming_it() -> None:
    r = twin("serve", "--store-url", "http://127.0.0.1:9", "--no-record", timeout=30)
    assert r.returncode == 1
    assert r.stderr.strip() == (
        "twin: error: The SPARQL endpoint http://127.0.0.1:9/query is unreachable: Connection refused."
    )
