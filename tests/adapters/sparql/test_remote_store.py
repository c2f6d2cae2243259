"""What is particular to the remote store: endpoints, configuration, connections, and a server that
goes away or stops answering (a clear error naming the URL, never a hang)."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from pathlib import Path

import pyoxigraph as ox
import pytest

from adapters.cli.config_cmd import load
from adapters.sparql.remote_store import RemoteStore, SparqlEndpoint
from adapters.sparql.settings import remote_store_settings
from tests.sparql_server import SparqlServer, start_sparql_server
from twin.config import load_config
from twin.errors import ConfigError, StoreError, StoreUnavailableError
from twin.graph.rdf import ChangeSet, RdfLiteral, Triple

Q = ox.Quad(ox.NamedNode("https://ex.org/a"), ox.NamedNode("https://ex.org/p"), ox.Literal("x"))


@pytest.fixture
def own_server(tmp_path: Path) -> Iterator[SparqlServer]:
    """A server of this test's own (on disk), which the test may kill."""
    server = start_sparql_server(tmp_path / "data")
    yield server
    server.stop()


def test_endpoints_are_paths_under_the_url_or_absolute_urls() -> None:
    oxigraph = SparqlEndpoint.at("http://127.0.0.1:7878/")
    assert (oxigraph.query, oxigraph.update, oxigraph.graph_store) == (
        "http://127.0.0.1:7878/query",
        "http://127.0.0.1:7878/update",
        "http://127.0.0.1:7878/store",
    )
    fuseki = SparqlEndpoint.at("http://h:3030/lab", query="sparql", update="/update", graph_store="data")
    assert (fuseki.query, fuseki.update, fuseki.graph_store) == (
        "http://h:3030/lab/sparql",
        "http://h:3030/lab/update",
        "http://h:3030/lab/data",
    )
    graphdb = SparqlEndpoint.at(
        "https://g/repositories/r", query="", update="statements", graph_store="x://y"
    )
    assert (graphdb.query, graphdb.update, graphdb.graph_store) == (
        "https://g/repositories/r",
        "https://g/repositories/r/statements",
        "x://y",
    )
    with pytest.raises(StoreError, match=r"Not a SPARQL endpoint URL .*'ftp://h/'"):
        SparqlEndpoint.at("ftp://h/")


def test_the_configuration_names_a_server_or_none(tmp_path: Path) -> None:
    assert remote_store_settings(load_config()) is None  # the default: the embedded store
    cfg = tmp_path / "site.toml"
    cfg.write_text('[store]\nurl = "http://10.0.0.5:3030/lab"\ntimeout_s = 2\nquery_endpoint = "sparql"\n')
    remote = remote_store_settings(load(cfg))
    assert remote is not None
    assert (remote.url, remote.timeout_s, remote.query_endpoint, remote.update_endpoint) == (
        "http://10.0.0.5:3030/lab",
        2.0,
        "sparql",
        "update",
    )
    for bad, match in (
        ('url = "localhost:7878"', r"\[store\] url: expected \"\" or an http\(s\):// URL"),
        ('url = "http://h"\ntimeout_s = 0', r"\[store\] timeout_s: expected a number > 0"),
        ('url = "http://h"\nupdate_endpoint = 3', r"\[store\] update_endpoint: expected a string, got 3"),
        ('uri = "http://h"', r"\[store\] uri: unknown key \(did you mean url\?\)"),
    ):
        cfg.write_text(f"[store]\n{bad}\n")
        with pytest.raises(ConfigError, match=match):
            load(cfg)


def test_opening_a_store_where_no_server_listens_is_a_clear_error() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # closed again: nothing listens there
    t0 = time.monotonic()
    with pytest.raises(StoreUnavailableError, match=rf"http://127.0.0.1:{port}/query is unreachable"):
        RemoteStore.open(f"http://127.0.0.1:{port}", timeout_s=5)
    assert time.monotonic() - t0 < 2


def test_a_server_that_stops_answering_times_out_instead_of_hanging() -> None:
    with socket.socket() as silent:  # accepts connections (the kernel's backlog), never answers
        silent.bind(("127.0.0.1", 0))
        silent.listen(8)
        url = f"http://127.0.0.1:{silent.getsockname()[1]}"
        t0 = time.monotonic()
        with pytest.raises(StoreUnavailableError, match=rf"{url}/query did not answer within 0.3 s"):
            RemoteStore.open(url, timeout_s=0.3)
        assert time.monotonic() - t0 < 2


def test_a_server_that_goes_away_gives_a_clear_error_for_reads_and_writes(own_server: SparqlServer) -> None:
    store = RemoteStore.open(own_server.url, timeout_s=5)
    store.add([Q])
    own_server.stop()
    t0 = time.monotonic()
    with pytest.raises(StoreUnavailableError, match=rf"{own_server.url}/query (is unreachable|closed)"):
        store.select("SELECT * WHERE { ?s ?p ?o }")
    change = ChangeSet(add=(Triple("https://ex.org/b", "https://ex.org/p", RdfLiteral("y")),))
    with pytest.raises(StoreUnavailableError, match=rf"{own_server.url}/update (is unreachable|closed)"):
        store.apply(change)
    assert time.monotonic() - t0 < 2
    store.close()


def test_requests_reuse_one_connection_and_survive_a_server_restart(own_server: SparqlServer) -> None:
    location = Path(own_server.process.args[-1])  # type: ignore[index]
    port = int(own_server.url.rsplit(":", 1)[1])
    with RemoteStore.open(own_server.url) as store:
        store.add([Q])
        for _ in range(20):
            assert len(store) == 1
        pool = store._pool
        assert pool is not None
        assert sum(len(c) for c in pool._idle.values()) == 1  # one keep-alive connection did it all
        own_server.stop()
        again = start_sparql_server(location, port=port)  # same data, same port: a restarted server
        try:
            assert len(store) == 1  # the dead kept-alive connection is noticed and replaced
            store.apply(ChangeSet(remove=(("https://ex.org/a", None),)))
            assert store.is_empty()
        finally:
            again.stop()


def test_the_servers_own_error_message_is_passed_on(sparql_server: SparqlServer) -> None:
    with RemoteStore.open(sparql_server.url) as store:
        with pytest.raises(StoreError, match=r"No SPARQL service at http://127.0.0.1:\d+/nothere \(HTTP 404"):
            RemoteStore.open(sparql_server.url, query="nothere")
        with pytest.raises(
            StoreError, match=r"/update failed \(HTTP 500\): The graph <urn:g> already exists"
        ):
            store.update("CREATE GRAPH <urn:g> ; CREATE GRAPH <urn:g>")


def test_bulk_add_loads_the_default_graph_only(sparql_server: SparqlServer) -> None:
    named = ox.Quad(Q.subject, Q.predicate, Q.object, ox.NamedNode("urn:g"))
    with RemoteStore.open(sparql_server.url) as store:
        store.clear()
        with pytest.raises(StoreError, match="default graph only, not <urn:g>"):
            store.bulk_add([Q, named])
        store.add([named])  # add() takes any graph
        assert len(store) == 1
        store.clear()
