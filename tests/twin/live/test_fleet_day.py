"""A day of a fleet in the core: re-confirmations are free, the graph does not grow with sightings,
single values stay single, and a restart gives the same twin."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from tests.conftest import imported
from tests.twin.box_lab import box_lab, element_iri, spec
from tests.twin.live_helpers import PREFIX, TWIN, box_turtle, observe, started
from twin.config import FusionRules, load_config
from twin.graph.meshcodec import encode_placement
from twin.live import TwinService
from twin.live.census import writer_sizes
from twin.live.events import MapPublished, MapUpdated, ObservationAccepted
from twin.live.membership import needs_store, selects
from twin.selection.skill_selection import selection_query
from twin.selection.skills import parse_skill

TABLE = "urn:robot1:table-1"


def test_a_re_confirmation_commits_no_revision_renders_nothing_and_is_acked_unchanged() -> None:
    service, rec = started()
    assert observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0, yaw=0.3)).body["revision"] == 1
    triples, events = len(service.store), len(rec.events)
    for _ in range(20):
        reply = observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0, yaw=0.3))
        assert reply.ok
        assert reply.body["unchanged"] is True and reply.body["revision"] == 1 and reply.body["maps"] == []
    assert service.revision == 1
    assert len(service.store) == triples
    assert len(rec.events) == events  # no map update, no accepted observation: nothing to publish
    assert service.status()["observations"] == {"accepted": 1, "unchanged": 20, "rejected": 0}


def test_without_fusion_noise_within_a_millimetre_and_a_tenth_of_a_milliradian_confirms() -> None:
    # [fusion] enabled = false: every report as robots say it (with fusion: tests/twin/live/test_fusion.py)
    service, _ = started(config=replace(load_config(), fusion=FusionRules(enabled=False)))
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0, yaw=0.3))
    assert observe(service, "robot1", box_turtle(TABLE, 6.6004, 1.9996, yaw=0.30005)).body.get("unchanged")
    assert observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0, sx=0.8004, yaw=0.3)).body.get("unchanged")
    moved = observe(service, "robot1", box_turtle(TABLE, 6.603, 2.0, yaw=0.3))
    assert moved.ok and "unchanged" not in moved.body and moved.body["revision"] == 2
    turned = observe(service, "robot1", box_turtle(TABLE, 6.603, 2.0, yaw=0.3005))
    assert turned.body["revision"] == 3


def test_a_door_seen_as_it_is_changes_nothing_and_a_new_label_is_a_change() -> None:
    service, _ = started()
    door = element_iri(spec("Door A"))
    assert observe(service, "robot1", f"{PREFIX}<{door}> twin:isOpen true .".encode()).body["revision"] == 1
    assert observe(service, "robot1", f"{PREFIX}<{door}> twin:isOpen true .".encode()).body["unchanged"]
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    labelled = (
        box_turtle(TABLE, 6.6, 2.0).decode().rstrip(" .\n")
        + ' ; <http://www.w3.org/2000/01/rdf-schema#label> "desk" .'
    )
    assert observe(service, "robot1", labelled.encode()).body["revision"] == 3
    assert observe(service, "robot1", labelled.encode()).body.get("unchanged") is True


def test_a_robot_may_re_confirm_a_wall_but_not_move_it() -> None:
    service, _ = started()
    wall = element_iri(spec("Wall A west"))
    shape = service.live_maps.shape_of(wall)
    assert shape is not None

    def placed(p: np.ndarray) -> bytes:
        return f'{PREFIX}<{wall}> twin:placement "{encode_placement(p)}"^^twin:Matrix4x4 .'.encode()

    reply = observe(service, "robot1", placed(shape[1]))
    assert reply.ok and reply.body.get("unchanged") is True
    moved = shape[1].copy()
    moved[0, 3] += 0.1
    refused = observe(service, "robot1", placed(moved))
    assert not refused.ok and "lacks the 'static' right" in str(refused.body["error"])
    assert service.revision == 0


def test_moving_a_table_a_thousand_times_leaves_the_graph_the_size_it_was_after_the_first_move() -> None:
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    observe(service, "robot1", box_turtle(TABLE, 6.0, 2.0))
    size = len(service.store)
    rng = np.random.default_rng(1)
    for x, y, yaw in zip(
        rng.uniform(5.0, 8.0, 300), rng.uniform(1.6, 2.4, 300), rng.uniform(0, 3, 300), strict=True
    ):
        assert observe(service, "robot1", box_turtle(TABLE, float(x), float(y), yaw=float(yaw))).ok
    assert len(service.store) == size
    for predicate in ("observedBy", "observedAt", "revision"):
        rows = service.store.select(f"SELECT ?o WHERE {{ <{TABLE}> twin:{predicate} ?o }}")
        assert len(rows) == 1, predicate
    rows = service.store.select(f"SELECT ?o WHERE {{ <{TABLE}/geometry> twin:placement ?o }}")
    assert len(rows) == 1
    model = service.store.select("SELECT ?r WHERE { ?m a twin:Model ; twin:revision ?r }")
    assert [int(r["r"] or 0) for r in model] == [service.revision]


def test_after_moves_door_changes_a_removal_and_a_re_creation_a_restart_gives_the_same_twin() -> None:
    store = imported(box_lab())
    service, _ = started(store)
    door = element_iri(spec("Door A"))
    docs = [
        box_turtle(TABLE, 6.6, 2.0),
        box_turtle(TABLE, 6.0, 2.1, yaw=0.7),
        f"{PREFIX}<{door}> twin:isOpen true .".encode(),
        f"{PREFIX}<{TABLE}> twin:removed true .".encode(),
        box_turtle(TABLE, 7.0, 1.9, sx=1.0),
        f"{PREFIX}<{door}> twin:isOpen false .".encode(),
        box_turtle(TABLE, 7.2, 1.9, sx=1.0),
        box_turtle(TABLE, 7.2, 1.9, sx=0.5),  # a new size: a new mesh
    ]
    for doc in docs:
        assert observe(service, "robot1", doc).ok
    again = TwinService(store, load_config())
    again.start()
    assert again.revision == service.revision
    for key, m in service.live_maps.skill_maps.items():
        np.testing.assert_array_equal(m.data, again.live_maps.skill_maps[key].data, err_msg=str(key))
        np.testing.assert_array_equal(m.data, service.live_maps.rebuild(m), err_msg=str(key))
    before, after = service.states[TABLE], again.states[TABLE]
    assert set(before.ifc_types) == set(after.ifc_types)
    assert replace(before, ifc_types=()) == replace(after, ifc_types=())
    assert again.states[door].is_open is False
    shape, fresh = service.live_maps.shape_of(TABLE), again.live_maps.shape_of(TABLE)
    assert shape is not None and fresh is not None
    np.testing.assert_array_equal(shape[1], fresh[1])
    np.testing.assert_array_equal(shape[0].vertices, fresh[0].vertices)


def test_in_memory_selection_answers_what_the_selection_query_answers_for_every_element() -> None:
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    pane = box_turtle("urn:r:pane", 5.0, 2.0, cls="IfcBuildingElementProxy").decode().rstrip(" .\n")
    observe(service, "robot1", (pane + f' ; <{TWIN}material> "Glass, tempered" .').encode())
    door = element_iri(spec("Door A"))
    observe(service, "robot1", f"{PREFIX}<{door}> twin:isOpen true .".encode())
    skills = [
        *service.skills.values(),
        parse_skill("walls", {"kind": "navigation", "include_types": ["IfcWall", "beo:Door"]}),
        parse_skill("no-glass", {"kind": "localization", "exclude_materials": ["glass", "fiberglass"]}),
        parse_skill("no-furniture", {"kind": "navigation", "exclude_types": ["IfcFurnishingElement"]}),
    ]
    for skill in skills:
        assert not needs_store(skill)
        by_store = {r["element"] for r in service.store.select(selection_query(skill))}
        in_memory = {
            iri
            for iri, state in service.states.items()
            if selects(skill, state, has_geometry=service.live_maps.shape_of(iri) is not None)
        }
        assert in_memory == by_store, skill.name


def test_a_skill_with_its_own_sparql_is_selected_by_the_store() -> None:
    config = load_config()
    skill = parse_skill("tables", {"kind": "navigation", "sparql": '?element twin:ifcClass "IfcFurniture" .'})
    config = replace(config, skills={**config.skills, "tables": skill})
    service, rec = started(config=config)
    reply = observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    assert ("ground-floor", "tables") in {(m["storey"], m["skill"]) for m in reply.body["maps"]}  # type: ignore[union-attr]
    m = service.live_maps.skill_maps[("ground-floor", "tables")]
    np.testing.assert_array_equal(m.data, service.live_maps.rebuild(m))
    assert rec.of(ObservationAccepted) and rec.of(MapUpdated) and rec.of(MapPublished)


@pytest.mark.parametrize("yaw", [0.0, math.pi / 7, 1.0])
def test_a_moved_table_keeps_its_mesh_and_changes_only_its_placement_in_the_graph(yaw: float) -> None:
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    meshes = service.store.select(f"SELECT ?ply WHERE {{ <{TABLE}/geometry> fog:asPly_v1.0-binaryLE ?ply }}")
    observe(service, "robot1", box_turtle(TABLE, 6.0, 2.2, yaw=yaw))
    again = service.store.select(f"SELECT ?ply WHERE {{ <{TABLE}/geometry> fog:asPly_v1.0-binaryLE ?ply }}")
    assert meshes == again and len(again) == 1


def test_a_turned_table_moved_many_times_writes_its_placement_alone_and_its_sizes_never_drift() -> None:
    # fusion places a move at the held sizes, which the held pose gives back from a turned mesh only to
    # about 1e-9 m: the box must still be the mesh it had, or every move writes a new mesh literal (a
    # string the store keeps for ever) and the sizes walk away from what the robot reported
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0, yaw=0.3))
    ply = f"SELECT ?ply WHERE {{ <{TABLE}/geometry> fog:asPly_v1.0-binaryLE ?ply }}"
    meshes = service.store.select(ply)
    shape = service.live_maps.shape_of(TABLE)
    assert shape is not None
    rng = np.random.default_rng(2)
    spots = zip(rng.uniform(5.0, 8.0, 40), rng.uniform(1.6, 2.4, 40), rng.uniform(0, 3, 40), strict=True)
    moves = [(6.0, 2.3, 1.1), *spots]
    for x, y, yaw in moves:
        assert observe(service, "robot1", box_turtle(TABLE, float(x), float(y), yaw=float(yaw))).ok
    assert service.revision > len(moves) // 2  # moves applied (fusion holds a short one back)
    moved = service.live_maps.shape_of(TABLE)
    assert moved is not None and moved[0] is shape[0]
    assert service.store.select(ply) == meshes


def test_moving_confirming_and_removing_the_same_tables_grows_neither_the_graph_nor_the_writer() -> None:
    service, _ = started()
    tables = {"robot1": ("urn:robot1:table", 4.5), "robot2": ("urn:robot2:table", 7.5)}
    rng = np.random.default_rng(3)

    def round_of(k: int) -> None:
        for robot, (table, x) in tables.items():
            if k % 10 == 9:
                assert observe(service, robot, f"{PREFIX}<{table}> twin:removed true .".encode()).ok
                continue
            turtle = box_turtle(table, x + (0.9 if k % 2 else -0.9), 2.0, yaw=float(rng.uniform(0, 3)))
            assert observe(service, robot, turtle).ok  # a move fusion applies at once (1.8 m)
            assert observe(service, robot, turtle).body.get("unchanged") is True

    for k in range(10):
        round_of(k)
    triples, sizes = len(service.store), writer_sizes({"live": service.live, "observer": service.observer})
    revision = service.revision
    for k in range(10, 30):
        round_of(k)
    assert service.revision == revision + 40
    assert len(service.store) == triples
    after = writer_sizes({"live": service.live, "observer": service.observer})
    grown = {k: (sizes.get(k), v) for k, v in after.items() if v > sizes.get(k, 0) and k != "observer.parsed"}
    assert grown == {}
    status = service.status()["sizes"]
    assert isinstance(status, dict) and after.items() <= status.items()  # what twin status says


def test_fifty_robot_iris_for_one_table_leave_nothing_behind_once_their_aliases_expire() -> None:
    # a tracker names the same table anew each time it loses it: each name becomes an alias (a triple
    # and an entry in memory) until unused for [fusion] alias_ttl_s
    now = [1_800_000_000 * 10**9]
    service = TwinService(imported(box_lab()), load_config(), clock=lambda: now[0])
    service.start()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0, yaw=0.3))
    observe(service, "robot2", box_turtle(TABLE, 6.6, 2.0, yaw=0.3))  # what memory keeps per robot
    triples, sizes = len(service.store), writer_sizes({"live": service.live})
    for i in range(50):
        now[0] += 10**8
        reply = observe(service, "robot2", box_turtle(f"urn:tracker:{i}", 6.61, 2.0, yaw=0.3))
        assert reply.body["resolved"] == {f"urn:tracker:{i}": TABLE}
    assert len(service.store) == triples + 50 and len(service.live.fusion.aliases) == 50
    now[0] += service.config.fusion.alias_ttl_ns + 10**9
    assert service.observer.expire_aliases() == 50
    assert len(service.store) == triples
    after = writer_sizes({"live": service.live})
    assert {k: v for k, v in after.items() if v > sizes.get(k, 0)} == {}


def test_a_removed_element_leaves_its_tombstone_but_no_cached_pose() -> None:
    service, _ = started()
    people = [f"urn:robot1:person-{i}" for i in range(5)]
    for i, iri in enumerate(people):
        assert observe(service, "robot1", box_turtle(iri, 3.0 + i, 2.0, sx=0.5, sy=0.5, sz=1.7, yaw=0.4)).ok
    assert set(people) <= set(service.live.fusion.shape_poses)
    for iri in people:
        assert observe(service, "robot1", f"{PREFIX}<{iri}> twin:removed true .".encode()).ok
    assert all(service.states[iri].removed for iri in people)
    assert not set(people) & set(service.live.fusion.shape_poses)


def test_a_writer_whose_queue_never_runs_dry_stops_taking_work_once_its_budget_is_spent() -> None:
    # serve_forever flushes the store, expires aliases and saves snapshots between two process calls:
    # at saturation the queue never runs dry, and without a budget none of them ever ran
    service, _ = started()
    replies: list[object] = []
    for k in range(100):
        service.submit_observation("robot1", box_turtle(TABLE, 4.5 + (k % 2), 2.0), replies.append)
    handled = service.process(budget_s=0.0)
    assert 0 < handled < 100 and service.queue_depth == 100 - handled
    assert service.process() == 100 - handled and len(replies) == 100


def test_the_store_is_flushed_and_housekeeping_runs_only_after_changes() -> None:
    store = imported(box_lab())
    jobs: list[int] = []
    service = TwinService(store, load_config(), flush_every_s=0.0, housekeeping=[lambda: jobs.append(1)])
    service.start()
    service.flush_store(due_only=True)
    assert jobs == []  # nothing committed yet: nothing to flush
    assert observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0)).ok
    service.flush_store(due_only=True)
    service.flush_store(due_only=True)
    assert jobs == [1]


@pytest.mark.parametrize("inflation", [0.0, 0.12])
def test_a_batch_of_moves_rendered_together_equals_a_rebuild(inflation: float) -> None:
    skill = parse_skill(
        "wide", {"kind": "navigation", "robot_height_m": 0.6, "inflation_radius_m": inflation}
    )
    config = load_config()
    service, _ = started(config=replace(config, skills={**config.skills, "wide": skill}))
    rng = np.random.default_rng(7)
    for round_ in range(4):
        for k in range(6):
            x, y = float(rng.uniform(4.0, 9.0)), float(rng.uniform(1.5, 2.5))
            doc = box_turtle(f"urn:r:t{k}", x, y, yaw=float(rng.uniform(0, 3)))
            service.submit_observation("robot1", doc)
        if round_ == 3:
            service.submit_observation("robot1", f"{PREFIX}<urn:r:t2> twin:removed true .".encode())
        service.process()
        for key, m in service.live_maps.skill_maps.items():
            np.testing.assert_array_equal(
                m.data, service.live_maps.rebuild(m), err_msg=f"{key} round {round_}"
            )
