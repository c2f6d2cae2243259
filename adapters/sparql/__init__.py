"""The graph on a SPARQL 1.1 server: :class:`~adapters.sparql.remote_store.RemoteStore`, the
``GraphStore`` of the core spoken over HTTP (SPARQL 1.1 Protocol and Graph Store Protocol)."""

from __future__ import annotations

from adapters.sparql.remote_store import RemoteStore, SparqlEndpoint

__all__ = ["RemoteStore", "SparqlEndpoint"]
