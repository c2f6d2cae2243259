"""The triples an observation writes: exact deletes of what the writer last wrote, and the adds.

Example::

    w = TripleWriter(held)
    w.set(iri, vocab.TWIN_OBSERVED_BY, literal("robot1"))
    changes = ChangeSet(remove=tuple(w.remove), add=tuple(w.add), delete=tuple(w.delete))
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from twin.graph import vocab
from twin.graph.meshcodec import encode_mesh, encode_placement
from twin.graph.rdf import Object, RdfLiteral, Triple
from twin.records import FloatArray, Mesh

Held = Mapping[str, Mapping[str, Object | None]]
"""Subject -> predicate -> the exact object of the single-valued triples the writer last wrote."""


@dataclass(slots=True)
class TripleWriter:
    """The triples one observation removes (patterns and exact triples) and adds.

    A single-valued triple the writer wrote before is replaced by deleting that exact triple: a pattern
    (``DELETE WHERE``) would scan every version the store still holds as a tombstone, which grows with
    every change until compaction; an exact delete costs the same all day.
    """

    held: Held
    remove: list[tuple[str, str | None]] = field(default_factory=list)
    delete: list[Triple] = field(default_factory=list)
    add: list[Triple] = field(default_factory=list)
    written: dict[str, dict[str, Object | None]] = field(default_factory=dict)
    cleared: set[str] = field(default_factory=set)

    def _current(self, subject: str, predicate: str) -> Object | bool | None:
        """The object held now, None if there is none, False if unknown (a pattern must remove it)."""
        mine = self.written.get(subject)
        if mine is not None and (predicate in mine or subject in self.cleared):
            return mine.get(predicate)
        held = self.held.get(subject)
        if held is not None and predicate in held:
            return held[predicate]
        return False

    def set(self, subject: str, predicate: str, obj: Object | None) -> None:
        """Make ``obj`` the one object of ``(subject, predicate)`` (None: remove it)."""
        current = self._current(subject, predicate)
        if current == obj:
            return
        if current is False:
            self.remove.append((subject, predicate))
        elif current is not None and not isinstance(current, bool):
            self.delete.append(Triple(subject, predicate, current))
        if obj is not None:
            self.add.append(Triple(subject, predicate, obj))
        self.written.setdefault(subject, {})[predicate] = obj

    def clear(self, subject: str) -> None:
        """Remove every triple of ``subject``."""
        self.remove.append((subject, None))
        self.written[subject] = {}
        self.cleared.add(subject)

    def changed(self) -> tuple[int, int, int]:
        return (len(self.remove), len(self.delete), len(self.add))


def literal(value: str, datatype: str = vocab.XSD_STRING) -> RdfLiteral:
    return RdfLiteral(value, datatype)


def boolean(value: bool) -> RdfLiteral:
    return RdfLiteral("true" if value else "false", vocab.XSD_BOOLEAN)


def geometry_triples(iri: str, mesh: Mesh, placement: FloatArray) -> list[Triple]:
    g = vocab.geometry_iri(iri)
    return [
        Triple(iri, vocab.OMG_HAS_GEOMETRY, g),
        Triple(g, vocab.RDF_TYPE, vocab.OMG_GEOMETRY),
        Triple(g, vocab.FOG_PLY_BINARY_LE, literal(encode_mesh(mesh), vocab.XSD_BASE64)),
        Triple(g, vocab.TWIN_PLACEMENT, literal(encode_placement(placement), vocab.TWIN_MATRIX4)),
        Triple(g, vocab.TWIN_CLOSED, boolean(mesh.closed)),
        Triple(g, vocab.TWIN_TRIANGLES, literal(str(mesh.triangle_count), vocab.XSD_INTEGER)),
        *([Triple(g, vocab.TWIN_SOLID, boolean(True))] if mesh.solid else []),
    ]
