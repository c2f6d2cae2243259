"""The common observation read without an RDF parser: boxes and descriptive strings in N-Triples form.

Robots re-report what they see many times a second, most often as a few statements per element::

    <urn:robot1:table-1> <https://w3id.org/building-twin#ifcClass> "IfcFurniture" ;
        <https://w3id.org/building-twin#storey> "ground-floor" ;
        <https://w3id.org/building-twin#box> "2.0 3.0 0.375 1.2 0.8 0.75 0.0" .

:func:`parse_box_document` reads such a document with two regular expressions, without turning every
triple into RDF term objects: full IRIs, plain (or ``^^xsd:string`` / ``^^xsd:dateTime``) literals
without escapes, ``;`` between an element's statements, and the terms ``twin:ifcClass``,
``twin:storey``, ``twin:box``, ``twin:senseTime``, ``rdfs:label`` and ``twin:material``. Anything else
(prefixes, escapes, blank nodes, a view, a mesh, another term, a value given twice, any error) gives
None, and the document goes to the full parser (:func:`twin.live.parse.parse_observation_document`),
which gives the same reports for what this reads and the error for what is wrong: the tests hold the
two together.
"""

from __future__ import annotations

import math
import re

import pyoxigraph as ox

from twin.config import Limits
from twin.errors import ObservationError
from twin.graph import vocab
from twin.live.sense_time import sense_time_ns
from twin.live.validate import check_report
from twin.records import ElementReport, Observation, ObservedBox

__all__ = ["parse_box_document"]

_WS = r"[ \t\r\n]*"
_IRI = r"[^\x00-\x20<>\"{}|^`\\]*"  # Turtle's IRIREF without escapes
_LITERAL = rf"\"[^\"\\\n\r]*\"(?:\^\^<{_IRI}>)?"  # a "..." literal without escapes, a datatype maybe
_STATEMENT = re.compile(
    rf"{_WS}<({_IRI})>{_WS}((?:<{_IRI}>{_WS}{_LITERAL}{_WS};{_WS})*<{_IRI}>{_WS}{_LITERAL}){_WS}(?:;{_WS})?\."
)
_PAIR = re.compile(rf"<({_IRI})>{_WS}\"([^\"\\\n\r]*)\"(?:\^\^<({_IRI})>)?")
_SINGLE = {  # the single-valued terms read here, and the datatypes each may have
    vocab.TWIN_IFC_CLASS: (vocab.XSD_STRING,),
    vocab.TWIN_STOREY: (vocab.XSD_STRING,),
    vocab.TWIN_BOX: (vocab.XSD_STRING,),
    vocab.TWIN_SENSE_TIME: (vocab.XSD_DATETIME, vocab.XSD_STRING),
}
_MANY = {vocab.RDFS_LABEL: "labels", vocab.TWIN_MATERIAL: "materials"}
_STRING_LIMIT = 1024  # as the full parser's for labels and materials


def parse_box_document(data: bytes, *, limits: Limits) -> Observation | None:
    """The observation of ``data`` if it is of the common form above and valid, else None (give it to
    the full parser: it says what is wrong, or reads what this does not)."""
    try:
        by_subject = _statements(data.decode())
    except (UnicodeDecodeError, ValueError):
        return None
    if not by_subject or len(by_subject) > limits.elements_per_observation:
        return None
    try:
        reports = tuple(_report(s, by_subject[s], limits) for s in sorted(by_subject))
    except (ObservationError, ValueError, OverflowError):
        return None
    return Observation(reports, None)


def _statements(text: str) -> dict[str, dict[str, list[str]]]:
    """Each subject's values by term; ValueError where the text leaves the common form."""
    by_subject: dict[str, dict[str, list[str]]] = {}
    pos, end = 0, len(text)
    while pos < end:
        m = _STATEMENT.match(text, pos)
        if m is None:
            if text[pos:].strip(" \t\r\n"):
                raise ValueError(text[pos : pos + 40])
            break
        pos = m.end()
        props = by_subject.setdefault(m.group(1), {})
        for predicate, value, datatype in _PAIR.findall(m.group(2)):
            kinds = _SINGLE.get(predicate)
            if kinds is None:
                if predicate not in _MANY or datatype not in ("", vocab.XSD_STRING):
                    raise ValueError(predicate)
            elif (datatype or vocab.XSD_STRING) not in kinds:
                raise ValueError(predicate)
            props.setdefault(predicate, []).append(value)
    return by_subject


def _report(subject: str, props: dict[str, list[str]], limits: Limits) -> ElementReport:
    ox.NamedNode(subject)  # ValueError unless an IRI the full parser reads
    args: dict[str, object] = {"iri": subject}
    for predicate, values in props.items():
        many = _MANY.get(predicate)
        if many is not None:
            if any(len(v) > _STRING_LIMIT for v in values):
                raise ValueError(predicate)
            args[many] = tuple(values)
        elif len(values) != 1:
            raise ValueError(predicate)
    if (v := props.get(vocab.TWIN_IFC_CLASS)) is not None:
        args["ifc_class"] = v[0]
    if (v := props.get(vocab.TWIN_STOREY)) is not None:
        args["storey"] = v[0]
    if (v := props.get(vocab.TWIN_BOX)) is not None:
        args["box"] = _box(v[0])
    if (v := props.get(vocab.TWIN_SENSE_TIME)) is not None:
        args["sense_ns"] = sense_time_ns(v[0])
    return check_report(ElementReport(**args), limits=limits)  # type: ignore[arg-type]


def _box(text: str) -> ObservedBox:
    values = [float(p) for p in text.split()]  # as the full parser reads them
    if len(values) != 7 or not all(math.isfinite(v) for v in values):
        raise ValueError(text)
    cx, cy, cz, sx, sy, sz, yaw = values
    return ObservedBox(cx, cy, cz, sx, sy, sz, yaw)
