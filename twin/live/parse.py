"""Observations: what robots report about elements, parsed from Turtle into typed records.

An observation is a Turtle document (N-Triples is valid Turtle) with one or more element
descriptions; the subjects are element IRIs (see ``docs/observations.md`` for the wire format).
This module checks everything that needs no graph: the syntax, the known terms, one value per term,
finite numbers, sizes and counts within :class:`~twin.config.Limits`. What needs the graph (does the
element exist, is it static, may this robot change it) is checked by :mod:`twin.live`.

Example::

    reports = parse_observation(b'''
        @prefix twin: <https://w3id.org/building-twin#> .
        <urn:robot1:table-1> twin:ifcClass "IfcFurniture" ; twin:storey "ground-floor" ;
            twin:box "2.0 3.0 0.375 1.2 0.8 0.75 0.0" .
    ''', limits=Limits())
    reports[0].box.sx        # 1.2
"""

from __future__ import annotations

import math
import re
from collections import defaultdict

import numpy as np
import pyoxigraph as ox

from twin.config import Limits
from twin.errors import ModelError, ObservationError
from twin.graph import vocab
from twin.graph.meshcodec import decode_mesh, decode_placement
from twin.live.box_document import parse_box_document
from twin.live.sense_time import sense_time_ns
from twin.live.validate import (
    MAX_LIFETIME_S,
    MAX_VIEW_POINTS,
    check_iri,
    check_observation,
    check_report,
    check_view,
)
from twin.records import ElementReport, FloatArray, Geometry, Observation, ObservedBox, ObservedView

__all__ = [
    "MAX_VIEW_POINTS",
    "check_observation",
    "parse_observation",
    "parse_observation_document",
    "sense_time_ns",
]

_CLASS_NAMESPACES = (vocab.BEO, vocab.FURN)
_VIEW_CLASS = ox.NamedNode(vocab.TWIN_VIEW)


def _fail(message: str) -> ObservationError:
    return ObservationError(message)


def _parse_turtle(payload: bytes) -> list[ox.Triple]:
    try:
        return [
            t if isinstance(t, ox.Triple) else t.triple
            for t in ox.parse(payload, format=ox.RdfFormat.TURTLE, without_named_graphs=True)
        ]
    except SyntaxError as err:
        first = str(err).splitlines()[0] if str(err) else "syntax error"
        raise _fail(f"Observation is not valid Turtle: {first}") from err
    except UnicodeDecodeError as err:
        raise _fail(f"Observation is not UTF-8 text: {err}") from err


def _name(term: ox.NamedNode | ox.BlankNode | ox.Literal | ox.Triple) -> str:
    if isinstance(term, ox.NamedNode):
        return f"<{term.value}>"
    return str(term)


def _one(subject: str, predicate: str, values: list[ox.Literal | ox.NamedNode | ox.BlankNode]) -> object:
    if len(values) != 1:
        raise _fail(f"Element <{subject}> has {len(values)} values for <{predicate}>; give exactly one.")
    return values[0]


def _literal(subject: str, predicate: str, values: list[object], datatypes: tuple[str, ...]) -> ox.Literal:
    term = _one(subject, predicate, values)  # type: ignore[arg-type]
    if not isinstance(term, ox.Literal) or term.datatype.value not in datatypes:
        short = predicate.rsplit("#", 1)[-1]
        kinds = " or ".join(d.rsplit("#", 1)[-1] for d in datatypes)
        raise _fail(f"Element <{subject}>: twin:{short} must be a literal of type {kinds}, got {term}.")
    return term


def _numbers(subject: str, what: str, text: str, count: int) -> list[float]:
    parts = text.split()
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise _fail(f"Element <{subject}>: {what} must be {count} numbers, got {text[:120]!r}.") from None
    if len(values) != count:
        raise _fail(
            f"Element <{subject}>: {what} must be {count} numbers, got {len(values)} in {text[:120]!r}."
        )
    if not all(math.isfinite(v) for v in values):
        raise _fail(f"Element <{subject}>: {what} has a NaN or infinite number: {text[:120]!r}.")
    return values


def _box(subject: str, text: str) -> ObservedBox:
    cx, cy, cz, sx, sy, sz, yaw = _numbers(subject, "twin:box", text, 7)
    return ObservedBox(cx, cy, cz, sx, sy, sz, yaw)


def _placement(subject: str, text: str) -> FloatArray:
    _numbers(subject, "twin:placement", text, 16)
    try:
        return decode_placement(text)
    except ModelError as err:
        raise _fail(f"Element <{subject}>: {err}") from err


def _geometry(
    subject: str,
    node: ox.NamedNode | ox.BlankNode,
    by_subject: dict[str, dict[str, list[object]]],
    limits: Limits,
) -> Geometry:
    props = by_subject.pop(_name(node), None)
    if props is None:
        raise _fail(f"Element <{subject}>: its omg:hasGeometry node {node} has no fog:asPly_v1.0-binaryLE.")
    allowed = {vocab.FOG_PLY_BINARY_LE, vocab.TWIN_PLACEMENT, vocab.RDF_TYPE}
    for predicate in props:
        if predicate not in allowed:
            raise _fail(f"Element <{subject}>: unknown term <{predicate}> on its geometry node.")
    if vocab.FOG_PLY_BINARY_LE not in props:
        raise _fail(f"Element <{subject}>: its geometry node has no fog:asPly_v1.0-binaryLE literal.")
    ply = _literal(subject, vocab.FOG_PLY_BINARY_LE, props[vocab.FOG_PLY_BINARY_LE], (vocab.XSD_BASE64,))
    try:
        mesh = decode_mesh(ply.value)
    except ModelError as err:
        raise _fail(f"Element <{subject}>: its mesh is unusable: {err}") from err
    if mesh.triangle_count > limits.triangles_per_mesh:
        raise _fail(
            f"Element <{subject}>: its mesh has {mesh.triangle_count} triangles, "
            f"more than the {limits.triangles_per_mesh} allowed."
        )
    if mesh.triangle_count == 0:
        raise _fail(f"Element <{subject}>: its mesh has no triangles.")
    placement = (
        _placement(
            subject,
            _literal(
                subject,
                vocab.TWIN_PLACEMENT,
                props[vocab.TWIN_PLACEMENT],
                (vocab.TWIN_MATRIX4, vocab.XSD_STRING),
            ).value,
        )
        if vocab.TWIN_PLACEMENT in props
        else None
    )
    return Geometry(mesh) if placement is None else Geometry(mesh, placement)


_ELEMENT_TERMS = {
    vocab.TWIN_IFC_CLASS,
    vocab.TWIN_STOREY,
    vocab.TWIN_BOX,
    vocab.OMG_HAS_GEOMETRY,
    vocab.TWIN_PLACEMENT,
    vocab.TWIN_IS_OPEN,
    vocab.TWIN_REMOVED,
    vocab.TWIN_KEEPOUT,
    vocab.TWIN_SPEED_LIMIT,
    vocab.RDFS_LABEL,
    vocab.TWIN_MATERIAL,
    vocab.RDF_TYPE,
    vocab.TWIN_SENSE_TIME,
    vocab.TWIN_DISTINCT,
    vocab.TWIN_UNMERGE,
    vocab.TWIN_LIFETIME,
}
_VIEW_TERMS = {
    vocab.RDF_TYPE,
    vocab.TWIN_STOREY,
    vocab.TWIN_POLYGON,
    vocab.TWIN_HOLE,
    vocab.TWIN_ORIGIN,
    vocab.TWIN_DETECTS,
    vocab.TWIN_SENSE_TIME,
}


def _sense(subject: str, values: list[object]) -> int:
    text = _literal(subject, vocab.TWIN_SENSE_TIME, values, (vocab.XSD_DATETIME, vocab.XSD_STRING)).value
    try:
        return sense_time_ns(text)
    except (ValueError, OverflowError):
        raise _fail(f"Element <{subject}>: twin:senseTime {text[:80]!r} is not an xsd:dateTime.") from None


def _flag(subject: str, predicate: str, values: list[object]) -> bool:
    value = _literal(subject, predicate, values, (vocab.XSD_BOOLEAN,)).value
    return value in ("true", "1")


def _strings(subject: str, predicate: str, values: list[object], *, limit: int = 1024) -> tuple[str, ...]:
    out = []
    for v in values:
        if not isinstance(v, ox.Literal):
            raise _fail(f"Element <{subject}>: <{predicate}> must be a literal, got {v}.")
        if len(v.value) > limit:
            raise _fail(f"Element <{subject}>: <{predicate}> is longer than {limit} characters.")
        out.append(v.value)
    return tuple(out)


def _report(
    subject: str,
    props: dict[str, list[object]],
    by_subject: dict[str, dict[str, list[object]]],
    limits: Limits,
) -> ElementReport:
    check_iri(subject)
    for predicate in props:
        if predicate not in _ELEMENT_TERMS:
            raise _fail(
                f"Element <{subject}>: unknown term <{predicate}> (known: twin:ifcClass, twin:storey, "
                "twin:box, omg:hasGeometry, twin:placement, twin:isOpen, twin:removed, twin:keepout, "
                "twin:speedLimit, rdfs:label, twin:material, rdf:type, twin:senseTime, twin:distinct, "
                "twin:unmerge, twin:lifetime)."
            )
    args: dict[str, object] = {"iri": subject}
    if vocab.TWIN_IFC_CLASS in props:
        value = _literal(
            subject, vocab.TWIN_IFC_CLASS, props[vocab.TWIN_IFC_CLASS], (vocab.XSD_STRING,)
        ).value
        args["ifc_class"] = value
    if vocab.TWIN_STOREY in props:
        args["storey"] = _literal(
            subject, vocab.TWIN_STOREY, props[vocab.TWIN_STOREY], (vocab.XSD_STRING,)
        ).value
    if vocab.TWIN_BOX in props:
        text = _literal(subject, vocab.TWIN_BOX, props[vocab.TWIN_BOX], (vocab.XSD_STRING,)).value
        args["box"] = _box(subject, text)
    if vocab.OMG_HAS_GEOMETRY in props:
        node = _one(subject, vocab.OMG_HAS_GEOMETRY, props[vocab.OMG_HAS_GEOMETRY])  # type: ignore[arg-type]
        if not isinstance(node, ox.NamedNode | ox.BlankNode):
            raise _fail(f"Element <{subject}>: omg:hasGeometry must point to a node, got {node}.")
        args["geometry"] = _geometry(subject, node, by_subject, limits)
    if vocab.TWIN_PLACEMENT in props:
        text = _literal(
            subject, vocab.TWIN_PLACEMENT, props[vocab.TWIN_PLACEMENT], (vocab.TWIN_MATRIX4, vocab.XSD_STRING)
        ).value
        args["placement"] = _placement(subject, text)
    if vocab.TWIN_IS_OPEN in props:
        args["is_open"] = _literal(
            subject, vocab.TWIN_IS_OPEN, props[vocab.TWIN_IS_OPEN], (vocab.XSD_BOOLEAN,)
        ).value in ("true", "1")
    if vocab.TWIN_REMOVED in props:
        removed = _literal(subject, vocab.TWIN_REMOVED, props[vocab.TWIN_REMOVED], (vocab.XSD_BOOLEAN,)).value
        if removed not in ("true", "1"):
            raise _fail(f"Element <{subject}>: twin:removed can only be true.")
        args["removed"] = True
    if vocab.TWIN_KEEPOUT in props:
        args["keepout"] = _literal(
            subject, vocab.TWIN_KEEPOUT, props[vocab.TWIN_KEEPOUT], (vocab.XSD_BOOLEAN,)
        ).value in ("true", "1")
    if vocab.TWIN_SPEED_LIMIT in props:
        text = _literal(
            subject, vocab.TWIN_SPEED_LIMIT, props[vocab.TWIN_SPEED_LIMIT], (vocab.XSD_INTEGER,)
        ).value
        if not re.fullmatch(r"[+-]?[0-9]{1,4}", text.strip()):
            raise _fail(
                f"Element <{subject}>: twin:speedLimit must be a percent from 0 (no limit) to 100, "
                f"got {text!r}."
            )
        args["speed_limit"] = int(text)
    if vocab.RDFS_LABEL in props:
        args["labels"] = _strings(subject, vocab.RDFS_LABEL, props[vocab.RDFS_LABEL])
    if vocab.TWIN_MATERIAL in props:
        args["materials"] = _strings(subject, vocab.TWIN_MATERIAL, props[vocab.TWIN_MATERIAL])
    if vocab.RDF_TYPE in props:
        classes = []
        for v in props[vocab.RDF_TYPE]:
            if not isinstance(v, ox.NamedNode) or not (
                v.value.startswith(_CLASS_NAMESPACES) or v.value == vocab.BOT_ELEMENT
            ):  # (a twin:View is a node of its own: see _view)
                raise _fail(
                    f"Element <{subject}>: rdf:type {v} is not allowed; only BEO and FURN classes "
                    "(e.g. furn:Table) and bot:Element."
                )
            classes.append(v.value)
        args["classes"] = tuple(classes)
    if vocab.TWIN_SENSE_TIME in props:
        args["sense_ns"] = _sense(subject, props[vocab.TWIN_SENSE_TIME])
    if vocab.TWIN_DISTINCT in props:
        args["distinct"] = _flag(subject, vocab.TWIN_DISTINCT, props[vocab.TWIN_DISTINCT])
    if vocab.TWIN_UNMERGE in props:
        args["unmerge"] = _flag(subject, vocab.TWIN_UNMERGE, props[vocab.TWIN_UNMERGE])
    if vocab.TWIN_LIFETIME in props:
        numeric = (vocab.XSD_DECIMAL, vocab.XSD_DOUBLE, vocab.XSD_INTEGER)
        text = _literal(subject, vocab.TWIN_LIFETIME, props[vocab.TWIN_LIFETIME], numeric).value
        try:
            lifetime = float(text)
        except ValueError:
            lifetime = math.nan
        if math.isnan(lifetime):
            raise _fail(
                f"Element <{subject}>: twin:lifetime must be seconds from 0 to {MAX_LIFETIME_S:g}, "
                f"got {text[:80]!r}."
            )
        args["lifetime_s"] = lifetime
    return check_report(ElementReport(**args), limits=limits)  # type: ignore[arg-type]


def _view(name: str, props: dict[str, list[object]]) -> ObservedView:
    where = f"The view {name}"
    for predicate in props:
        if predicate not in _VIEW_TERMS:
            raise _fail(
                f"{where}: unknown term <{predicate}> (known: twin:storey, twin:polygon, twin:hole, "
                "twin:origin, twin:detects, twin:senseTime)."
            )
    if vocab.TWIN_STOREY not in props:
        raise _fail(f"{where} has no twin:storey.")
    storey = _literal(name, vocab.TWIN_STOREY, props[vocab.TWIN_STOREY], (vocab.XSD_STRING,)).value
    points = 0
    rings: dict[str, list[FloatArray]] = {}
    for term, predicate in (("twin:polygon", vocab.TWIN_POLYGON), ("twin:hole", vocab.TWIN_HOLE)):
        rings[term] = []
        for text in _strings(name, predicate, props.get(predicate, []), limit=1 << 17):
            parts = text.split()
            if len(parts) < 6 or len(parts) % 2:
                raise _fail(
                    f"{where}: {term} must be x y pairs of at least 3 points, got {len(parts)} numbers."
                )
            values = _numbers(name, term, text, len(parts))
            points += len(values) // 2
            if points > MAX_VIEW_POINTS:
                raise _fail(f"{where}: its polygons have more than {MAX_VIEW_POINTS} points.")
            rings[term].append(np.asarray(values, dtype=np.float64).reshape(-1, 2))
    polygons, holes = rings["twin:polygon"], rings["twin:hole"]
    origin = None
    if vocab.TWIN_ORIGIN in props:
        texts = _strings(name, vocab.TWIN_ORIGIN, props[vocab.TWIN_ORIGIN])
        if len(texts) != 1:
            raise _fail(f"{where}: give one twin:origin, got {len(texts)}.")
        x, y, z = _numbers(name, "twin:origin", texts[0], 3)
        origin = (x, y, z)
    if not polygons:
        raise _fail(f"{where} has no twin:polygon (the floor its sensor saw).")
    detects = _strings(name, vocab.TWIN_DETECTS, props.get(vocab.TWIN_DETECTS, []))
    sense = _sense(name, props[vocab.TWIN_SENSE_TIME]) if vocab.TWIN_SENSE_TIME in props else None
    view = ObservedView(
        storey, tuple(polygons), tuple(dict.fromkeys(detects)), sense, holes=tuple(holes), origin=origin
    )
    return check_view(view, name=name)


def parse_observation(payload: bytes | str, *, limits: Limits) -> tuple[ElementReport, ...]:
    """The element reports of an observation document (see :func:`parse_observation_document`)."""
    return parse_observation_document(payload, limits=limits).reports


def parse_observation_document(payload: bytes | str, *, limits: Limits) -> Observation:
    """Parse and check an observation document; ObservationError names the first problem.

    Args:
        payload: the Turtle document (bytes, UTF-8).
        limits: payload size, element count, mesh size and box size limits.

    Returns:
        One report per described element, in IRI order, and the view (``a twin:View``) if it has one.
    """
    data = payload.encode() if isinstance(payload, str) else bytes(payload)
    if len(data) > limits.payload_bytes:
        raise _fail(f"Observation is {len(data):,} bytes, more than the {limits.payload_bytes:,} allowed.")
    if not data.strip():
        raise _fail("Observation is empty: it must describe at least one element.")
    if (common := parse_box_document(data, limits=limits)) is not None:
        return common  # boxes in N-Triples form, read without an RDF parser: the same reports
    triples = _parse_turtle(data)
    by_subject: dict[str, dict[str, list[object]]] = defaultdict(lambda: defaultdict(list))
    objects_of_geometry: set[str] = set()
    views: list[str] = []
    for t in triples:
        by_subject[_name(t.subject)][t.predicate.value].append(t.object)
        if t.predicate.value == vocab.OMG_HAS_GEOMETRY:
            objects_of_geometry.add(_name(t.object))
        if t.predicate.value == vocab.RDF_TYPE and t.object == _VIEW_CLASS:
            views.append(_name(t.subject))
    if len(set(views)) > 1:
        raise _fail(f"Observation has {len(set(views))} views; give at most one twin:View.")
    view = _view(views[0], dict(by_subject.pop(views[0]))) if views else None
    subjects = sorted(s for s in by_subject if s not in objects_of_geometry)
    for s in subjects:
        if not s.startswith("<"):
            raise _fail(f"Observation describes a blank node {s}: element subjects must be IRIs.")
    if len(subjects) > limits.elements_per_observation:
        raise _fail(
            f"Observation describes {len(subjects)} elements, more than the "
            f"{limits.elements_per_observation} allowed."
        )
    if not subjects and view is None:
        raise _fail("Observation describes no element.")
    reports = [_report(s[1:-1], dict(by_subject.pop(s)), by_subject, limits) for s in subjects]
    leftover = sorted(by_subject)
    if leftover:
        raise _fail(f"Observation has triples about {leftover[0]} that belong to no element.")
    return Observation(tuple(reports), view)
