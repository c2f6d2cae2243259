"""The graph store: the :class:`GraphStore` interface and its embedded pyoxigraph implementation.

The other implementation, on a remote SPARQL server, is ``adapters.sparql.remote_store``; what both
share (change sets as SPARQL updates, solutions as plain rows) is ``twin.graph.rdf``.

The embedded store is on disk by default (a directory, RocksDB), in memory when no path is given
(tests). Only one process can open an on-disk store for writing: the daemon owns it, others query
through the daemon.

Example::

    with EmbeddedStore.open(Path("site.store")) as store:
        rows = store.select("SELECT ?s WHERE { ?s a bot:Storey }")
"""

from __future__ import annotations

import contextlib
import gc
import io
import json
import logging
import re
import shutil
import threading
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import IO, Protocol, Self, runtime_checkable

import pyoxigraph as ox

from twin.errors import QueryError, StoreError, StoreNotFoundError, StoreWriteError
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

REOPEN_FREE_BYTES = 1 << 20
"""A store is reopened after a write error only once its file system has this much room (a new
write-ahead log, manifest and options files)."""
REOPEN_WAIT_S = 5.0
"""How long a reader waits for a reopen to hand it the new handle."""

# twin.live still imports these records from here; their home is twin.graph.rdf.
__all__ = ["EmbeddedStore", "GraphStore", "StoreInfo", "TextLoader"]


class GraphStore(Protocol):
    """What the core needs of a graph store. :class:`EmbeddedStore` is the embedded implementation."""

    def select(self, sparql: str) -> list[Row]: ...

    def iter_select(self, sparql: str) -> Iterator[Row]: ...

    def ask(self, sparql: str) -> bool: ...

    def query_serialized(self, sparql: str) -> tuple[str, bytes]: ...

    def apply(self, changes: ChangeSet, *more: ChangeSet) -> None: ...

    def flush(self) -> None: ...

    def bulk_add(self, quads: Iterable[ox.Quad]) -> None: ...

    def clear(self) -> None: ...

    def is_empty(self) -> bool: ...

    def __len__(self) -> int: ...

    def dump_turtle(self, out: IO[bytes] | Path) -> None: ...

    def turtle_size(self) -> int: ...

    def close(self) -> None: ...


@runtime_checkable
class TextLoader(Protocol):
    """A store that can bulk-load N-Triples text itself (faster than quads built in Python)."""

    def bulk_load_ntriples(self, data: bytes, *, iris_checked: bool = False) -> None: ...


@dataclass(frozen=True, slots=True)
class StoreInfo:
    path: Path | None
    read_only: bool


_CHAR_CLASS = re.compile(r"\[[^\]]*\]")
_POSITION = re.compile(r"^error at (\d+):(\d+): expected (?:one of )?(.*)$")


def syntax_error_text(err: Exception, text: str) -> str:
    """Oxigraph's SyntaxError in one readable line: ``at line 1, column 27 (after '{ ?e ?p ?o'):
    expected one of ',', '.', '}', a letter or digit`` (its character classes named, not listed)."""
    message = " ".join(str(err).split())
    m = _POSITION.match(message)
    if m is None:
        return f": {message}"
    line, column, expected = int(m[1]), int(m[2]), m[3]
    classes = _CHAR_CLASS.findall(expected)
    tokens = [t for t in (t.strip() for t in _CHAR_CLASS.sub("", expected).split(", ")) if t]
    if any("'0'" in c for c in classes):
        tokens.append("a digit")
    if any("'A'" in c or "'a'" in c for c in classes):
        tokens.append("a letter")
    lines = text.splitlines() or [""]
    before = lines[line - 1][: column - 1] if 0 < line <= len(lines) else ""
    near = f" (after {before[-20:].strip()!r})" if before.strip() else ""
    wanted = ", ".join(tokens) or "something else"
    return f"at line {line}, column {column}{near}: expected {'one of ' if len(tokens) > 1 else ''}{wanted}"


class EmbeddedStore:
    """The embedded pyoxigraph store (a :class:`GraphStore`). Use :meth:`open` and close it (or ``with``)."""

    def __init__(self, store: ox.Store, info: StoreInfo) -> None:
        self._handle: ox.Store | None = store
        self.info = info
        self._reopened_read_only: str | None = None
        """Why a store opened for writing holds a read-only handle now (a failed :meth:`reopen`)."""
        self._open = threading.Event()
        self._open.set()  # cleared while :meth:`reopen` swaps the handle: readers wait for it

    @property
    def _store(self) -> ox.Store:
        if self._handle is None:
            self._open.wait(REOPEN_WAIT_S)
        handle = self._handle
        if handle is None:
            msg = f"The store at {self.info.path or 'memory'} is closed."
            raise StoreError(msg)
        return handle

    # --- lifecycle --------------------------------------------------------------------------------
    @classmethod
    def open(cls, path: Path | None = None, *, read_only: bool = False, create: bool = True) -> EmbeddedStore:
        """Open the store at ``path`` (a directory), or an in-memory store when ``path`` is None."""
        if path is None:
            return cls(ox.Store(), StoreInfo(None, read_only=read_only))
        path = Path(path)
        if path.exists() and not path.is_dir():
            msg = f"Store path {path} exists and is not a directory."
            raise StoreError(msg)
        if not path.exists():
            if read_only or not create:
                msg = f"No store at {path}."
                raise StoreNotFoundError(msg)
            path.mkdir(parents=True)
        try:
            store = ox.Store.read_only(str(path)) if read_only else ox.Store(str(path))
        except OSError as err:
            hint = " (is another process, e.g. the daemon, using it?)" if "lock" in str(err).lower() else ""
            msg = f"Cannot open the store at {path}{hint}: {err}"
            raise StoreError(msg) from err
        return cls(store, StoreInfo(path, read_only))

    def close(self) -> None:
        """Flush and release the store; closing twice is harmless."""
        if self._handle is None:
            return
        try:
            if not self.info.read_only and self.info.path is not None and self._reopened_read_only is None:
                self._handle.flush()
        except OSError as err:  # a full disk: the commits are in the write-ahead log already
            log.warning("Could not flush the store at %s on closing: %s", self.info.path, err)
        self._handle = None

    def reopen(self) -> None:
        """Close the on-disk store and open it again: RocksDB keeps a write error (e.g. ENOSPC) until
        then. If it cannot be opened for writing (a disk still full, a query still holding the old
        handle) it is opened read-only, so reads go on, and StoreWriteError says why."""
        path = self.info.path
        if path is None or self.info.read_only:
            return
        free = shutil.disk_usage(path).free
        if free < REOPEN_FREE_BYTES:  # keep the handle (reads go on) until there is room to write
            msg = f"No space left on device: {free:,} bytes free for the store at {path}."
            raise StoreWriteError(msg)
        self._open.clear()
        try:
            self._handle = None
            gc.collect()  # the old handle's last references: its RocksDB lock goes with it
            try:
                self._handle = ox.Store(str(path))
                self._reopened_read_only = None
            except OSError as err:
                msg = f"Cannot open the store at {path} for writing again: {err}"
                self._reopened_read_only = msg
                with contextlib.suppress(OSError):
                    self._handle = ox.Store.read_only(str(path))
                raise StoreWriteError(msg) from err
        finally:
            self._open.set()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    # --- writing ------------------------------------------------------------------------------------
    def _writable(self) -> ox.Store:
        if self.info.read_only:
            msg = f"The store at {self.info.path} is open read-only."
            raise StoreError(msg)
        if self._reopened_read_only is not None:
            raise StoreWriteError(self._reopened_read_only)
        return self._store

    def bulk_add(self, quads: Iterable[ox.Quad]) -> None:
        """Add many quads at once (initial loads). Not atomic: use :meth:`add` for live changes."""
        self._writable().bulk_extend(quads)

    def bulk_load_ntriples(self, data: bytes, *, iris_checked: bool = False) -> None:
        """Add N-Triples text at once (initial loads; not atomic). The parsing and writing run without
        the GIL, so another thread can work meanwhile. ``iris_checked``: every IRI in ``data`` was
        checked when the text was made, so the parser does not check them again (about 12 % less
        CPU on 300,000 triples); anything else is still checked."""
        try:
            self._writable().bulk_load(data, format=ox.RdfFormat.N_TRIPLES, lenient=iris_checked)
        except SyntaxError as err:
            msg = f"N-Triples to load do not parse: {err}"
            raise StoreError(msg) from err

    def add(self, quads: Iterable[ox.Quad]) -> None:
        """Add quads atomically."""
        self._writable().extend(quads)

    def apply(self, changes: ChangeSet, *more: ChangeSet) -> None:
        """Apply ``changes`` (then each of ``more``, in turn) in one transaction (all or nothing),
        durable once this returns."""
        todo = [c for c in (changes, *more) if c]
        if todo:
            self.update(changes_to_sparql(*todo))

    def flush(self) -> None:
        """Write the store's in-memory buffers to its files (RocksDB memtables to SST files).

        Commits are durable without it (the write-ahead log); the daemon calls it now and then so that
        neither the memory the buffers hold nor the log grows with the number of changes."""
        if (
            self._handle is not None
            and not self.info.read_only
            and self.info.path is not None
            and self._reopened_read_only is None
        ):
            self._handle.flush()

    def update(self, sparql_update: str) -> None:
        """Run a SPARQL 1.1 update atomically (the vocabulary's prefixes are predefined)."""
        try:
            self._writable().update(sparql_update, prefixes=vocab.PREFIXES)
        except SyntaxError as err:
            msg = f"SPARQL update does not parse {syntax_error_text(err, sparql_update)}"
            raise QueryError(msg) from err
        except OSError as err:  # RocksDB: a full disk, an I/O error; it keeps refusing until reopened
            msg = f"The store at {self.info.path or 'memory'} could not write: {err}"
            raise StoreWriteError(msg) from err

    def clear(self) -> None:
        self._writable().clear()

    # --- reading ----------------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self._store)

    def is_empty(self) -> bool:
        return next(iter(self._store.quads_for_pattern(None, None, None)), None) is None

    def _query(self, sparql: str) -> ox.QuerySolutions | ox.QueryBoolean | ox.QueryTriples:
        reject_service(sparql)
        try:
            return self._store.query(sparql, prefixes=vocab.PREFIXES)
        except SyntaxError as err:
            msg = f"SPARQL query does not parse {syntax_error_text(err, sparql)}"
            raise QueryError(msg) from err
        except OSError as err:
            msg = f"SPARQL query failed: {err}"
            raise QueryError(msg) from err

    def select(self, sparql: str) -> list[Row]:
        """Run a SELECT query; one plain row per solution (see :data:`Row`)."""
        return list(self.iter_select(sparql))

    def iter_select(self, sparql: str) -> Iterator[Row]:
        """Like :meth:`select`, lazily."""
        return solution_rows(self._query(sparql))

    def ask(self, sparql: str) -> bool:
        return boolean_answer(self._query(sparql))

    def query_serialized(self, sparql: str) -> tuple[str, bytes]:
        """Run any read-only query; return (media type, bytes): SPARQL JSON results, or Turtle for graphs."""
        result = self._query(sparql)
        if isinstance(result, ox.QueryTriples):
            buf = io.BytesIO()
            result.serialize(buf, format=ox.RdfFormat.TURTLE)
            return "text/turtle", buf.getvalue()
        buf = io.BytesIO()
        result.serialize(buf, format=ox.QueryResultsFormat.JSON)
        return "application/sparql-results+json", buf.getvalue()

    def query_json(self, sparql: str) -> dict[str, object]:
        media, body = self.query_serialized(sparql)
        if media != "application/sparql-results+json":
            msg = "Expected a SELECT or ASK query for JSON results."
            raise QueryError(msg)
        value: dict[str, object] = json.loads(body)
        return value

    def dump_turtle(self, out: IO[bytes] | Path) -> None:
        """Write the default graph as Turtle with the LBD prefixes."""
        target: IO[bytes] | str = str(out) if isinstance(out, Path) else out
        self._store.dump(
            target, format=ox.RdfFormat.TURTLE, from_graph=ox.DefaultGraph(), prefixes=vocab.PREFIXES
        )

    def backup(self, target: Path) -> None:
        """Copy the on-disk store into the new directory ``target``: a consistent copy that opens as a store.

        Works on a read-only handle while another process (the daemon) writes the store."""
        if self.info.path is None:
            msg = "An in-memory store has nothing on disk to back up."
            raise StoreError(msg)
        if target.exists():
            msg = f"Backup target {target} exists: give a new directory."
            raise StoreError(msg)
        target.parent.mkdir(parents=True, exist_ok=True)
        self._store.backup(str(target))

    def turtle_size(self) -> int:
        """Bytes of :meth:`dump_turtle` output, without keeping it in memory."""
        sink = ByteCounter()
        self._store.dump(
            sink,  # type: ignore[arg-type]  # any binary writer works
            format=ox.RdfFormat.TURTLE,
            from_graph=ox.DefaultGraph(),
            prefixes=vocab.PREFIXES,
        )
        return sink.count
