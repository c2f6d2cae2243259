"""Open-RMF obstacles and door states -> observations: levels and their transforms, lifetimes, ADD,
DELETE and DELETEALL per source; doors by table, GlobalId and name; MOVING changes nothing."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from adapters.ros.observation_doc import RosInputError, Translation
from adapters.ros.rmf import (
    DoorIndex,
    DoorSettings,
    Level,
    ObstacleSettings,
    ObstacleTracker,
    held_obstacles,
    translate_door_state,
)
from tests.adapters.ros_reports import Obstacle, cdr_door_state, cdr_obstacles
from tests.conftest import BASE
from tests.small_disk import fill_until_refused, small_tmpfs
from tests.twin.box_lab import OX, OY, box_lab
from tests.twin.live_helpers import observe, started
from twin.graph import vocab
from twin.graph.import_model import import_model
from twin.graph.store import EmbeddedStore
from twin.live import TwinService

NOW = 1_700_000_000_000_000_000
GUID = "2_bXoMMEnLjvJDRiT8YUDb"
DOOR = f"https://example.org/lab#door_{vocab.expand_guid(GUID)}"
SETTINGS = ObstacleSettings(
    "rmf",
    {"human": "IfcBuildingElementProxy"},
    {"L1": Level("ground-floor"), "L2": Level("first-floor", x=10.0, y=0.0, yaw=math.pi / 2)},
)


def human(i: int, level: str = "L1", **kw: object) -> Obstacle:
    return Obstacle(i, "cam1", level, "human", (1.0, 2.0, 0.9), (0.5, 0.5, 1.8), **kw)  # type: ignore[arg-type]


def test_an_obstacle_becomes_a_box_on_its_levels_storey_moved_by_the_levels_transform() -> None:
    tracker = ObstacleTracker(SETTINGS)
    t = tracker.translate(cdr_obstacles(NOW, [human(1), human(2, "L2")]), now_ns=NOW)
    doc = (t.document or b"").decode()
    assert 'twin:storey "ground-floor"' in doc and 'twin:box "1 2 0.9 0.5 0.5 1.8 0"' in doc
    assert 'twin:storey "first-floor"' in doc and 'twin:box "8 1 0.9 0.5 0.5 1.8 1.570796"' in doc
    assert t.iris == ("urn:twin-ros:rmf:obstacle:cam1%2F1", "urn:twin-ros:rmf:obstacle:cam1%2F2")


def test_an_obstacle_expires_after_its_lifetime() -> None:
    tracker = ObstacleTracker(SETTINGS)
    tracker.translate(cdr_obstacles(NOW, [human(1, lifetime_ns=2_000_000_000), human(2)]), now_ns=NOW)
    assert tracker.next_expiry() == NOW + 2_000_000_000
    assert tracker.expire(now_ns=NOW + 1_000_000_000).documents == ()
    (gone,) = tracker.expire(now_ns=NOW + 2_000_000_000).documents
    assert b"<urn:twin-ros:rmf:obstacle:cam1%2F1> twin:removed true" in gone and b"cam1%2F2" not in gone
    assert tracker.held == 1 and tracker.next_expiry() is None


def test_delete_and_deleteall_remove_only_what_that_rmf_source_added_each_on_its_own() -> None:
    tracker = ObstacleTracker(SETTINGS)
    other = Obstacle(9, "cam2", "L1", "human", (5, 5, 0.9), (0.5, 0.5, 1.8))
    tracker.translate(cdr_obstacles(NOW, [human(1), human(2), other]), now_ns=NOW)
    (deleted,) = tracker.translate(cdr_obstacles(NOW, [human(1, action=2)]), now_ns=NOW).documents
    assert b"cam1%2F1> twin:removed true" in deleted
    unknown = tracker.translate(cdr_obstacles(NOW, [human(7, action=2)]), now_ns=NOW)
    assert unknown.documents == () and unknown.ignored == {"unknown_id": 1}
    everything = tracker.translate(cdr_obstacles(NOW, [human(0, action=3), human(5)]), now_ns=NOW)
    boxes, removal = everything.documents  # the boxes, then each removal in a document of its own
    assert b"cam1%2F5> twin:ifcClass" in boxes and b"removed" not in boxes
    assert removal.endswith(b"<urn:twin-ros:rmf:obstacle:cam1%2F2> twin:removed true .\n")
    assert b"cam2" not in boxes + removal
    assert tracker.held == 2


def test_unknown_classification_is_ignored_and_an_unknown_level_refused() -> None:
    tracker = ObstacleTracker(SETTINGS)
    robot = Obstacle(1, "cam1", "L1", "robot", (1, 2, 0.5), (1, 1, 1))
    t = tracker.translate(cdr_obstacles(NOW, [robot, human(2, "basement")]), now_ns=NOW)
    assert t.ignored == {"unknown_class": 1}
    assert [c for c, _ in t.refused] == ["unknown_level"] and "basement" in t.refused[0][1]
    assert t.document is None


INDEX = DoorIndex(
    [(DOOR, "Door A"), ("https://example.org/lab#door_x", "Twin"), ("https://example.org/lab#door_y", "Twin")]
)


@pytest.mark.parametrize(
    ("name", "table"),
    [
        ("Door A", {}),
        (GUID, {}),
        ("main", {"main": GUID}),
        ("main", {"main": "Door A"}),
        ("main", {"main": DOOR}),
    ],
)
def test_a_door_state_open_or_closed_matches_the_door_by_table_globalid_or_name(
    name: str, table: dict[str, str]
) -> None:
    opened = translate_door_state(cdr_door_state(NOW, name, 2), DoorSettings("doors", table), INDEX)
    assert opened.document is not None and f"<{DOOR}> twin:isOpen true".encode() in opened.document
    closed = translate_door_state(cdr_door_state(NOW, name, 0), DoorSettings("doors", table), INDEX)
    assert closed.document is not None and f"<{DOOR}> twin:isOpen false".encode() in closed.document


@pytest.mark.parametrize(
    ("mode", "cause"), [(1, "mode_moving"), (3, "mode_offline"), (4, "mode_unknown"), (9, "mode_invalid")]
)
def test_moving_offline_and_unknown_change_nothing(mode: int, cause: str) -> None:
    t = translate_door_state(cdr_door_state(NOW, "Door A", mode), DoorSettings("doors", {}), INDEX)
    assert t.document is None and t.ignored == {cause: 1}


def test_an_unknown_or_ambiguous_door_is_refused_naming_it() -> None:
    with pytest.raises(RosInputError, match="No door of the twin matches RMF door 'Lift door'") as err:
        translate_door_state(cdr_door_state(NOW, "Lift door", 2), DoorSettings("doors", {}), INDEX)
    assert err.value.cause == "unknown_door"
    with pytest.raises(RosInputError, match="several doors have that name"):
        translate_door_state(cdr_door_state(NOW, "Twin", 2), DoorSettings("doors", {}), INDEX)


def test_a_tracker_takes_back_the_obstacles_of_a_previous_run_from_the_graph_rows() -> None:
    before = ObstacleTracker(SETTINGS)
    doc = before.translate(cdr_obstacles(NOW, [human(1, lifetime_ns=2_000_000_000), human(2)]), now_ns=NOW)
    assert b'twin:lifetime "2.000000000"^^xsd:decimal' in (doc.document or b"")
    at = "2023-11-14T22:13:20Z"  # NOW as the graph's twin:observedAt
    rows = [
        {"e": "urn:twin-ros:rmf:obstacle:cam1%2F1", "at": at, "life": "2"},
        {"e": "urn:twin-ros:rmf:obstacle:cam1%2F2", "at": at, "life": "0"},
        {"e": "urn:twin-ros:other:obstacle:cam1%2F3", "at": at, "life": None},  # another twin source's
        {"e": "urn:twin-ros:rmf:obstacle:cam1%2F4", "at": "not a time", "life": "1"},
    ]
    after = ObstacleTracker(SETTINGS)
    assert after.restore(held_obstacles(rows)) == 2
    assert after.held == 2 and after.next_expiry() == NOW + 2_000_000_000
    (deleted,) = after.translate(cdr_obstacles(NOW, [human(2, action=2)]), now_ns=NOW).documents
    assert b"cam1%2F2> twin:removed true" in deleted  # a DELETE of a previous run's obstacle
    (gone,) = after.expire(now_ns=NOW + 2_000_000_000).documents
    assert b"cam1%2F1> twin:removed true" in gone and after.held == 0


def _to_twin(service: TwinService, t: Translation) -> bool:
    """Submit ``t``'s document as the ingestion does and tell the tracker the twin's verdict."""
    assert t.document is not None and t.settle is not None
    reply = observe(service, "obstacles", t.document if isinstance(t.document, bytes) else b"")
    t.settle(reply.ok)
    return reply.ok


def test_an_obstacle_the_twin_refuses_is_not_held_so_a_delete_or_lifetime_later_acts_on_nothing() -> None:
    service, _ = started()
    tracker = ObstacleTracker(SETTINGS)
    far = Obstacle(1, "cam1", "L1", "human", (OX + 900.0, OY, 0.9), (0.5, 0.5, 1.8), lifetime_ns=5 * 10**9)
    t = tracker.translate(cdr_obstacles(NOW, [far]), now_ns=NOW)
    assert tracker.held == 1  # held from its ADD on: a DELETE right behind it finds it
    assert _to_twin(service, t) is False  # outside the site's extent
    assert tracker.held == 0 and tracker.next_expiry() is None
    delete = tracker.translate(
        cdr_obstacles(NOW, [Obstacle(1, "cam1", "L1", "human", (0, 0, 0), (1, 1, 1), action=2)]), now_ns=NOW
    )
    assert delete.documents == () and delete.ignored == {"unknown_id": 1}
    assert tracker.translate(cdr_obstacles(NOW, [human(0, action=3)]), now_ns=NOW).documents == ()


def test_a_refused_change_of_a_held_obstacle_keeps_it_with_its_earlier_lifetime() -> None:
    service, _ = started()
    tracker = ObstacleTracker(SETTINGS)
    here = Obstacle(
        1, "cam1", "L1", "human", (OX + 5.0, OY + 5.0, 0.9), (0.5, 0.5, 1.8), lifetime_ns=5 * 10**9
    )
    assert _to_twin(service, tracker.translate(cdr_obstacles(NOW, [here]), now_ns=NOW)) is True
    away = Obstacle(1, "cam1", "L1", "human", (OX + 900.0, OY, 0.9), (0.5, 0.5, 1.8), lifetime_ns=60 * 10**9)
    refused = tracker.translate(cdr_obstacles(NOW + 10**9, [away]), now_ns=NOW + 10**9)
    again = tracker.translate(cdr_obstacles(NOW + 2 * 10**9, [here]), now_ns=NOW + 2 * 10**9)
    assert _to_twin(service, refused) is False  # the refusal arrives after the next ADD: that one holds
    assert tracker.held == 1 and tracker.next_expiry() == NOW + 7 * 10**9
    assert _to_twin(service, again) is True
    assert _to_twin(service, tracker.translate(cdr_obstacles(NOW, [away]), now_ns=NOW + 3 * 10**9)) is False
    assert tracker.held == 1 and tracker.next_expiry() == NOW + 7 * 10**9  # the twin still holds it so
    (gone,) = tracker.expire(now_ns=NOW + 7 * 10**9).documents
    assert observe(service, "obstacles", gone if isinstance(gone, bytes) else b"").ok


def test_a_lifetime_removal_refused_by_a_full_store_is_held_and_tried_again_once_it_takes_writes(
    tmp_path: Path,
) -> None:
    with small_tmpfs(tmp_path / "disk") as disk:
        store = EmbeddedStore.open(disk / "store")
        import_model(store, box_lab(), base_iri=BASE, site="test")
        service, _ = started(store)
        tracker = ObstacleTracker(SETTINGS)
        brief = Obstacle(
            1, "cam1", "L1", "human", (OX + 5.0, OY + 5.0, 0.9), (0.5, 0.5, 1.8), lifetime_ns=10**9
        )
        assert _to_twin(service, tracker.translate(cdr_obstacles(NOW, [brief]), now_ns=NOW)) is True
        filler = fill_until_refused(disk, service.store)
        lapsed = tracker.expire(now_ns=NOW + 10**9)
        assert lapsed.removes == ("urn:twin-ros:rmf:obstacle:cam1%2F1",) and tracker.held == 0
        reply = observe(service, "obstacles", bytes(lapsed.documents[0]))  # type: ignore[arg-type]
        assert not reply.ok and "No space left on device" in str(reply.body["error"])
        tracker.removal_refused(lapsed.removes[0], now_ns=NOW + 10**9)  # the ingestion: the twin holds it
        assert tracker.held == 1 and tracker.next_expiry() == NOW + 3 * 10**9
        filler.unlink()
        assert service.recover_store()
        (again,) = tracker.expire(now_ns=NOW + 3 * 10**9).documents
        assert observe(service, "obstacles", bytes(again)).ok  # type: ignore[arg-type]
        assert tracker.held == 0
        service.store.close()
