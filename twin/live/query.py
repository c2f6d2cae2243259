"""Read-only SPARQL for anyone (operators, robots), bounded in time and result size.

Example::

    media, body = run_query(store, "SELECT ?s WHERE { ?s a bot:Storey }", limits=config.limits)
"""

from __future__ import annotations

import re
import threading

from twin.config import Limits
from twin.errors import QueryError, TwinError
from twin.graph.store import GraphStore

_PREFIXES = re.compile(r"^\s*((PREFIX|BASE)\s+[^\n]*\n?\s*)*", re.IGNORECASE)
_UPDATE = re.compile(r"^\s*(INSERT|DELETE|LOAD|CLEAR|DROP|CREATE|ADD|MOVE|COPY|WITH)\b", re.IGNORECASE)


def run_query(store: GraphStore, sparql: str, *, limits: Limits) -> tuple[str, bytes]:
    """Run a read-only query; return (media type, bytes). QueryError names the problem: an update,
    a query over ``limits.sparql_timeout_s`` (abandoned), a result over ``limits.sparql_result_bytes``."""
    if _UPDATE.search(_PREFIXES.sub("", sparql)):
        msg = "This SPARQL endpoint is read-only: updates (INSERT, DELETE, LOAD, CLEAR, ...) are refused."
        raise QueryError(msg)
    result: list[tuple[str, bytes] | BaseException] = []

    def run() -> None:
        try:
            result.append(store.query_serialized(sparql))
        except BaseException as err:
            result.append(err)

    worker = threading.Thread(target=run, name="twin-sparql", daemon=True)
    worker.start()
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
