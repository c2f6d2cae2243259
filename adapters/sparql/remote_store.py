"""The graph store on a remote SPARQL 1.1 server (a :class:`~twin.graph.store.GraphStore`).

Any server that speaks the SPARQL 1.1 Protocol (queries and updates) and the Graph Store Protocol
works: Oxigraph's own server (``oxigraph serve``, endpoints ``/query``, ``/update``, ``/store``), Fuseki
(``/ds/query``, ``/ds/update``, ``/ds/data``), GraphDB, ... Requests go over HTTP/1.1 keep-alive
connections (standard library only: this module imports no transport beyond ``http.client``), each with a
timeout; results are parsed into the same plain :data:`~twin.graph.store.Row` records :class:`EmbeddedStore`
returns, so the service and the map engine cannot tell the two apart.

- :meth:`RemoteStore.apply` is ONE SPARQL update request, which the server runs as one transaction:
  when it returns, the change is committed on the server (the daemon acks only after that).
- :meth:`RemoteStore.bulk_add` is ONE Graph Store Protocol ``POST`` of N-Triples to the default graph,
  streamed in chunks (so blank nodes keep their identity and memory stays flat).
- The vocabulary's prefixes (:data:`twin.graph.vocab.PREFIXES`) are predefined, as in the embedded store.

Example::

    with RemoteStore.open("http://127.0.0.1:7878") as store:
        rows = store.select("SELECT ?s WHERE { ?s a bot:Storey }")
"""

from __future__ import annotations

import http.client
import logging
import re
import select
import threading
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import IO, Self
from urllib.parse import urlsplit

import pyoxigraph as ox

from twin.errors import QueryError, StoreError, StoreUnavailableError
from twin.graph import vocab
from twin.graph.rdf import (
    ByteCounter,
    ChangeSet,
    Row,
    boolean_answer,
    changes_to_sparql,
    reject_service,
    solution_rows,
)

log = logging.getLogger(__name__)

_JSON = "application/sparql-results+json"
_TURTLE = "text/turtle"
_N_TRIPLES = "application/n-triples"
_ACCEPT = f"{_JSON}, {_TURTLE};q=0.9"
_BATCH = 10_000  # triples serialised at a time into the streamed body of a bulk load
_MESSAGE_CHARS = 500  # of the server's error message, in our errors
_ALL_QUADS = "{ ?s ?p ?o } UNION { GRAPH ?g { ?s ?p ?o } }"


@dataclass(frozen=True, slots=True)
class SparqlEndpoint:
    """Where a SPARQL 1.1 server answers: the base URL and the full URLs of its three services."""

    url: str
    query: str
    update: str
    graph_store: str

    @classmethod
    def at(
        cls, url: str, *, query: str = "query", update: str = "update", graph_store: str = "store"
    ) -> SparqlEndpoint:
        """The endpoint of a server at ``url``; each service is a path under it (``""``: ``url`` itself)
        or an absolute URL. Oxigraph's defaults: ``/query``, ``/update``, ``/store``."""
        base = url.rstrip("/")
        parts = urlsplit(base)
        if parts.scheme not in ("http", "https") or not parts.hostname:
            msg = f"Not a SPARQL endpoint URL (http:// or https:// and a host): {url!r}."
            raise StoreError(msg)

        def under(path: str) -> str:
            if "://" in path:
                return path
            return f"{base}/{path.strip('/')}" if path.strip("/") else base

        return cls(base, under(query), under(update), under(graph_store))


class _Connections:
    """HTTP/1.1 keep-alive connections, pooled per host, safe to share between threads.

    A connection is taken for one request and returned once its response has been read whole; an idle
    connection the server has closed meanwhile is noticed (readable socket) and replaced.
    """

    def __init__(self, timeout_s: float) -> None:
        self.timeout_s = timeout_s
        self._idle: dict[tuple[str, str], list[http.client.HTTPConnection]] = {}
        self._lock = threading.Lock()

    def take(self, scheme: str, netloc: str) -> tuple[http.client.HTTPConnection, bool]:
        """An idle connection (reused=True) or a new one (not yet connected)."""
        with self._lock:
            idle = self._idle.get((scheme, netloc), [])
            while idle:
                conn = idle.pop()
                if not _dropped(conn):
                    return conn, True
                conn.close()
        kind = http.client.HTTPSConnection if scheme == "https" else http.client.HTTPConnection
        return kind(netloc, timeout=self.timeout_s), False

    def give_back(self, scheme: str, netloc: str, conn: http.client.HTTPConnection) -> None:
        with self._lock:
            self._idle.setdefault((scheme, netloc), []).append(conn)

    def close(self) -> None:
        with self._lock:
            for conns in self._idle.values():
                for conn in conns:
                    conn.close()
            self._idle.clear()


def _dropped(conn: http.client.HTTPConnection) -> bool:
    """True when an idle connection is unusable: no socket, or readable (the server closed it)."""
    sock = conn.sock
    if sock is None:
        return True
    try:
        readable, _, _ = select.select([sock], [], [], 0)
    except (OSError, ValueError):
        return True
    return bool(readable)


_STALE = (http.client.RemoteDisconnected, ConnectionResetError, BrokenPipeError, ConnectionAbortedError)


class RemoteStore:
    """A graph store behind a SPARQL 1.1 endpoint. Use :meth:`open` and close it (or ``with``)."""

    def __init__(self, endpoint: SparqlEndpoint, *, timeout_s: float, read_only: bool = False) -> None:
        self.endpoint = endpoint
        self.timeout_s = timeout_s
        self.read_only = read_only
        self._prefixes = vocab.sparql_prefixes()
        self._pool: _Connections | None = _Connections(timeout_s)

    # --- lifecycle --------------------------------------------------------------------------------
    @classmethod
    def open(
        cls,
        url: str,
        *,
        query: str = "query",
        update: str = "update",
        graph_store: str = "store",
        timeout_s: float = 30.0,
        read_only: bool = False,
    ) -> RemoteStore:
        """Connect to the server at ``url`` and check that it answers a query (StoreUnavailableError if
        not). ``timeout_s`` bounds every socket operation of every request (connect, send, each read)."""
        if not timeout_s > 0:
            msg = f"The store timeout must be a positive number of seconds, got {timeout_s!r}."
            raise StoreError(msg)
        endpoint = SparqlEndpoint.at(url, query=query, update=update, graph_store=graph_store)
        store = cls(endpoint, timeout_s=timeout_s, read_only=read_only)
        try:
            store.ask("ASK { }")
        except BaseException:
            store.close()
            raise
        return store

    def close(self) -> None:
        """Close the connections; closing twice is harmless. The data stays on the server."""
        if self._pool is not None:
            self._pool.close()
            self._pool = None

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"RemoteStore({self.endpoint.url!r})"

    # --- HTTP ---------------------------------------------------------------------------------------
    @contextmanager
    def _request(
        self,
        method: str,
        url: str,
        *,
        body: bytes | Iterable[bytes] | None = None,
        headers: dict[str, str],
        retry: bool,
        what: str = "request",
    ) -> Iterator[http.client.HTTPResponse]:
        """One request; yields the response (status < 400), whose body must be read within the block.

        ``retry``: the request may be sent again (it is idempotent) if a reused keep-alive connection
        turns out to be closed. ``what`` names the request in errors (``query``, ``update``). Every
        failure becomes a :class:`StoreError` naming ``url``.
        """
        if self._pool is None:
            msg = f"The store at {self.endpoint.url} is closed."
            raise StoreError(msg)
        pool = self._pool
        parts = urlsplit(url)
        target = parts.path or "/"
        if parts.query:
            target += "?" + parts.query
        for attempt in (1, 2):
            conn, reused = pool.take(parts.scheme, parts.netloc)
            try:
                conn.request(method, target, body=body, headers=headers)
                response = conn.getresponse()
            except _STALE as err:
                conn.close()
                if reused and retry and attempt == 1:
                    log.debug("Reconnecting to %s after a closed keep-alive connection: %s", url, err)
                    continue
                msg = f"The SPARQL endpoint {url} closed the connection: {err or type(err).__name__}."
                raise StoreUnavailableError(msg) from err
            except TimeoutError as err:
                conn.close()
                msg = f"The SPARQL endpoint {url} did not answer within {self.timeout_s:g} s."
                raise StoreUnavailableError(msg) from err
            except OSError as err:
                conn.close()
                msg = f"The SPARQL endpoint {url} is unreachable: {err.strerror or err}."
                raise StoreUnavailableError(msg) from err
            except http.client.HTTPException as err:
                conn.close()
                msg = f"The SPARQL endpoint {url} sent a malformed answer: {err!r}."
                raise StoreUnavailableError(msg) from err
            except BaseException:
                conn.close()
                raise
            break
        try:
            if response.status >= 400:
                _raise_for(url, response, what=what, line_offset=self._prefixes.count("\n"))
            yield response
            response.read()  # drain, so the connection can carry the next request
        except TimeoutError as err:
            conn.close()
            msg = f"The SPARQL endpoint {url} stopped sending within {self.timeout_s:g} s."
            raise StoreUnavailableError(msg) from err
        except (OSError, http.client.HTTPException) as err:
            conn.close()
            msg = f"The SPARQL endpoint {url} broke off its answer: {err or type(err).__name__}."
            raise StoreUnavailableError(msg) from err
        except BaseException:
            conn.close()
            raise
        if response.will_close:
            conn.close()
        else:
            pool.give_back(parts.scheme, parts.netloc, conn)

    def _query(self, sparql: str) -> tuple[str, bytes]:
        reject_service(sparql)
        headers = {"Content-Type": "application/sparql-query; charset=utf-8", "Accept": _ACCEPT}
        body = (self._prefixes + sparql).encode()
        with self._request(
            "POST", self.endpoint.query, body=body, headers=headers, retry=True, what="query"
        ) as r:
            media = (r.getheader("Content-Type") or "").split(";")[0].strip().lower()
            data = r.read()
        if media not in (_JSON, _TURTLE):
            got = media or "no media type"
            msg = f"The SPARQL endpoint {self.endpoint.query} answered in {got}, not {_ACCEPT}."
            raise StoreError(msg)
        return media, data

    def _results(self, sparql: str) -> ox.QuerySolutions | ox.QueryBoolean | None:
        media, data = self._query(sparql)
        if media != _JSON:
            return None
        try:
            return ox.parse_query_results(data, format=ox.QueryResultsFormat.JSON)
        except SyntaxError as err:
            msg = f"The SPARQL endpoint {self.endpoint.query} sent results that do not parse: {err}"
            raise StoreError(msg) from err

    # --- writing ------------------------------------------------------------------------------------
    def _writable(self) -> None:
        if self.read_only:
            msg = f"The store at {self.endpoint.url} is open read-only."
            raise StoreError(msg)

    def update(self, sparql_update: str, *, retry: bool = False) -> None:
        """Run a SPARQL 1.1 update: one request, one transaction on the server, committed on return.

        ``retry``: the update is idempotent, so it may be resent over a fresh connection if a kept-alive
        one turns out to be closed."""
        self._writable()
        headers = {"Content-Type": "application/sparql-update; charset=utf-8"}
        body = (self._prefixes + sparql_update).encode()
        with self._request(
            "POST", self.endpoint.update, body=body, headers=headers, retry=retry, what="update"
        ):
            pass

    def apply(self, changes: ChangeSet, *more: ChangeSet) -> None:
        """Apply ``changes`` (then each of ``more``) in one transaction (one update request), committed
        once this returns."""
        todo = [c for c in (changes, *more) if c]
        if not todo:
            return
        # DELETE WHERE, DELETE DATA then INSERT DATA of fixed IRIs and literals: the whole sequence is
        # idempotent, so safe to resend.
        self.update(changes_to_sparql(*todo), retry=True)

    def flush(self) -> None:
        """Nothing to do: the server manages its own buffers."""

    def add(self, quads: Iterable[ox.Quad]) -> None:
        """Add quads atomically (one ``INSERT DATA`` request)."""
        lines = []
        for q in quads:
            triple = f"{q.subject} {q.predicate} {q.object} ."
            graph = q.graph_name
            lines.append(triple if isinstance(graph, ox.DefaultGraph) else f"GRAPH {graph} {{ {triple} }}")
        if lines:
            self.update("INSERT DATA {\n" + "\n".join(lines) + "\n}")

    def bulk_add(self, quads: Iterable[ox.Quad]) -> None:
        """Add many quads of the default graph (initial loads): one Graph Store Protocol ``POST`` of
        N-Triples, streamed. Not atomic on every server; use :meth:`apply` for live changes."""
        self._writable()
        url = self.endpoint.graph_store
        sep = "&" if "?" in url else "?"

        def chunks() -> Iterator[bytes]:
            batch: list[ox.Triple] = []
            for q in quads:
                if not isinstance(q.graph_name, ox.DefaultGraph):
                    msg = f"RemoteStore.bulk_add loads the default graph only, not {q.graph_name}."
                    raise StoreError(msg)
                batch.append(q.triple)
                if len(batch) >= _BATCH:
                    yield _n_triples(batch)
                    batch = []
            if batch:
                yield _n_triples(batch)

        headers = {"Content-Type": _N_TRIPLES}
        with self._request("POST", f"{url}{sep}default", body=chunks(), headers=headers, retry=False):
            pass

    def clear(self) -> None:
        """Remove every triple of every graph."""
        self.update("CLEAR ALL", retry=True)

    # --- reading ----------------------------------------------------------------------------------
    def __len__(self) -> int:
        """Triples in every graph (like :class:`EmbeddedStore`), counted by the server."""
        rows = self.select(f"SELECT (COUNT(*) AS ?n) WHERE {{ {_ALL_QUADS} }}")
        return int(rows[0]["n"] or 0)

    def is_empty(self) -> bool:
        return not self.ask(f"ASK {{ {_ALL_QUADS} }}")

    def select(self, sparql: str) -> list[Row]:
        """Run a SELECT query; one plain row per solution (see :data:`~twin.graph.store.Row`)."""
        return list(solution_rows(self._results(sparql)))

    def iter_select(self, sparql: str) -> Iterator[Row]:
        """Like :meth:`select` (the whole answer is read first: a connection is not held open)."""
        return iter(self.select(sparql))

    def ask(self, sparql: str) -> bool:
        return boolean_answer(self._results(sparql))

    def query_serialized(self, sparql: str) -> tuple[str, bytes]:
        """Run any read-only query; return (media type, bytes): SPARQL JSON results, or Turtle for graphs
        (the server's own serialisation, passed through)."""
        return self._query(sparql)

    def _dump(self, out: IO[bytes]) -> None:
        # A CONSTRUCT sorted by subject and predicate rather than a Graph Store GET (which Oxigraph
        # answers in predicate order): the Turtle then groups every subject's triples, as the embedded
        # store's dump does, and has the same size.
        url = self.endpoint.query
        headers = {"Content-Type": "application/sparql-query; charset=utf-8", "Accept": _N_TRIPLES}
        body = b"CONSTRUCT { ?s ?p ?o } WHERE { ?s ?p ?o } ORDER BY ?s ?p"
        with self._request("POST", url, body=body, headers=headers, retry=True, what="query") as response:
            try:
                triples = ox.parse(response, format=ox.RdfFormat.N_TRIPLES)
                ox.serialize(triples, out, format=ox.RdfFormat.TURTLE, prefixes=vocab.PREFIXES)
            except SyntaxError as err:
                msg = f"The SPARQL endpoint {url} sent N-Triples that do not parse: {err}"
                raise StoreError(msg) from err

    def dump_turtle(self, out: IO[bytes] | Path) -> None:
        """Write the default graph as Turtle with the LBD prefixes (streamed from the server, which sorts
        it by subject and predicate)."""
        if isinstance(out, Path):
            with out.open("wb") as fh:
                self._dump(fh)
        else:
            self._dump(out)

    def turtle_size(self) -> int:
        """Bytes of :meth:`dump_turtle` output, without keeping it in memory."""
        sink = ByteCounter()
        self._dump(sink)  # type: ignore[arg-type]  # any binary writer works
        return sink.count


def _n_triples(triples: list[ox.Triple]) -> bytes:
    return ox.serialize(triples, format=ox.RdfFormat.N_TRIPLES) or b""


_POSITION = re.compile(r"(error at |line )(\d+)")


def _raise_for(url: str, response: http.client.HTTPResponse, *, what: str, line_offset: int) -> None:
    """Turn an HTTP error status into the store's error, with the server's own message (its line numbers
    made relative to the caller's text again, past the ``line_offset`` predefined PREFIX lines)."""
    raw = response.read(64 * 1024)
    text = raw.decode("utf-8", "replace").strip()
    message = " ".join(text.split())[:_MESSAGE_CHARS] or response.reason
    status = response.status
    if status == 400:
        message = _POSITION.sub(
            lambda m: f"{m[1]}{int(m[2]) - line_offset if int(m[2]) > line_offset else m[2]}", message
        )
        msg = f"SPARQL {what} does not parse or was refused by {url} (HTTP 400): {message}"
        raise QueryError(msg)
    if status in (401, 403):
        msg = f"The SPARQL endpoint {url} refused access (HTTP {status}): {message}"
        raise StoreError(msg)
    if status == 404:
        msg = f"No SPARQL service at {url} (HTTP 404; check the [store] endpoints): {message}"
        raise StoreError(msg)
    if status in (502, 503, 504):
        msg = f"The SPARQL endpoint {url} is unavailable (HTTP {status}): {message}"
        raise StoreUnavailableError(msg)
    msg = f"The SPARQL endpoint {url} failed (HTTP {status}): {message}"
    raise StoreError(msg)
