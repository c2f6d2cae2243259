"""Many robots, one twin: association, confirmation or move, absence, sense time, merges, aliases."""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from tests.twin.box_lab import OX, OY, element_iri, spec
from tests.twin.fusion.fusion_helpers import CORRIDOR, ROOM_A, at, sensed, view, view_only
from tests.twin.fusion.fusion_helpers import cell as cells_of
from tests.twin.live_helpers import PREFIX, box_turtle, observe, started
from twin.config import FusionRules, load_config
from twin.live import TwinService
from twin.live.events import ObservationAccepted, ObservationNoted

T0 = 1_795_000_000_000_000_000  # a sense time (ns) well in the past of the test's clock
TABLE = "urn:robot1:table-1"


def dynamic_elements(service: TwinService) -> list[str]:
    return sorted(i for i, s in service.states.items() if not s.is_static and not s.removed)


def assert_maps_equal_a_rebuild(service: TwinService) -> None:
    for key, m in service.live_maps.skill_maps.items():
        np.testing.assert_array_equal(m.data, service.live_maps.rebuild(m), err_msg=str(key))


# --- association --------------------------------------------------------------------------------------


def test_three_robots_reporting_one_table_make_one_element_and_the_others_resolve_to_it() -> None:
    service, _ = started()
    first = observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0, yaw=0.3))
    assert first.body["upserted"] == [TABLE]
    before = dynamic_elements(service)
    second = observe(service, "robot2", box_turtle("urn:robot2:obj-77", 6.62, 2.01, yaw=0.31))
    third = observe(service, "robot3", box_turtle("urn:robot3:t", 6.58, 1.99, yaw=0.29 + math.pi))
    assert second.body["resolved"] == {"urn:robot2:obj-77": TABLE} and second.body["unchanged"] is True
    assert third.body["resolved"] == {"urn:robot3:t": TABLE} and third.body["unchanged"] is True
    assert dynamic_elements(service) == before and service.revision == 1
    # later reports by either IRI are that element: a removal by an alias removes the table
    gone = observe(service, "robot2", f"{PREFIX}<urn:robot2:obj-77> twin:removed true .".encode())
    assert gone.body["removed"] == [TABLE]
    assert service.states[TABLE].removed


def test_a_move_by_the_creator_leaves_no_ghost_of_the_other_robots_copies() -> None:
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    observe(service, "robot2", box_turtle("urn:robot2:a", 6.61, 2.0))
    observe(service, "robot3", box_turtle("urn:robot3:b", 6.6, 2.02))
    assert cells_of(service, 6.6, 2.0) == 100
    moved = observe(service, "robot1", box_turtle(TABLE, 2.0, 2.0))  # 4.6 m along: a move, at once
    assert moved.body["revision"] == 2 and "unchanged" not in moved.body
    assert cells_of(service, 6.6, 2.0) == 0 and cells_of(service, 2.0, 2.0) == 100
    assert len(dynamic_elements(service)) == 2  # the table and the imported one
    assert_maps_equal_a_rebuild(service)


def test_two_tables_a_metre_apart_stay_two_elements() -> None:
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 5.0, 2.0))
    other = observe(service, "robot2", box_turtle("urn:robot2:t", 6.0, 2.0))
    assert "resolved" not in other.body and other.body["upserted"] == ["urn:robot2:t"]
    assert {TABLE, "urn:robot2:t"} <= set(dynamic_elements(service))


def test_a_table_reported_onto_a_wall_does_not_change_the_wall() -> None:
    service, _ = started()
    wall = element_iri(spec("Wall corridor south"))
    before = (service.states[wall], service.live_maps.shape_of(wall))
    reply = observe(service, "robot1", box_turtle("urn:robot1:x", 6.0, 1.3, sx=0.8, sy=0.3))
    assert reply.ok and "resolved" not in reply.body
    assert service.states[wall] == before[0] and service.live_maps.shape_of(wall) is before[1]


def test_the_imported_table_is_associated_and_a_flipped_heading_confirms_it() -> None:
    service, _ = started()
    imported_table = element_iri(spec("Table"))  # 1.2 x 0.8 at lab (1.4-2.6, 2.6-3.4)
    reply = observe(
        service,
        "robot1",
        box_turtle("urn:robot1:tt", 2.02, 3.0, sx=1.2, sy=0.8, cls="IfcFurnishingElement", yaw=math.pi),
    )
    assert reply.body["resolved"] == {"urn:robot1:tt": imported_table} and reply.body["unchanged"] is True


def test_two_robots_creating_one_table_in_one_batch_make_one_element() -> None:
    service, _ = started()
    replies: list = []
    service.submit_observation("robot1", box_turtle(TABLE, 6.6, 2.0), replies.append)
    service.submit_observation("robot2", box_turtle("urn:robot2:x", 6.62, 2.0), replies.append)
    service.process()
    assert [r.body.get("resolved") for r in replies if "resolved" in r.body] == [{"urn:robot2:x": TABLE}]
    assert TABLE in dynamic_elements(service) and "urn:robot2:x" not in service.states


def test_a_robot_saying_distinct_gets_an_element_of_its_own() -> None:
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    payload = box_turtle("urn:robot2:other", 6.62, 2.0).decode().rstrip().removesuffix(".")
    reply = observe(service, "robot2", f"{payload} ; twin:distinct true .".encode())
    assert "resolved" not in reply.body and reply.body["upserted"] == ["urn:robot2:other"]


def test_an_element_moved_onto_another_of_its_class_is_merged_and_an_operator_can_undo_it() -> None:
    config = replace(load_config(), default_rights=frozenset({"create", "dynamic", "doors"}))
    service, rec = started(config=config)
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    observe(service, "robot2", box_turtle("urn:robot2:t", 5.2, 2.0))  # far apart: two elements
    merged = observe(service, "robot2", box_turtle("urn:robot2:t", 6.61, 2.0))  # now where the first stands
    assert merged.body["removed"] == ["urn:robot2:t"] and merged.body["resolved"] == {"urn:robot2:t": TABLE}
    assert service.states["urn:robot2:t"].removed and not service.states[TABLE].removed
    assert any("merged into" in n for e in rec.of(ObservationAccepted) for n in e.notes)
    refused = observe(service, "robot2", f"{PREFIX}<urn:robot2:t> twin:unmerge true .".encode())
    assert not refused.ok and "merges" in refused.body["error"]
    service.config = replace(service.config, default_rights=frozenset({"create", "dynamic", "merges"}))
    service.observer.config = service.config
    undone = observe(
        service,
        "ops",
        box_turtle("urn:robot2:t", 5.2, 2.0).decode().rstrip().removesuffix(".").encode()
        + b" ; twin:unmerge true .",
    )
    assert undone.ok and undone.body["upserted"] == ["urn:robot2:t"]
    assert not service.states["urn:robot2:t"].removed
    again = observe(service, "robot2", box_turtle("urn:robot2:t", 5.21, 2.0))
    assert "resolved" not in again.body


# --- confirmation, refinement, moves --------------------------------------------------------------------


def test_noisy_sightings_of_a_still_table_commit_nothing_and_a_real_move_shows_at_once() -> None:
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0, yaw=0.3))
    rng = np.random.default_rng(7)
    for _ in range(200):
        dx, dy = rng.normal(0, 0.03, 2)
        dyaw = rng.normal(0, math.radians(2))
        reply = observe(service, "robot1", box_turtle(TABLE, 6.6 + dx, 2.0 + dy, yaw=0.3 + dyaw))
        assert reply.ok
    assert service.revision <= 2  # the creation, at most one refinement: no flapping
    moved = observe(service, "robot1", box_turtle(TABLE, 6.0, 2.0, yaw=0.3))
    assert "unchanged" not in moved.body and cells_of(service, 6.0, 2.0) == 100


def test_confirmations_that_agree_on_a_small_offset_refine_the_pose_once() -> None:
    service, rec = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    revisions = []
    for _ in range(15):  # 9 cm off: within the confirmation distance, past half of it
        revisions.append(observe(service, "robot2", box_turtle("urn:robot2:t", 6.69, 2.0)).body["revision"])
    assert service.revision == 2
    assert any("refined" in n for e in rec.of(ObservationAccepted) for n in e.notes)
    shape = service.live_maps.shape_of(TABLE)
    assert shape is not None and abs(shape[1][0, 3] - (OX + 6.69)) < 0.01


# --- sense time -------------------------------------------------------------------------------------------


def test_door_sightings_arriving_out_of_order_leave_the_newest_state() -> None:
    service, rec = started()
    door = element_iri(spec("Door A"))
    t = service.clock()
    opened = observe(
        service, "robotB", f"{PREFIX}<{door}> twin:isOpen true ; twin:senseTime {at(t - 10**9)} .".encode()
    )
    assert opened.ok and service.states[door].is_open is True
    late = observe(
        service,
        "robotA",
        f"{PREFIX}<{door}> twin:isOpen false ; twin:senseTime {at(t - 2 * 10**9)} .".encode(),
    )
    assert late.body["stale"] == [door] and late.body["unchanged"] is True
    assert service.states[door].is_open is True
    assert rec.of(ObservationNoted)
    newer = observe(
        service, "robotA", f"{PREFIX}<{door}> twin:isOpen false ; twin:senseTime {at(t)} .".encode()
    )
    assert "stale" not in newer.body and service.states[door].is_open is False


def test_a_sense_time_too_far_in_the_future_is_refused_naming_it() -> None:
    service, _ = started()
    future = service.clock() + 60 * 10**9
    reply = observe(service, "robot1", sensed(box_turtle(TABLE, 6.6, 2.0), future))
    assert not reply.ok and "in the future" in reply.body["error"] and service.revision == 0


def test_a_stale_sighting_does_not_bring_back_a_removed_element() -> None:
    service, _ = started()
    t = service.clock()
    observe(service, "robot1", sensed(box_turtle(TABLE, 6.6, 2.0), t - 5 * 10**9))
    gone = observe(
        service, "robot1", f"{PREFIX}<{TABLE}> twin:removed true ; twin:senseTime {at(t - 10**9)} .".encode()
    )
    assert gone.body["removed"] == [TABLE]
    late = observe(service, "robot2", sensed(box_turtle(TABLE, 6.6, 2.0), t - 3 * 10**9))
    assert late.body["stale"] == [TABLE] and service.states[TABLE].removed


# --- absence ----------------------------------------------------------------------------------------------


def test_a_table_not_seen_in_views_over_a_second_is_removed_with_the_reason() -> None:
    service, _ = started()
    t = service.clock() - 10 * 10**9
    observe(service, "robot1", sensed(box_turtle(TABLE, 6.6, 2.0), t))
    assert cells_of(service, 6.6, 2.0) == 100
    for i in range(1, 3):  # two misses: not yet
        reply = observe(service, f"robot{i}", view_only(t + i * 5 * 10**8, CORRIDOR))
        assert reply.body["unchanged"] is True
    third = observe(service, "robot3", view_only(t + 16 * 10**8, CORRIDOR))
    assert third.body["removed"] == [TABLE]
    assert cells_of(service, 6.6, 2.0) == 0
    reason = service.store.select(f"SELECT ?why WHERE {{ <{TABLE}> twin:removedBecause ?why }}")[0]["why"]
    assert reason is not None and "absent" in reason and "robot1" in reason and "robot3" in reason
    assert_maps_equal_a_rebuild(service)


def test_two_elements_of_one_table_that_a_view_sees_as_one_box_are_merged_not_excused_as_covered() -> None:
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    # a detector's double detection in one document: the table is matched once, the other box is an
    # object of its own (the rules' way to a duplicate; others: a settled dispute, a late creation)
    double = box_turtle("urn:robot2:a", 6.61, 2.0) + box_turtle("urn:robot2:b", 6.6, 2.02).split(b"\n", 1)[1]
    assert observe(service, "robot2", double).body["upserted"] == ["urn:robot2:b"]
    # robot1 sees one table there: its box (its own element) covers the other element's footprint
    seen = observe(service, "robot1", box_turtle(TABLE, 6.6, 2.01) + view(service.clock(), CORRIDOR))
    assert seen.body["removed"] == ["urn:robot2:b"] and seen.body["merged"] == {"urn:robot2:b": TABLE}
    assert dynamic_elements(service) == sorted([TABLE, element_iri(spec("Table"))])
    again = observe(service, "robot2", box_turtle("urn:robot2:b", 6.6, 2.02))
    assert again.body["resolved"] == {"urn:robot2:b": TABLE} and again.body["unchanged"] is True
    assert_maps_equal_a_rebuild(service)


def test_a_sighting_between_misses_resets_them_and_structure_and_zones_are_never_removed() -> None:
    service, _ = started()
    t = service.clock() - 10 * 10**9
    observe(service, "robot1", sensed(box_turtle(TABLE, 6.6, 2.0), t))
    zone = (
        PREFIX + f'<urn:ops:zone> twin:ifcClass "IfcFurniture" ; twin:storey "ground-floor" ; '
        f'twin:box "{OX + 5.0} {OY + 2.0} 0.3 0.4 0.4 0.6 0" ; twin:keepout true .'
    ).encode()
    service.config = replace(
        service.config, default_rights=frozenset({"create", "dynamic", "doors", "zones"})
    )
    service.observer.config = service.config
    assert observe(service, "ops", zone).ok
    everything = ("IfcFurnishingElement", "IfcWall", "IfcDoor", "IfcSlab")
    for i in range(2):
        observe(
            service, "robot2", (PREFIX.encode() + view(t + (i + 1) * 6 * 10**8, CORRIDOR, detects=everything))
        )
    observe(service, "robot3", sensed(box_turtle("urn:robot3:t", 6.61, 2.0), t + 13 * 10**8))  # seen again
    for i in range(2):
        observe(
            service,
            "robot2",
            (PREFIX.encode() + view(t + (14 + i * 6) * 10**8, CORRIDOR, detects=everything)),
        )
    assert not service.states[TABLE].removed  # two misses since the sighting, not three
    assert not service.states["urn:ops:zone"].removed
    walls = [i for i, s in service.states.items() if s.is_static]
    assert not any(service.states[w].removed for w in walls)


def test_elements_of_classes_the_detector_does_not_report_or_outside_the_view_get_no_misses() -> None:
    service, _ = started()
    t = service.clock() - 10 * 10**9
    observe(service, "robot1", sensed(box_turtle(TABLE, 6.6, 2.0), t))
    for i in range(5):
        observe(
            service,
            "robot2",
            (PREFIX.encode() + view(t + (i + 1) * 5 * 10**8, CORRIDOR, detects=("IfcDoor",))),
        )
        observe(service, "robot2", view_only(t + (i + 1) * 5 * 10**8 + 1, ROOM_A))
    assert not service.states[TABLE].removed


def test_the_imported_table_no_longer_there_is_removed_once_viewed_and_a_robot_without_rights_cannot() -> (
    None
):
    config = replace(load_config(), robots={})
    service, _ = started(config=config)
    imported_table = element_iri(spec("Table"))
    t = service.clock() - 10 * 10**9
    service.config = replace(service.config, default_rights=frozenset({"create"}))
    service.observer.config = service.config
    for i in range(5):
        observe(service, "visitor", view_only(t + i * 5 * 10**8, ROOM_A))
    assert not service.states[imported_table].removed
    service.config = replace(service.config, default_rights=frozenset({"create", "dynamic"}))
    service.observer.config = service.config
    for i in range(5, 9):
        observe(service, "robot1", view_only(t + i * 5 * 10**8, ROOM_A))
    assert service.states[imported_table].removed


# --- durability ---------------------------------------------------------------------------------------------


def test_aliases_survive_a_restart_and_expire_when_unused() -> None:
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    observe(service, "robot2", box_turtle("urn:robot2:obj-77", 6.62, 2.0))
    again, _ = started(service.store, service.config)
    assert again.live.fusion.aliases["urn:robot2:obj-77"].target == TABLE
    reply = observe(again, "robot2", f"{PREFIX}<urn:robot2:obj-77> twin:removed true .".encode())
    assert reply.body["removed"] == [TABLE]
    short = replace(again.config, fusion=replace(again.config.fusion, alias_ttl_ns=0))
    again.observer.config = short
    assert again.observer.expire_aliases() == 1
    assert not again.store.select("SELECT ?a WHERE { ?a twin:aliasOf ?t }")


def test_without_fusion_every_robot_iri_is_an_element_of_its_own() -> None:
    service, _ = started(config=replace(load_config(), fusion=FusionRules(enabled=False)))
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    reply = observe(service, "robot2", box_turtle("urn:robot2:obj-77", 6.62, 2.0))
    assert "resolved" not in reply.body and reply.body["upserted"] == ["urn:robot2:obj-77"]


def test_with_a_time_to_live_an_element_nobody_sees_is_removed_and_imported_ones_stay() -> None:
    service, _ = started()
    t = service.clock()
    observe(service, "robot1", sensed(box_turtle(TABLE, 6.6, 2.0), t - 30 * 10**9))
    observe(service, "robot1", sensed(box_turtle("urn:robot1:fresh", 2.0, 2.0), t))
    assert service.observer.expire_unconfirmed() == []  # off by default
    rules = service.config.fusion
    service.observer.config = replace(
        service.config, fusion=replace(rules, default=replace(rules.default, ttl_ns=10 * 10**9))
    )
    assert service.observer.expire_unconfirmed() == [TABLE]
    assert service.states[TABLE].removed and not service.states["urn:robot1:fresh"].removed
    assert not service.states[element_iri(spec("Table"))].removed
    reason = service.store.select(f"SELECT ?why WHERE {{ <{TABLE}> twin:removedBecause ?why }}")[0]["why"]
    assert reason is not None and reason.startswith("expired")
    assert_maps_equal_a_rebuild(service)


def test_held_tentative_a_one_off_detection_makes_no_element_and_a_second_sighting_does() -> None:
    service, _ = started()
    rules = service.config.fusion
    service.observer.config = replace(service.config, fusion=replace(rules, tentative_sightings=2))
    first = observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    assert (
        first.body["tentative"] == [TABLE] and first.body["unchanged"] is True and TABLE not in service.states
    )
    second = observe(service, "robot1", box_turtle(TABLE, 6.61, 2.0))
    assert second.body["upserted"] == [TABLE]
    observe(service, "robot2", box_turtle("urn:robot2:one-off", 2.0, 2.0))
    assert "urn:robot2:one-off" in service.live.fusion.tentative
    service.clock = lambda: time.time_ns() + 120 * 10**9
    service.observer.clock = service.clock
    service.observer.expire_aliases()
    assert "urn:robot2:one-off" not in service.live.fusion.tentative


def test_a_nearly_square_table_seen_at_every_quarter_turn_never_flaps() -> None:
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0, sx=0.62, sy=0.6, yaw=0.2))
    rng = np.random.default_rng(3)
    for i in range(300):
        dx, dy = rng.normal(0, 0.03, 2)
        turn = (i % 4) * math.pi / 2 + rng.normal(0, math.radians(2))
        sx, sy = (0.6, 0.62) if i % 3 else (0.62, 0.6)
        reply = observe(
            service,
            f"robot{i % 3}",
            box_turtle(f"urn:r{i % 3}:t", 6.6 + dx, 2.0 + dy, sx=sx, sy=sy, yaw=0.2 + turn),
        )
        assert reply.ok
    assert service.revision <= 2


def test_a_detector_outlier_is_no_move_and_a_short_move_shows_at_its_second_sighting() -> None:
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    outlier = observe(service, "robot2", box_turtle("urn:robot2:t", 6.8, 2.0))  # 20 cm off, once
    assert outlier.body["unchanged"] is True
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    first = observe(service, "robot1", box_turtle(TABLE, 6.85, 2.0))  # a real 25 cm move
    assert first.body["unchanged"] is True
    second = observe(service, "robot2", box_turtle("urn:robot2:t", 6.86, 2.01))
    assert second.body["upserted"] == [TABLE] and service.revision == 2
    shape = service.live_maps.shape_of(TABLE)
    assert shape is not None and abs(shape[1][0, 3] - (OX + 6.855)) < 0.005  # the two sightings' mean


def test_camera_noise_over_thousands_of_sightings_makes_no_revision() -> None:
    rng = np.random.default_rng(11)
    for sx, sy in ((0.7, 0.45), (0.6, 0.55), (0.9, 0.6)):
        service, _ = started()
        observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0, sx=sx, sy=sy, yaw=1.0))
        for i in range(800):
            dx, dy = rng.normal(0, 0.03, 2)
            flip = math.pi if rng.random() < 0.3 else 0.0
            yaw = 1.0 + rng.normal(0, math.radians(2)) + flip
            a, b = sx + rng.normal(0, 0.01), sy + rng.normal(0, 0.01)
            observe(
                service,
                f"robot{i % 10}",
                box_turtle(f"urn:r{i % 10}:t", 6.6 + dx, 2.0 + dy, sx=a, sy=b, yaw=yaw),
            )
        assert service.revision <= 2, (sx, sy, service.revision)  # the creation, at most one refinement
