"""Hostile input never crashes the service and never changes the twin when refused (fuzzing with
hypothesis: observations built from the real vocabulary, mutated bytes, skill JSON and SPARQL)."""

from __future__ import annotations

import contextlib
import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.twin.box_lab import element_iri, spec
from tests.twin.live_helpers import TWIN, observe, started
from twin.errors import QueryError
from twin.live import TwinService

FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck))

SUBJECTS = [
    "<urn:r:a>",
    "<urn:r:b>",
    f"<{element_iri(spec('Door A'))}>",
    f"<{element_iri(spec('Table'))}>",
    f"<{element_iri(spec('Wall A west'))}>",
    "_:x",
    "<not an iri>",
    "<>",
]
PREDICATES = [
    f"<{TWIN}{t}>"
    for t in ("ifcClass", "storey", "box", "placement", "isOpen", "removed", "material", "colour")
] + ["a", "<http://www.w3.org/2000/01/rdf-schema#label>", "<https://w3id.org/omg#hasGeometry>"]
NUMBERS = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-(10**6), 10**6)).map(str)
OBJECTS = st.one_of(
    st.sampled_from(
        [
            '"IfcFurniture"',
            '"IfcWall"',
            '"IfcDoor"',
            '"ground-floor"',
            '"attic"',
            "true",
            "false",
            '"x"',
            "<urn:r:c>",
            "[]",
            '"IfcSpaceship"',
            '"\\u0000"',
            '""',
        ]
    ),
    st.lists(NUMBERS, min_size=0, max_size=18).map(lambda ns: '"' + " ".join(ns) + '"'),
    st.text(max_size=30).map(json.dumps),
)


@st.composite
def documents(draw: st.DrawFn) -> bytes:
    lines = []
    for _ in range(draw(st.integers(1, 6))):
        s, p, o = draw(st.sampled_from(SUBJECTS)), draw(st.sampled_from(PREDICATES)), draw(OBJECTS)
        lines.append(f"{s} {p} {o} .")
    text = "\n".join(lines).encode()
    if draw(st.booleans()):  # mutate some bytes
        data = bytearray(text)
        for _ in range(draw(st.integers(1, 5))):
            if data:
                data[draw(st.integers(0, len(data) - 1))] = draw(st.integers(0, 255))
        text = bytes(data)
    return text


@pytest.fixture(scope="module")
def service() -> TwinService:
    return started()[0]


def snapshot(service: TwinService) -> tuple[int, int, dict[tuple[str, str], bytes]]:
    return (
        service.revision,
        len(service.store),
        {k: m.data.tobytes() for k, m in service.live_maps.skill_maps.items()},
    )


@FUZZ
@given(doc=documents())
def test_fuzzed_observations_are_answered_and_refusals_change_nothing(
    service: TwinService, doc: bytes
) -> None:
    before = snapshot(service)
    reply = observe(service, "robot1", doc)
    assert set(reply.body) >= {"ok"}
    if not reply.ok:
        assert isinstance(reply.body["error"], str) and reply.body["error"]
        assert snapshot(service) == before
    for m in service.live_maps.skill_maps.values():
        assert np.isin(m.data, (0, 100, -1)).all()


@FUZZ
@given(
    payload=st.one_of(
        st.binary(max_size=200),
        st.recursive(
            st.one_of(st.none(), st.booleans(), st.floats(), st.text(max_size=10), st.integers()),
            lambda c: st.one_of(
                st.lists(c, max_size=4),
                st.dictionaries(
                    st.sampled_from(
                        [
                            "kind",
                            "robot_height_m",
                            "lidar_height_m",
                            "resolution_m",
                            "sparql",
                            "exclude_types",
                            "x",
                        ]
                    ),
                    c,
                    max_size=4,
                ),
            ),
            max_leaves=12,
        ).map(lambda v: json.dumps(v).encode()),
    )
)
def test_fuzzed_skill_profiles_are_answered_and_never_break_the_service(
    service: TwinService, payload: bytes
) -> None:
    replies = []
    service.submit_skill("fuzzed", payload, replies.append)
    service.process()
    assert len(replies) == 1
    if replies[0].ok:
        service.submit_skill("fuzzed", None, replies.append)
        service.process()
        assert replies[-1].ok
    assert "fuzzed" not in service.skills


@FUZZ
@given(
    query=st.one_of(
        st.text(max_size=80),
        st.sampled_from(
            [
                "INSERT DATA { <urn:a> <urn:b> <urn:c> }",
                "DELETE WHERE { ?s ?p ?o }",
                "CLEAR ALL",
                "DROP DEFAULT",
                "PREFIX x: <urn:x#> INSERT DATA { x:a x:b x:c }",
                "LOAD <http://127.0.0.1:9/x.ttl>",
                "SELECT * WHERE { SERVICE <http://127.0.0.1:9/> { ?s ?p ?o } }",
                "SELECT * WHERE { " + "{ " * 200 + "?s ?p ?o" + " }" * 200 + " }",
            ]
        ),
    )
)
def test_fuzzed_sparql_never_updates_the_twin(service: TwinService, query: str) -> None:
    before = snapshot(service)
    with contextlib.suppress(QueryError):
        service.query(query)
    assert snapshot(service) == before
