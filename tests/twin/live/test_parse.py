"""Observation parsing: Turtle in, typed element reports out; every problem named, nothing guessed."""

from __future__ import annotations

import math

import pytest

from twin.config import Limits
from twin.errors import ObservationError
from twin.live.parse import parse_observation

TWIN = "https://w3id.org/building-twin#"
P = f"@prefix twin: <{TWIN}> .\n@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .\n"
LIMITS = Limits()


def _one(doc: str, limits: Limits = LIMITS) -> object:
    (report,) = parse_observation(P + doc, limits=limits)
    return report


def test_a_box_observation_becomes_a_report_with_its_class_storey_and_box() -> None:
    r = _one('<urn:r:t1> twin:ifcClass "IfcFurniture" ; twin:storey "ground-floor" ; '
             'twin:box "2.0 3.0 0.375 1.2 0.8 0.75 0.5" ; rdfs:label "Table" .')  # fmt: skip
    assert r.iri == "urn:r:t1" and r.ifc_class == "IfcFurniture" and r.storey == "ground-floor"
    assert (r.box.cx, r.box.cy, r.box.sx, r.box.yaw) == (2.0, 3.0, 1.2, 0.5)
    assert r.labels == ("Table",)
    assert r.changes_geometry and not r.removed


def test_door_state_and_removal_are_read_as_booleans() -> None:
    reports = parse_observation(P + "<urn:d> twin:isOpen true .\n<urn:t> twin:removed true .", limits=LIMITS)
    by_iri = {r.iri: r for r in reports}
    assert by_iri["urn:d"].is_open is True and not by_iri["urn:d"].changes_geometry
    assert by_iri["urn:t"].removed is True


def test_several_elements_come_back_in_iri_order() -> None:
    reports = parse_observation(P + "<urn:b> twin:isOpen false .\n<urn:a> twin:isOpen true .", limits=LIMITS)
    assert [r.iri for r in reports] == ["urn:a", "urn:b"]


@pytest.mark.parametrize(
    ("doc", "named"),
    [
        ('<urn:t> twin:box "1 2 nan 1 1 1 0" ; twin:storey "g" .', "nan"),
        ('<urn:t> twin:box "1 2 0.5 1 1" ; twin:storey "g" .', "urn:t"),
        ('<urn:t> twin:box "1 2 0.5 100 1 1 0" ; twin:storey "g" .', "50"),
        ('<urn:t> twin:flavour "sweet" .', "flavour"),
        ("<urn:t> twin:isOpen true , false .", "isOpen"),
        ("<urn:t> twin:isOpen true", "line 3"),  # no final dot: a syntax error, located
        ("_:b twin:isOpen true .", "blank node"),
    ],
)
def test_a_malformed_observation_is_refused_naming_what_is_wrong(doc: str, named: str) -> None:
    with pytest.raises(ObservationError) as err:
        parse_observation(P + doc, limits=LIMITS)
    assert named.lower() in str(err.value).lower(), str(err.value)


def test_an_empty_or_oversized_observation_is_refused_before_it_is_parsed() -> None:
    with pytest.raises(ObservationError, match="empty"):
        parse_observation(b"  \n", limits=LIMITS)
    small = Limits(payload_bytes=100)
    with pytest.raises(ObservationError, match="more than the 100 allowed"):
        parse_observation(P + "<urn:t> twin:isOpen true .", limits=small)


def test_more_elements_than_the_limit_are_refused() -> None:
    doc = "".join(f"<urn:d{i}> twin:isOpen true .\n" for i in range(5))
    with pytest.raises(ObservationError, match="5"):
        parse_observation(P + doc, limits=Limits(elements_per_observation=4))
    assert len(parse_observation(P + doc, limits=Limits(elements_per_observation=5))) == 5


def test_box_sizes_and_angles_are_finite_numbers() -> None:
    r = _one('<urn:t> twin:box "-1e3 2.5e1 0 0.01 0.01 0.01 -3.1" ; twin:storey "g" .')
    assert all(math.isfinite(v) for v in (r.box.cx, r.box.cy, r.box.cz, r.box.yaw))


def test_a_lifetime_is_read_as_seconds_and_a_negative_or_endless_one_is_refused() -> None:
    r = _one('<urn:o> twin:ifcClass "IfcFurniture" ; twin:storey "g" ; twin:box "1 2 0.5 1 1 1 0" ; '
             'twin:lifetime 2.5 .')  # fmt: skip
    assert r.lifetime_s == 2.5
    for bad in ("-1.0", '"NaN"^^<http://www.w3.org/2001/XMLSchema#double>', "1e9", '"5"'):
        with pytest.raises(ObservationError, match="twin:lifetime"):
            _one(f"<urn:o> twin:lifetime {bad} .")
