"""Confirmation, moves and sizes: sizes change on strong evidence only, and an element imported from IFC
keeps its mesh when robots move it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from tests.twin.box_lab import element_iri, spec
from tests.twin.fusion.fusion_helpers import box, cell, sensed, size_of
from tests.twin.live_helpers import observe, started
from twin.fusion.confirm import only_sighting, only_sighting_where_it_stands
from twin.live.explain import fusion_of
from twin.live.state import ElementState
from twin.records import ElementReport, ObservedBox

DESK = "urn:robot1:desk-1"
TABLE = element_iri(spec("Table"))  # 1.2 x 0.8 x 0.75 at lab (1.4-2.6, 2.6-3.4)


def test_one_sighting_at_other_sizes_changes_nothing_and_a_second_robot_agreeing_resizes_the_box() -> None:
    service, _ = started()
    observe(service, "robot1", box(DESK, 6.0, 2.0, sx=1.0, sy=0.6))
    first = observe(service, "robot1", box(DESK, 6.0, 2.0, sx=1.2, sy=0.7))
    assert first.body["unchanged"] is True and size_of(service, DESK)[:2] == (1.0, 0.6)
    second = observe(service, "robot2", box("urn:robot2:d", 6.01, 2.0, sx=1.21, sy=0.7))
    assert second.body["upserted"] == [DESK] and second.body["resolved"] == {"urn:robot2:d": DESK}
    assert size_of(service, DESK)[:2] == (1.205, 0.7)


def test_one_robot_resizes_a_box_only_over_enough_sightings_spanning_a_second() -> None:
    service, _ = started()
    t = service.clock() - 10 * 10**9
    observe(service, "robot1", sensed(box(DESK, 6.0, 2.0, sx=1.0, sy=0.6), t))
    for i in range(1, 5):  # four sightings at 1.2 m: not yet
        reply = observe(service, "robot1", sensed(box(DESK, 6.0, 2.0, sx=1.2, sy=0.6), t + i * 3 * 10**8))
        assert reply.body["unchanged"] is True, i
    fifth = observe(service, "robot1", sensed(box(DESK, 6.0, 2.0, sx=1.2, sy=0.6), t + 15 * 10**8))
    assert fifth.body["upserted"] == [DESK] and size_of(service, DESK)[:2] == (1.2, 0.6)


def test_sightings_at_other_sizes_within_a_moment_never_resize() -> None:
    service, _ = started()
    t = service.clock() - 10 * 10**9
    observe(service, "robot1", sensed(box(DESK, 6.0, 2.0, sx=1.0, sy=0.6), t))
    for i in range(1, 20):  # 19 sightings within 0.2 s: a burst, not evidence over time
        observe(service, "robot1", sensed(box(DESK, 6.0, 2.0, sx=1.2, sy=0.6), t + i * 10**7))
    assert size_of(service, DESK)[:2] == (1.0, 0.6) and service.revision == 1


def test_a_moved_box_keeps_its_sizes() -> None:
    service, _ = started()
    observe(service, "robot1", box(DESK, 6.0, 2.0, sx=1.0, sy=0.6))
    moved = observe(service, "robot1", box(DESK, 5.0, 2.0, sx=1.2, sy=0.7))  # 1 m: a move, at once
    assert moved.body["upserted"] == [DESK]
    assert size_of(service, DESK)[:2] == (1.0, 0.6) and cell(service, 5.0, 2.0) == 100


def test_the_imported_table_moved_by_robots_keeps_its_mesh_and_never_takes_their_sizes() -> None:
    service, _ = started()
    mesh, placement = service.live_maps.shape_of(TABLE)  # type: ignore[misc]
    for robot in ("robot1", "robot2", "robot3"):  # three robots agree on other sizes: still its mesh
        observe(service, robot, box(f"urn:{robot}:t", 2.0, 3.0, sx=1.4, sy=0.9, cls="IfcFurnishingElement"))
    assert service.live_maps.shape_of(TABLE)[0] is mesh  # type: ignore[index]
    moved = observe(
        service, "robot1", box("urn:robot1:t", 2.0, 2.0, sx=1.4, sy=0.9, cls="IfcFurnishingElement")
    )
    assert moved.body["upserted"] == [TABLE]
    new_mesh, new_placement = service.live_maps.shape_of(TABLE)  # type: ignore[misc]
    assert new_mesh is mesh
    np.testing.assert_allclose(new_placement[:3, 3] - placement[:3, 3], [0.0, -1.0, 0.0], atol=1e-6)
    assert size_of(service, TABLE)[:2] == (1.2, 0.8) and cell(service, 2.0, 2.0) == 100
    assert cell(service, 2.0, 3.2) == 0


def test_a_noted_short_move_is_acked_pending_and_explain_shows_it_with_the_deciding_rule() -> None:
    service, _ = started()
    observe(service, "robot1", box(DESK, 6.0, 2.0, sx=1.0, sy=0.6))
    first = observe(service, "robot1", box(DESK, 6.25, 2.0, sx=1.0, sy=0.6))  # 25 cm, once
    assert first.body["pending"] == [DESK] and first.body["unchanged"] is True
    fused = fusion_of(service.live, DESK)
    assert fused["pending_move"]["robots"] == ["robot1"] and fused["pending_move"]["sightings"] == 1
    assert "move_sightings" in fused["decided"] and "robot1" in fused["decided"]
    second = observe(service, "robot1", box(DESK, 6.26, 2.0, sx=1.0, sy=0.6))
    assert "pending" not in second.body and second.body["upserted"] == [DESK]
    assert fusion_of(service.live, DESK)["decided"] == "move by robot1"


def test_a_confirming_report_is_only_a_sighting_exactly_when_it_would_be_without_its_box_and_storey() -> None:
    state = ElementState("urn:e", "IfcFurniture", ("IfcFurniture", "IfcFurnishingElement"), False)
    box_ = ObservedBox(1, 2, 0, 1, 1, 1, 0)
    base = ElementReport("urn:e", ifc_class="IfcFurniture", storey="ground-floor", box=box_)
    variants = [
        base,
        replace(base, ifc_class=None),
        replace(base, ifc_class="ifcfurniture"),
        replace(base, ifc_class="IfcFurnishingElement"),
        replace(base, ifc_class="IfcDoor"),
        replace(base, labels=("desk",)),
        replace(base, materials=("Wood",)),
        replace(base, classes=("http://x#Desk",)),
        replace(base, is_open=True),
        replace(base, keepout=False),
        replace(base, speed_limit=30),
        replace(base, removed=True),
        replace(base, unmerge=True),
        replace(base, placement=np.eye(4)),
    ]
    expected = [only_sighting(replace(r, box=None, storey=None), state) for r in variants]
    assert [only_sighting_where_it_stands(r, state) for r in variants] == expected
    assert expected.count(True) == 4
