"""What the store can do now, as the twin last found it, and a store that keeps that up to date.

``twin status`` shows it in one field, ``store``:

- ``"ok"``;
- ``"read-only: <reason>"``: a write failed (the store's file system is full: ENOSPC, or an I/O error).
  Observations are refused with that reason (nothing is acked that is not durable); maps, SPARQL and
  status go on. RocksDB keeps such an error until the store is reopened: the writer tries that, and a
  probe write, every ``retry_s`` (:meth:`WatchedStore.recover`), and takes writes again once it works;
- ``"unreachable: <reason>"``: a remote store (``[store] url``) did not answer; the writer asks again
  every ``retry_s``.

Example::

    store = WatchedStore(EmbeddedStore.open(path))
    store.health.text                     # "ok"
    store.recover()                       # after a failure: reopen, probe; True once it is ok again
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import IO, TypeVar

import pyoxigraph as ox

from twin.errors import StoreError, StoreUnavailableError, StoreWriteError
from twin.graph import vocab
from twin.graph.rdf import ChangeSet, RdfLiteral, Row, Triple
from twin.graph.store import GraphStore

log = logging.getLogger(__name__)

T = TypeVar("T")
PROBE = Triple("urn:building-twin:probe", "urn:building-twin:probe", RdfLiteral("written", vocab.XSD_STRING))
"""Written and deleted in one transaction: a write that leaves the graph as it was."""


class StoreHealth:
    """``ok``, ``read-only`` or ``unreachable``, with the reason (any thread reads it)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.state = "ok"
        self.reason = ""
        self.since = time.monotonic()

    @property
    def text(self) -> str:
        """What ``twin status`` shows: ``ok``, ``read-only: <reason>`` or ``unreachable: <reason>``."""
        with self._lock:
            return self.state if self.state == "ok" else f"{self.state}: {self.reason}"

    @property
    def ok(self) -> bool:
        return self.state == "ok"

    def failed(self, err: StoreError) -> None:
        """Note a failure: StoreUnavailableError makes it unreachable, StoreWriteError read-only (other
        errors, e.g. a query that does not parse, say nothing of the store)."""
        state = (
            "unreachable" if isinstance(err, StoreUnavailableError)
            else "read-only" if isinstance(err, StoreWriteError)
            else None
        )  # fmt: skip
        if state is None:
            return
        with self._lock:
            changed = (self.state, self.reason) != (state, str(err))
            if self.state != state:
                self.since = time.monotonic()
            self.state, self.reason = state, str(err)
        if changed:
            log.error("The store is %s: %s", state, err)

    def worked(self, *, wrote: bool) -> None:
        """Note a success: a write clears any failure, a read clears ``unreachable``."""
        with self._lock:
            if self.state == "ok" or (not wrote and self.state != "unreachable"):
                return
            was = self.state
            self.state, self.reason, self.since = "ok", "", time.monotonic()
        log.warning("The store is ok again (was %s)", was)


class WatchedStore:
    """A :class:`~twin.graph.store.GraphStore` that notes every failure and success in :attr:`health`."""

    def __init__(self, inner: GraphStore, health: StoreHealth | None = None) -> None:
        self.inner = inner
        self.health = health or StoreHealth()

    def _call(self, run: Callable[[], T], *, wrote: bool) -> T:
        try:
            out = run()
        except StoreError as err:
            self.health.failed(err)
            raise
        self.health.worked(wrote=wrote)
        return out

    # --- GraphStore ---------------------------------------------------------------------------------
    def select(self, sparql: str) -> list[Row]:
        return self._call(lambda: self.inner.select(sparql), wrote=False)

    def iter_select(self, sparql: str) -> Iterator[Row]:
        return self._call(lambda: self.inner.iter_select(sparql), wrote=False)

    def ask(self, sparql: str) -> bool:
        return self._call(lambda: self.inner.ask(sparql), wrote=False)

    def query_serialized(self, sparql: str) -> tuple[str, bytes]:
        return self._call(lambda: self.inner.query_serialized(sparql), wrote=False)

    def apply(self, changes: ChangeSet, *more: ChangeSet) -> None:
        self._call(lambda: self.inner.apply(changes, *more), wrote=True)

    def flush(self) -> None:
        self.inner.flush()

    def bulk_add(self, quads: Iterable[ox.Quad]) -> None:
        self._call(lambda: self.inner.bulk_add(quads), wrote=True)

    def clear(self) -> None:
        self._call(self.inner.clear, wrote=True)

    def is_empty(self) -> bool:
        return self._call(self.inner.is_empty, wrote=False)

    def __len__(self) -> int:
        return self._call(self.inner.__len__, wrote=False)

    def dump_turtle(self, out: IO[bytes] | Path) -> None:
        self._call(lambda: self.inner.dump_turtle(out), wrote=False)

    def turtle_size(self) -> int:
        return self._call(self.inner.turtle_size, wrote=False)

    def close(self) -> None:
        self.inner.close()

    # --- recovery -----------------------------------------------------------------------------------
    def recover(self) -> bool:
        """Try to make the store work again; True if it is ok now. Read-only: reopen it (an embedded
        store: RocksDB keeps a write error until then), then a probe write that leaves the graph as it
        was. Unreachable: ask it something."""
        if self.health.ok:
            return True
        try:
            if self.health.state == "read-only":
                reopen = getattr(self.inner, "reopen", None)
                if reopen is not None:
                    reopen()
                self.apply(ChangeSet(add=(PROBE,)), ChangeSet(delete=(PROBE,)))
            else:
                self.ask("ASK { }")
        except StoreError as err:
            self.health.failed(err)
            log.debug("The store is still %s", self.health.text)
        return self.health.ok
