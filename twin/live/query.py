"""Read-only SPARQL for anyone (operators, robots), bounded in time and result size.

Each query runs on a worker thread of its own, which the asker waits for up to
``limits.sparql_timeout_s``; pyoxigraph cannot cancel a query, so one over time is abandoned, not
stopped, and runs on. :class:`QueryWorkers` keeps those threads so that a stop can refuse new queries
and wait for the ones still running (see :meth:`QueryWorkers.close`): no query thread is left to the
interpreter's finalization.

Example::

    media, body = run_query(store, "SELECT ?s WHERE { ?s a bot:Storey }", limits=config.limits)
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Callable

from twin.config import Limits
from twin.errors import QueryError, TwinError
from twin.graph.store import GraphStore

_PREFIXES = re.compile(r"^\s*((PREFIX|BASE)\s+[^\n]*\n?\s*)*", re.IGNORECASE)
_UPDATE = re.compile(r"^\s*(INSERT|DELETE|LOAD|CLEAR|DROP|CREATE|ADD|MOVE|COPY|WITH)\b", re.IGNORECASE)


class QueryWorkers:
    """The worker threads of the queries running (answered, abandoned or not yet): what a stop waits
    for. Any thread may start queries; :meth:`close` refuses new ones and waits for the running."""

    def __init__(self) -> None:
        self._running: set[threading.Thread] = set()
        self._lock = threading.Condition()
        self._closed = False

    def start(self, target: Callable[[], None]) -> threading.Thread:
        """Run ``target`` on a new worker; QueryError once closed (the twin is stopping)."""

        def run() -> None:
            try:
                target()
            finally:
                with self._lock:
                    self._running.discard(threading.current_thread())
                    self._lock.notify_all()

        with self._lock:
            if self._closed:
                msg = "The twin is stopping: no more SPARQL queries."
                raise QueryError(msg)
            worker = threading.Thread(target=run, name="twin-sparql", daemon=True)
            self._running.add(worker)
            worker.start()
        return worker

    @property
    def running(self) -> int:
        """Queries whose worker has not finished (abandoned ones included)."""
        with self._lock:
            return len(self._running)

    def close(self, timeout_s: float) -> int:
        """Refuse new queries, then wait up to ``timeout_s`` for the running ones; return how many
        are still running (0: every worker has ended)."""
        deadline = time.monotonic() + timeout_s
        with self._lock:
            self._closed = True
            self._lock.wait_for(lambda: not self._running, timeout=max(0.0, deadline - time.monotonic()))
            running = list(self._running)
        for worker in running:  # ended but not yet joined: a moment at most
            worker.join(max(0.0, deadline - time.monotonic()))
        return sum(w.is_alive() for w in running)


def run_query(
    store: GraphStore, sparql: str, *, limits: Limits, workers: QueryWorkers | None = None
) -> tuple[str, bytes]:
    """Run a read-only query; return (media type, bytes). QueryError names the problem: an update,
    a query over ``limits.sparql_timeout_s`` (abandoned), a result over ``limits.sparql_result_bytes``,
    ``workers`` closed (the twin is stopping). ``workers``: where the query's thread is kept (default:
    a set of its own, for a caller that never stops them)."""
    if _UPDATE.search(_PREFIXES.sub("", sparql)):
        msg = "This SPARQL endpoint is read-only: updates (INSERT, DELETE, LOAD, CLEAR, ...) are refused."
        raise QueryError(msg)
    result: list[tuple[str, bytes] | BaseException] = []

    def run() -> None:
        try:
            result.append(store.query_serialized(sparql))
        except BaseException as err:
            result.append(err)

    worker = (workers if workers is not None else QueryWorkers()).start(run)
    worker.join(limits.sparql_timeout_s)
    if not result:
        msg = f"The SPARQL query took longer than {limits.sparql_timeout_s} s and was abandoned."
        raise QueryError(msg)
    out = result[0]
    if isinstance(out, BaseException):
        if isinstance(out, TwinError):
            raise out
        msg = f"SPARQL query failed: {out}"
        raise QueryError(msg) from out
    if len(out[1]) > limits.sparql_result_bytes:
        msg = (
            f"The SPARQL result is {len(out[1]):,} bytes, more than the "
            f"{limits.sparql_result_bytes:,} allowed: add a LIMIT."
        )
        raise QueryError(msg)
    return out
