"""The common box document read without an RDF parser gives what the full parser gives, or nothing."""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.config import Limits
from twin.errors import ObservationError
from twin.graph import vocab
from twin.live import parse
from twin.live.box_document import parse_box_document
from twin.records import Observation

T = "https://w3id.org/building-twin#"
LIMITS = Limits()
BOX = (
    f'<urn:r1:table> <{T}ifcClass> "IfcFurniture" ; <{T}storey> "ground-floor" ;\n'
    f'  <{T}box> "12.1234 5.6 0.375 0.8 0.6 0.75 0.1" .\n'
)


def _full(data: bytes) -> Observation | ObservationError:
    """What the full parser makes of ``data`` (the RDF parser, never the common form's reader)."""
    try:
        return parse.parse_observation_document(data, limits=LIMITS)
    except ObservationError as err:
        return err


@pytest.fixture(autouse=True)
def _full_parser(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(parse, "parse_box_document", lambda data, limits: None)


def _same(a: Observation, b: Observation) -> bool:
    return (
        a.view is None
        and b.view is None
        and [dataclasses.astuple(r) for r in a.reports] == [dataclasses.astuple(r) for r in b.reports]
    )


def test_a_box_document_reads_as_the_full_parser_reads_it() -> None:
    label, when = vocab.RDFS_LABEL, "2026-11-28T18:00:00.123456789Z"
    doc = (
        BOX + f'<urn:r1:chair> <{T}ifcClass> "IfcFurniture"^^<{vocab.XSD_STRING}> ; '
        f'<{T}storey> "ground-floor" ; <{T}box> "1 2 0.4 0.5 0.5 0.8 0" ; '
        f'<{T}senseTime> "{when}"^^<{vocab.XSD_DATETIME}> ; <{label}> "a chair" ; <{label}> "b" ; .'
    ).encode()
    fast = parse_box_document(doc, limits=LIMITS)
    full = _full(doc)
    assert fast is not None and isinstance(full, Observation) and _same(fast, full)
    assert [r.iri for r in fast.reports] == ["urn:r1:chair", "urn:r1:table"]
    assert (
        fast.reports[0].labels == ("a chair", "b") and fast.reports[0].sense_ns == 1_795_888_800_123_456_789
    )


@pytest.mark.parametrize(
    "doc",
    [
        f'@prefix twin: <{T}> .\n<urn:r1:t> twin:ifcClass "IfcFurniture" .',  # prefixes
        BOX.replace("IfcFurniture", "Ifc\\u0046urniture"),  # an escape
        BOX.replace("<urn:r1:table>", "_:b0"),  # a blank node
        BOX.replace("<urn:r1:table>", "<table>"),  # not an absolute IRI
        BOX.replace('"ground-floor"', '"ground-floor", "first-floor"'),  # two values
        BOX + f'<urn:r1:table> <{T}storey> "first-floor" .',  # twice, in two statements
        BOX.replace("0.375 0.8", "0.375 nan"),  # a NaN
        BOX.replace("0.375 0.8", "0.375 80.0"),  # too big
        BOX.replace(f"<{T}storey>", f"<{T}storeys>"),  # an unknown term
        BOX.replace(' "IfcFurniture"', ' "IfcFurniture"@en'),  # a language tag
        BOX + "# a comment",
        BOX.replace(" .", " ;; ."),  # valid Turtle, not the common form
        f"<urn:r1:t> <{T}isOpen> true .",  # another term
        "",
    ],
)
def test_documents_outside_the_common_form_go_to_the_full_parser(doc: str) -> None:
    assert parse_box_document(doc.encode(), limits=LIMITS) is None


_IRI_CHARS = st.sampled_from([*list("urn:ab/#?x-._~%é"), " ", "<", ">", '"', "\\", "[", "{", "^"])
_LIT_CHARS = st.sampled_from([*list("ab 1.-eE+Z:_é"), '"', "\\", "\n", "\t", "'", ";", ".", "#"])
_NUMBER = st.sampled_from(["1", "-2.5", "0.75", "1e-3", "1_0", "inf", "nan", "0", "60", "x"])
_VALUES = {  # per term: mostly what it takes, sometimes anything
    f"{T}ifcClass": st.sampled_from(["IfcFurniture", "IfcChair", "ifcwall", "IfcBogus"]),
    f"{T}storey": st.sampled_from(["ground-floor", "first-floor", ""]),
    f"{T}box": st.lists(_NUMBER, min_size=6, max_size=8).map(" ".join),
    f"{T}senseTime": st.sampled_from(["2026-11-28T18:00:00.123456789Z", "2026-11-28T18:00:00", "soon"]),
    f"{T}material": st.text(_LIT_CHARS, max_size=6),
    vocab.RDFS_LABEL: st.text(_LIT_CHARS, max_size=6),
    f"{T}isOpen": st.sampled_from(["true"]),
}
_DATATYPES = st.sampled_from(
    ["", "", "", f"^^<{vocab.XSD_STRING}>", f"^^<{vocab.XSD_DATETIME}>", f"^^<{vocab.XSD_BOOLEAN}>"]
)


@st.composite
def _pair(draw: st.DrawFn, predicate: str) -> str:
    value = draw(st.one_of(_VALUES[predicate], _VALUES[predicate], st.text(_LIT_CHARS, max_size=8)))
    space = draw(st.sampled_from([" ", "", "\n  "]))
    return f'<{predicate}>{space}"{value}"{draw(_DATATYPES)}'


@st.composite
def _documents(draw: st.DrawFn) -> str:
    statements = []
    for _ in range(draw(st.integers(1, 3))):
        subject = draw(
            st.one_of(
                st.sampled_from(["urn:r:a", "urn:r:b", "http://x/y"] * 3), st.text(_IRI_CHARS, max_size=10)
            )
        )
        terms = draw(st.lists(st.sampled_from(sorted(_VALUES)), min_size=1, max_size=5))
        pairs = [draw(_pair(t)) for t in terms]
        end = draw(st.sampled_from([" .", ".", " ; .", " ;\n.", ""]))
        statements.append(f"<{subject}> " + " ; ".join(pairs) + end)
    return "\n".join(statements)


@st.composite
def _elements(draw: st.DrawFn) -> str:
    """Mostly well-formed elements: the form robots send, spaced and typed in every way allowed."""
    subject = draw(st.sampled_from(["urn:r:a", "urn:r:b", "http://x/y?q#f", "urn:é:x"]))
    numbers = draw(st.lists(st.floats(-50, 50, allow_nan=False), min_size=3, max_size=3))
    sizes = draw(st.lists(st.floats(0.001, 60), min_size=3, max_size=3))
    box = " ".join(map(repr, [*numbers, *sizes, draw(st.floats(-4, 4))]))
    string = draw(st.sampled_from(["", f"^^<{vocab.XSD_STRING}>"]))
    pairs = [
        f'<{T}ifcClass> "IfcFurniture"{string}',
        f'<{T}storey> "ground-floor"',
        f'<{T}box> "{box}"{string}',
    ]
    if draw(st.booleans()):
        pairs.append(f'<{T}senseTime> "2026-11-28T18:00:00.5Z"^^<{vocab.XSD_DATETIME}>')
    pairs += [
        f'<{vocab.RDFS_LABEL}> "{v}"' for v in draw(st.lists(st.text(_LIT_CHARS, max_size=5), max_size=2))
    ]
    order = draw(st.permutations(pairs))
    space = draw(st.sampled_from([" ", "", "\n\t"]))
    return f"<{subject}>{space}" + f"{space};{space}".join(order) + draw(st.sampled_from([" .", ".", " ; ."]))


@settings(max_examples=200, deadline=None)
@given(st.one_of(_documents(), st.lists(_elements(), min_size=1, max_size=3).map("\n".join)))
def test_any_document_the_common_form_reads_reads_the_same_in_the_full_parser(doc: str) -> None:
    fast = parse_box_document(doc.encode(), limits=LIMITS)
    if fast is not None:
        full = _full(doc.encode())
        assert isinstance(full, Observation), full
        assert _same(fast, full)
