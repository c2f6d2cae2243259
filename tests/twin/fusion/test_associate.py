"""Association by size and kind: a chair never becomes the table it stands under, a box over two desks
pushed together never resizes one of them (issue cases 1 and 2)."""

from __future__ import annotations

from tests.twin.box_lab import element_iri, spec
from tests.twin.fusion.fusion_helpers import (
    CORRIDOR,
    ROOM_A,
    box,
    cell,
    sensed,
    size_of,
    typed,
    view,
    view_only,
)
from tests.twin.live_helpers import observe, started

TABLE = element_iri(spec("Table"))  # 1.2 x 0.8 x 0.75 at lab (1.4-2.6, 2.6-3.4), IfcFurnishingElement


def test_a_chair_tucked_under_the_imported_table_confirms_it_and_pulled_out_is_a_chair_of_its_own() -> None:
    service, _ = started()
    shape = service.live_maps.shape_of(TABLE)
    for i in range(3):  # a 0.55 m chair under the table: smaller, within its footprint
        reply = observe(service, "robot1", box("urn:robot1:det:3", 2.3, 3.0, sx=0.55, sy=0.55, sz=0.9))
        assert reply.body["unchanged"] is True and reply.body["resolved"] == {"urn:robot1:det:3": TABLE}, i
    assert service.live_maps.shape_of(TABLE) is shape and service.revision == 0
    assert "urn:robot1:det:3" not in service.live.fusion.aliases  # a partial view makes no alias
    pulled = observe(service, "robot1", box("urn:robot1:det:3", 2.0, 2.0, sx=0.55, sy=0.55, sz=0.9))
    assert pulled.body["upserted"] == ["urn:robot1:det:3"] and "resolved" not in pulled.body
    assert service.live_maps.shape_of(TABLE) is shape
    assert cell(service, 2.0, 3.0) == 100 and cell(service, 2.0, 2.0) == 100


def test_a_chair_typed_as_a_chair_under_a_robots_table_is_its_own_element_and_never_moves_the_table() -> None:
    service, _ = started()
    table = "urn:robot2:table-1"
    observe(service, "robot2", typed(box(table, 6.0, 2.0, sx=1.0, sy=0.6), "Table"))
    before = size_of(service, table)
    for x in (6.2, 6.21, 6.19):  # a 0.45 m chair under it, by a detector that says what it is
        reply = observe(service, "robot1", typed(box("urn:robot1:c", x, 2.0, sx=0.45, sy=0.45), "Chair"))
        assert "resolved" not in reply.body
    assert "urn:robot1:c" in service.states and size_of(service, table) == before
    out = observe(service, "robot1", typed(box("urn:robot1:c", 6.2, 1.5, sx=0.45, sy=0.45), "Chair"))
    assert out.ok and size_of(service, table) == before and cell(service, 5.7, 2.0) == 100


def test_a_smaller_box_of_a_robots_table_without_a_type_confirms_it_and_changes_nothing() -> None:
    service, _ = started()
    table = "urn:robot2:table-1"
    observe(service, "robot2", box(table, 6.0, 2.0, sx=1.0, sy=0.6))
    for _ in range(3):
        reply = observe(service, "robot1", box("urn:robot1:c", 6.2, 2.0, sx=0.45, sy=0.45))
        assert reply.body["unchanged"] is True and reply.body["resolved"] == {"urn:robot1:c": table}
    assert size_of(service, table)[:2] == (1.0, 0.6) and service.revision == 1


def test_a_tucked_chair_and_its_table_in_one_observation_both_resolve_to_the_table_in_either_order() -> None:
    service, _ = started()
    table = "urn:robot1:table-1"
    observe(service, "robot1", box(table, 6.0, 2.0, sx=1.0, sy=0.6))
    # the robot's IRIs are fresh (its tracker lost both for a while); a document's reports are taken in
    # the order of their IRIs: the chair's partial view first ("trk-19" < "trk-7"), then the other way
    for chair_iri, table_iri in (("urn:robot2:trk-19", "urn:robot2:trk-7"), ("urn:robot3:b", "urn:robot3:a")):
        chair = box(chair_iri, 6.2, 2.0, sx=0.45, sy=0.45, sz=0.9)
        both = chair + box(table_iri, 6.01, 2.0, sx=1.0, sy=0.6).split(b"\n", 1)[1]
        reply = observe(service, table_iri.split(":")[1], both)
        assert reply.body["resolved"] == {chair_iri: table, table_iri: table}, reply.body
        assert reply.body["unchanged"] is True and not reply.body["upserted"]
    assert sorted(i for i in service.states if i.startswith("urn:")) == [table] and service.revision == 1


def test_two_desks_pushed_together_seen_as_one_box_keep_their_sizes_and_are_not_missed() -> None:
    service, _ = started()
    left, right = "urn:robot1:desk-1", "urn:robot1:desk-2"
    t = service.clock() - 10 * 10**9
    observe(service, "robot1", sensed(box(left, 5.4, 2.0, sx=1.2, sy=0.6), t))
    observe(service, "robot1", sensed(box(right, 6.6, 2.0, sx=1.2, sy=0.6), t))
    sizes = size_of(service, left), size_of(service, right)
    t += 10**8
    for i in range(6):  # a lidar clusterer's one 2.4 m box over both, in views over 2.5 s
        blob = sensed(box("urn:robot3:blob", 6.0 + 0.01 * i, 2.0, sx=2.4, sy=0.6), t + i * 5 * 10**8)
        reply = observe(
            service, "robot3", blob + view(t + i * 5 * 10**8, CORRIDOR, detects=("IfcFurniture",))
        )
        assert reply.ok and "resolved" not in reply.body, reply.body
    assert (size_of(service, left), size_of(service, right)) == sizes
    assert not service.states[left].removed and not service.states[right].removed
    assert cell(service, 5.4, 2.0) == 100 and cell(service, 6.6, 2.0) == 100


# --- aliases are checked (issue case 3) ----------------------------------------------------------------

DET3 = "urn:twin-ros:robot1:det:3"


def test_a_reused_tracker_id_that_is_now_a_chair_elsewhere_drops_its_alias_and_never_moves_the_table() -> (
    None
):
    service, _ = started()
    shape = service.live_maps.shape_of(TABLE)
    first = observe(service, "robot1", box(DET3, 2.0, 3.0, sx=1.2, sy=0.8, cls="IfcFurnishingElement"))
    assert first.body["resolved"] == {DET3: TABLE} and service.live.fusion.aliases[DET3].target == TABLE
    chair = observe(service, "robot1", box(DET3, 6.0, 2.0, sx=0.5, sy=0.5, sz=0.9))  # perception restarted
    assert chair.body["upserted"] == [DET3] and "resolved" not in chair.body
    assert DET3 not in service.live.fusion.aliases and service.live_maps.shape_of(TABLE) is shape
    assert not service.store.select(f"SELECT ?t WHERE {{ <{DET3}> twin:aliasOf ?t }}")
    assert cell(service, 2.0, 3.0) == 100 and cell(service, 6.0, 2.0) == 100


def test_a_report_through_an_alias_farther_than_the_jump_limit_is_another_object() -> None:
    service, _ = started()
    observe(service, "robot1", box("urn:robot1:desk", 5.0, 2.0, sx=1.0, sy=0.6))
    observe(service, "robot2", box("urn:robot2:7", 5.02, 2.0, sx=1.0, sy=0.6))
    far = observe(service, "robot2", box("urn:robot2:7", 7.5, 2.0, sx=1.0, sy=0.6))  # 2.5 m away
    assert far.body["upserted"] == ["urn:robot2:7"] and "resolved" not in far.body
    assert cell(service, 5.0, 2.0) == 100 and cell(service, 7.5, 2.0) == 100


def test_a_report_through_an_alias_within_the_jump_limit_still_moves_the_element() -> None:
    service, _ = started()
    observe(service, "robot1", box("urn:robot1:desk", 5.0, 2.0, sx=1.0, sy=0.6))
    observe(service, "robot2", box("urn:robot2:7", 5.02, 2.0, sx=1.0, sy=0.6))
    moved = observe(service, "robot2", box("urn:robot2:7", 6.2, 2.0, sx=1.0, sy=0.6))  # 1.2 m: a move
    assert moved.body["upserted"] == ["urn:robot1:desk"] and moved.body["resolved"] == {
        "urn:robot2:7": "urn:robot1:desk"
    }
    assert cell(service, 5.0, 2.0) == 0 and cell(service, 6.2, 2.0) == 100


# --- kinds agree in misses (issue case 7) -------------------------------------------------------------


def test_a_detector_of_ifc_furniture_that_resolves_to_the_imported_table_also_misses_it() -> None:
    service, _ = started()
    t = service.clock() - 10 * 10**9
    seen = observe(service, "robot1", sensed(box("urn:robot1:t", 2.0, 3.0, sx=1.2, sy=0.8), t))
    assert seen.body["resolved"] == {"urn:robot1:t": TABLE}  # IfcFurniture resolves to IfcFurnishingElement
    for i in range(1, 5):  # the table is gone: the same detector's views of room A miss it
        observe(service, "robot1", view_only(t + i * 5 * 10**8, ROOM_A, detects=("IfcFurniture",)))
    assert service.states[TABLE].removed


def test_two_chairs_once_seen_as_one_never_drag_their_element_back_and_forth_when_one_moves() -> None:
    service, _ = started()
    chair = {"sx": 0.5, "sy": 0.5, "sz": 0.9}
    observe(service, "robot1", box("urn:robot1:chair", 5.0, 2.0, **chair))
    for iri in ("urn:robot2:7", "urn:robot2:8"):  # two tracks of what looked like one chair
        assert observe(service, "robot2", box(iri, 5.02, 2.0, **chair)).body["resolved"] == {
            iri: "urn:robot1:chair"
        }
    both = box("urn:robot2:7", 5.0, 2.0, **chair) + box("urn:robot2:8", 6.5, 2.0, **chair).split(b"\n", 1)[1]
    first = observe(service, "robot2", both)  # one stayed, one moved 1.5 m (within alias_jump_m)
    assert first.body["upserted"] == ["urn:robot2:8"], first.body
    again = observe(service, "robot2", both)
    assert again.body.get("unchanged") is True and not again.body["upserted"], again.body
    assert cell(service, 5.0, 2.0) == 100 and cell(service, 6.5, 2.0) == 100
