"""Planning an observation: decided before anything changes, and only what differs is written."""

from __future__ import annotations

from collections.abc import Sequence

import pytest

from tests.twin.live_helpers import box_turtle, observe, started
from twin.config import load_config
from twin.errors import ObservationError
from twin.graph import vocab
from twin.live.parse import parse_observation
from twin.live.plan import ObservationPlan, plan_observation
from twin.live.service import TwinService
from twin.records import ElementReport

ALL_RIGHTS = frozenset({"create", "dynamic", "doors", "static", "zones"})


def _reports(payload: bytes) -> Sequence[ElementReport]:
    return parse_observation(payload, limits=load_config().limits)


def _plan(service: TwinService, payload: bytes, rights: frozenset[str] = ALL_RIGHTS) -> ObservationPlan:
    live = service.live
    reports = _reports(payload)
    return plan_observation(
        reports,
        robot="robot1",
        rights=rights,  # type: ignore[arg-type]
        site=live.site,
        states=live.states,
        shapes={r.iri: live.maps.shape_of(r.iri) for r in reports},
        held=live.held,
        revision=live.revision + 1,
        stamp_ns=1_700_000_000_000_000_000,
    )


def _predicates(plan: ObservationPlan) -> set[str]:
    return {t.predicate for t in plan.changes.add}


def test_a_new_table_is_planned_with_its_class_geometry_and_provenance() -> None:
    service, _ = started()
    plan = _plan(service, box_turtle("urn:r:t1", 5.0, 2.0))
    assert not plan.unchanged and plan.upserted == ("urn:r:t1",)
    assert {vocab.TWIN_IFC_CLASS, vocab.TWIN_PLACEMENT, vocab.TWIN_OBSERVED_BY, vocab.TWIN_REVISION} <= (
        _predicates(plan)
    )
    assert [g.iri for g in plan.geometry] == ["urn:r:t1"] and plan.geometry[0].new is not None
    assert service.live.revision == 0  # planning changed nothing


def test_a_table_seen_where_it_stands_is_a_re_confirmation_that_writes_nothing() -> None:
    service, _ = started()
    assert observe(service, "robot1", box_turtle("urn:r:t1", 5.0, 2.0)).ok
    plan = _plan(service, box_turtle("urn:r:t1", 5.0 + 0.0004, 2.0))  # 0.4 mm: within 1 mm
    assert plan.unchanged and not plan.geometry and not plan.states


def test_a_moved_box_rewrites_its_placement_only_by_an_exact_delete() -> None:
    service, _ = started()
    assert observe(service, "robot1", box_turtle("urn:r:t1", 5.0, 2.0)).ok
    plan = _plan(service, box_turtle("urn:r:t1", 6.0, 2.0))
    geometry_writes = {t.predicate for t in plan.changes.add if t.subject == vocab.geometry_iri("urn:r:t1")}
    assert geometry_writes == {vocab.TWIN_PLACEMENT}  # not the mesh
    assert [t.predicate for t in plan.changes.delete if t.predicate == vocab.TWIN_PLACEMENT] == [
        vocab.TWIN_PLACEMENT
    ]
    assert not [r for r in plan.changes.remove if r[1] == vocab.TWIN_PLACEMENT]  # no pattern delete


@pytest.mark.parametrize(
    ("payload", "rights", "named"),
    [
        (box_turtle("urn:r:t1", 5.0, 2.0), frozenset({"dynamic"}), "'create' right"),
        (box_turtle("urn:r:t1", 5.0, 2.0, storey="attic"), ALL_RIGHTS, "unknown storey 'attic'"),
        (box_turtle("urn:r:t1", 500.0, 2.0), ALL_RIGHTS, "outside the site"),
        (box_turtle("urn:r:t1", 5.0, 2.0, cls="IfcNothing"), ALL_RIGHTS, "'IfcNothing' is not an IFC"),
    ],
)
def test_a_plan_that_cannot_be_carried_out_is_refused_naming_why(
    payload: bytes, rights: frozenset[str], named: str
) -> None:
    service, _ = started()
    with pytest.raises(ObservationError, match=named):
        _plan(service, payload, rights)


def test_an_element_cannot_change_its_class() -> None:
    service, _ = started()
    assert observe(service, "robot1", box_turtle("urn:r:t1", 5.0, 2.0)).ok
    with pytest.raises(ObservationError, match="cannot make it IfcWall"):
        _plan(service, box_turtle("urn:r:t1", 5.0, 2.0, cls="IfcWall"))


def test_a_lifetime_is_kept_in_the_graph_and_the_same_one_again_writes_nothing() -> None:
    from tests.twin.live_helpers import box_turtle, observe, started

    service, _ = started()
    box = box_turtle("urn:rmf:obstacle:1", 2.0, 1.0)
    assert box.endswith(b" .\n")
    doc = box[:-3] + b' ; twin:lifetime "5.0"^^<http://www.w3.org/2001/XMLSchema#decimal> .\n'
    first = observe(service, "robot1", doc)
    assert first.ok and "unchanged" not in first.body
    assert observe(service, "robot1", doc).body.get("unchanged") is True
    rows = service.store.select("SELECT ?l WHERE { <urn:rmf:obstacle:1> twin:lifetime ?l }")
    assert [r["l"] for r in rows] == ["5"]
    moved = box_turtle("urn:rmf:obstacle:1", 4.0, 1.0)  # a move with another lifetime writes both
    longer = moved[:-3] + b' ; twin:lifetime "7.5"^^<http://www.w3.org/2001/XMLSchema#decimal> .\n'
    assert "unchanged" not in observe(service, "robot1", longer).body
    rows = service.store.select("SELECT ?l WHERE { <urn:rmf:obstacle:1> twin:lifetime ?l }")
    assert [r["l"] for r in rows] == ["7.5"]


def test_opening_an_element_the_twin_does_not_hold_says_there_is_no_such_element() -> None:
    service, _ = started()
    with pytest.raises(ObservationError, match=r"^No element <urn:nothing> in the twin: only an element"):
        _plan(service, f"<urn:nothing> <{vocab.TWIN}isOpen> true .\n".encode())
    identity = " ".join("1" if i % 5 == 0 else "0" for i in range(16))
    moved = f'<urn:nothing> <{vocab.TWIN}placement> "{identity}"^^<{vocab.TWIN}Matrix4x4> .\n'
    with pytest.raises(ObservationError, match=r"^No element <urn:nothing> in the twin"):
        _plan(service, moved.encode())
    t = vocab.TWIN
    boxed = f'<urn:r:t9> <{t}storey> "ground-floor" ; <{t}box> "5 2 0.4 1 1 0.8 0" .\n'.encode()
    with pytest.raises(ObservationError, match=r"^Element <urn:r:t9> is new: give its twin:ifcClass\."):
        _plan(service, boxed)
