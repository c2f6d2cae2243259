"""A merge keeps what either element knew: the one kept gains the labels, materials and descriptive types
of the one merged into it (:func:`twin.fusion.merge.carried`), by a move and under another's box."""

from __future__ import annotations

import pytest

from tests.twin.box_lab import element_iri, spec
from tests.twin.fusion.fusion_helpers import CORRIDOR, FURN, view, with_triples
from tests.twin.live_helpers import box_turtle, observe, started
from twin.fusion.context import FusionContext
from twin.fusion.merge import merge
from twin.graph import vocab
from twin.live import TwinService

TABLE = "urn:robot1:table-1"
DUPLICATE = "urn:robot2:t"
LABEL = f'<{vocab.RDFS_LABEL}> "Desk 12"'


def held(service: TwinService, iri: str, predicate: str) -> set[str]:
    """The values the graph holds for ``<iri> <predicate>``."""
    rows = service.store.select(f"SELECT ?v WHERE {{ <{iri}> <{predicate}> ?v }}")
    return {str(r["v"]) for r in rows}


def merged_by_a_move(service: TwinService, extra: str) -> None:
    """robot1's table, and robot2's copy of it (with ``extra``) made apart and then moved onto it."""
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    assert observe(service, "robot2", with_triples(box_turtle(DUPLICATE, 5.2, 2.0), extra)).ok
    moved = observe(service, "robot2", box_turtle(DUPLICATE, 6.61, 2.0))
    assert moved.ok and moved.body["merged"] == {DUPLICATE: TABLE}


def test_a_duplicate_with_a_label_merged_by_a_move_leaves_its_label_on_the_element_kept() -> None:
    service, _ = started()
    merged_by_a_move(service, LABEL)
    assert held(service, TABLE, vocab.RDFS_LABEL) == {"Desk 12"}
    assert service.states[TABLE].labels == {"Desk 12"} and service.states[DUPLICATE].removed
    again, _ = started(service.store, service.config)  # durable: in the graph, not only in memory
    assert again.states[TABLE].labels == {"Desk 12"}


@pytest.mark.parametrize("own", [(), ("Window table",)])  # robot1's report: a sighting, or a change too
def test_a_duplicate_merged_under_another_elements_box_leaves_its_label_on_the_element_kept(
    own: tuple[str, ...],
) -> None:
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    # a detector's double detection: the second box is an element of its own, labelled
    second = with_triples(box_turtle("urn:robot2:b", 6.6, 2.02), LABEL).split(b"\n", 1)[1]
    assert observe(service, "robot2", box_turtle("urn:robot2:a", 6.61, 2.0) + second).body["upserted"] == [
        "urn:robot2:b"
    ]
    sighting = box_turtle(TABLE, 6.6, 2.01)
    if own:  # one report of the table: the label it carries over joins it (the plan takes one per element)
        sighting = with_triples(sighting, f'<{vocab.RDFS_LABEL}> "{own[0]}"')
    seen = observe(service, "robot1", sighting + view(service.clock(), CORRIDOR))
    assert seen.body["merged"] == {"urn:robot2:b": TABLE}
    assert held(service, TABLE, vocab.RDFS_LABEL) == {"Desk 12", *own}
    assert service.states[TABLE].labels == {"Desk 12", *own} and seen.body["upserted"] == [TABLE]


def test_a_merged_duplicates_materials_become_facing_materials_and_its_kind_carries_over() -> None:
    service, _ = started()
    merged_by_a_move(service, f'twin:material "oak", "steel" ; a <{FURN}Table>')
    assert held(service, TABLE, vocab.TWIN_MATERIAL) == {"oak", "steel"}
    assert held(service, TABLE, vocab.TWIN_FACING_MATERIAL) == {"oak", "steel"}
    kept = service.states[TABLE]
    assert kept.materials == kept.facing_materials == {"oak", "steel"}
    assert FURN + "Table" in kept.classes and FURN + "Table" in held(service, TABLE, vocab.RDF_TYPE)


def test_an_element_imported_from_ifc_kept_over_a_robots_gains_its_label_and_keeps_its_own() -> None:
    service, _ = started()
    imported = element_iri(spec("Table"))  # 1.2 x 0.8 at lab (1.4-2.6, 2.6-3.4)
    own = set(service.states[imported].labels)
    box = box_turtle(DUPLICATE, 5.2, 2.0, sx=1.2, sy=0.8, cls="IfcFurnishingElement")
    assert observe(service, "robot2", with_triples(box, LABEL)).ok
    moved = observe(
        service, "robot2", box_turtle(DUPLICATE, 2.0, 3.0, sx=1.2, sy=0.8, cls="IfcFurnishingElement")
    )
    assert moved.body["merged"] == {DUPLICATE: imported}
    assert service.states[imported].labels == own | {"Desk 12"}
    assert held(service, imported, vocab.RDFS_LABEL) == own | {"Desk 12"}


def test_a_robot_that_may_not_change_the_element_kept_still_merges_and_carries_nothing_over() -> None:
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    observe(service, "robot2", with_triples(box_turtle(DUPLICATE, 5.2, 2.0), LABEL))
    live = service.live
    rules, now = service.config.fusion, service.clock()
    ctx = FusionContext("visitor", frozenset({"create"}), live, live.states, {}, rules, "", {}, now)
    removal, extra = merge(ctx, DUPLICATE, TABLE, sense=now)
    assert removal.iri == DUPLICATE and removal.removed and extra is None
    assert ctx.out.merged == {DUPLICATE: TABLE}
    assert any("not carried over" in n and "'dynamic'" in n for n in ctx.out.notes)
    allowed = FusionContext("robot2", frozenset({"dynamic"}), live, live.states, {}, rules, "", {}, now)
    _, extra = merge(allowed, DUPLICATE, TABLE, sense=now)
    assert extra is not None and extra.iri == TABLE and extra.labels == ("Desk 12",)


def test_an_element_that_gains_a_label_is_named_as_a_restart_names_it() -> None:
    service, _ = started()
    imported = element_iri(spec("Table"))
    assert service.states[imported].labels  # its IFC name, which sorts before "zz desk"
    observe(
        service,
        "robot2",
        with_triples(
            box_turtle(DUPLICATE, 5.2, 2.0, sx=1.2, sy=0.8, cls="IfcFurnishingElement"),
            f'<{vocab.RDFS_LABEL}> "zz desk"',
        ),
    )
    moved = observe(
        service, "robot2", box_turtle(DUPLICATE, 2.0, 3.0, sx=1.2, sy=0.8, cls="IfcFurnishingElement")
    )
    assert moved.body["merged"] == {DUPLICATE: imported}
    again, _ = started(service.store, service.config)
    assert service.states[imported].name == again.states[imported].name == min(again.states[imported].labels)
