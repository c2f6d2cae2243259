"""The graph's plain values and their SPARQL, shared by every :class:`~twin.graph.store.GraphStore`.

Going in: RDF literals, triples and change sets (:class:`ChangeSet`), written as one SPARQL 1.1
update (:func:`changes_to_sparql`). Coming out: query solutions as plain rows (:data:`Row`,
:func:`solution_rows`) and ASK answers. The embedded store (``twin.graph.store``) and the remote one
(``adapters.sparql.remote_store``) both use these, so the two cannot tell rows apart.

Example::

    is_open = Triple(door, TWIN + "isOpen", RdfLiteral("true", XSD + "boolean"))
    update = changes_to_sparql(ChangeSet(remove=((door, TWIN + "isOpen"),), add=(is_open,)))
    rows = list(solution_rows(oxigraph_store.query("SELECT ?s WHERE { ?s a bot:Storey }")))
"""

from __future__ import annotations

import functools
import io
import re
from collections.abc import Iterator
from dataclasses import dataclass

import pyoxigraph as ox

from twin.errors import QueryError, StoreError
from twin.graph import vocab

_SERVICE = re.compile(r"\bSERVICE\b", re.IGNORECASE)
_NOT_IN_IRI = re.compile(r'[<>"{}|\\^` \n]')
"""Characters an IRI in a change may not hold (N-Triples' IRIREF excludes them)."""
_NEEDS_ESCAPE = re.compile(r'[^\x20-\x7e]|["\\]')
"""Characters of a literal's lexical form that N-Triples escapes (or that pyoxigraph may): those
literals are written by pyoxigraph, the others as they are (the same text, without its cost)."""
_XSD_STRING = vocab.XSD + "string"

Term = ox.NamedNode | ox.BlankNode | ox.Literal | ox.Triple
Row = dict[str, str | None]
"""One solution of a SELECT: variable name -> lexical value of its term (IRI text, literal value), or
None when unbound."""


@dataclass(frozen=True, slots=True)
class RdfLiteral:
    """An RDF literal as a plain value: its lexical form and datatype IRI."""

    value: str
    datatype: str = vocab.XSD + "string"


Object = str | RdfLiteral
"""The object of a triple: an IRI (``str``) or a :class:`RdfLiteral`."""


@dataclass(frozen=True, slots=True)
class Triple:
    subject: str
    predicate: str
    object: Object


@dataclass(frozen=True, slots=True)
class ChangeSet:
    """One change: remove the triples matching ``remove`` and the triples ``delete``, then add ``add``.

    Attributes:
        remove: ``(subject, predicate)`` patterns; ``predicate`` None removes every triple of the subject.
        add: the triples to insert.
        delete: exact triples to remove (where a pattern would remove too much).
    """

    remove: tuple[tuple[str, str | None], ...] = ()
    add: tuple[Triple, ...] = ()
    delete: tuple[Triple, ...] = ()

    def __bool__(self) -> bool:
        return bool(self.remove or self.add or self.delete)


def _term(term: Term | None) -> str | None:
    if term is None:
        return None
    if isinstance(term, ox.Triple):
        return str(term)
    return term.value


@functools.lru_cache(maxsize=4096)
def _nt_iri(iri: str) -> str:
    """``<iri>``, checked (remembered: a change set names the same subjects and predicates again)."""
    if not iri or _NOT_IN_IRI.search(iri) is not None:
        msg = f"Not an IRI usable in a change: {iri!r}."
        raise StoreError(msg)
    return f"<{iri}>"


def _nt_object(obj: Object) -> str:
    if isinstance(obj, RdfLiteral):
        if _NEEDS_ESCAPE.search(obj.value) is not None:
            return str(ox.Literal(obj.value, datatype=ox.NamedNode(obj.datatype)))
        if obj.datatype == _XSD_STRING:
            return f'"{obj.value}"'
        return f'"{obj.value}"^^{_nt_iri(obj.datatype)}'
    return _nt_iri(obj)


def _nt(triples: tuple[Triple, ...]) -> str:
    return "\n".join(f"{_nt_iri(t.subject)} {_nt_iri(t.predicate)} {_nt_object(t.object)} ." for t in triples)


def changes_to_sparql(*changes: ChangeSet) -> str:
    """The SPARQL 1.1 update of ``changes``, each applied in turn (one request: a store runs it in one
    transaction)."""
    parts = []
    for change in changes:
        for subject, predicate in change.remove:
            p = _nt_iri(predicate) if predicate is not None else "?p"
            parts.append(f"DELETE WHERE {{ {_nt_iri(subject)} {p} ?o }}")
        if change.delete:
            parts.append(f"DELETE DATA {{\n{_nt(change.delete)}\n}}")
        if change.add:
            parts.append(f"INSERT DATA {{\n{_nt(change.add)}\n}}")
    return " ;\n".join(parts)


def uses_service(sparql: str) -> bool:
    """True if ``sparql`` mentions the SERVICE keyword (a federated, remote query)."""
    return _SERVICE.search(sparql) is not None


def reject_service(sparql: str) -> None:
    """QueryError if ``sparql`` uses SERVICE: every store answers from its own graph only."""
    if uses_service(sparql):
        msg = "SPARQL queries may not use SERVICE: the store answers from its own graph only."
        raise QueryError(msg)


def solution_rows(result: object) -> Iterator[Row]:
    """The plain rows (:data:`Row`) of a SELECT's ``ox.QuerySolutions``, lazily; QueryError for any
    other result. Every :class:`GraphStore` turns its solutions into rows here."""
    if not isinstance(result, ox.QuerySolutions):
        msg = "Expected a SELECT query."
        raise QueryError(msg)
    names = [v.value for v in result.variables]
    return ({n: _term(s[n]) for n in names} for s in result)


def boolean_answer(result: object) -> bool:
    """The answer of an ASK's ``ox.QueryBoolean``; QueryError for any other result."""
    if not isinstance(result, ox.QueryBoolean):
        msg = "Expected an ASK query."
        raise QueryError(msg)
    return bool(result)


class ByteCounter(io.RawIOBase):
    """A binary sink that only counts bytes (to measure a dump without keeping it)."""

    def __init__(self) -> None:
        self.count = 0

    def writable(self) -> bool:
        return True

    def write(self, b: bytes | bytearray | memoryview) -> int:  # type: ignore[override]
        n = len(b)
        self.count += n
        return n


def literal_value(term: Term | str | None) -> str | None:
    """The lexical value of a term (a plain row value passes through), None for an unbound variable."""
    if term is None or isinstance(term, str):
        return term
    return _term(term)
