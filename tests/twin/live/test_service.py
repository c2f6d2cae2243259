"""The twin service on the box lab: observations change exactly the maps and cells they should."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.conftest import imported
from tests.twin.box_lab import OX, OY, box_lab, element_iri, spec
from tests.twin.live_helpers import PREFIX, TWIN, box_turtle, observe, started
from twin.config import load_config
from twin.errors import QueryError
from twin.live import TwinService
from twin.live.events import MapPublished, MapRemoved, MapUpdated, ObservationAccepted, ObservationRejected
from twin.live.membership import selects
from twin.maps.grid import OCCUPIED
from twin.selection.skill_selection import selection_query

TABLE = "urn:robot1:table-1"


def grid_of(service: TwinService, skill: str, storey: str = "ground-floor") -> np.ndarray:
    return service.live_maps.skill_maps[(storey, skill)].data.copy()


def cells(service: TwinService, skill: str, *box: float) -> np.ndarray:
    x0, y0, x1, y1 = box
    m = service.live_maps.skill_maps[("ground-floor", skill)]
    w = m.plan.frame.window_for(OX + x0, OY + y0, OX + x1, OY + y1)
    return m.data[w.row0 : w.row1, w.col0 : w.col1]


def assert_equals_rebuild(service: TwinService) -> None:
    for key, m in service.live_maps.skill_maps.items():
        np.testing.assert_array_equal(m.data, service.live_maps.rebuild(m), err_msg=str(key))


def test_a_table_in_the_corridor_appears_in_navigation_maps_only_within_its_footprint() -> None:
    service, rec = started()
    before = {k: m.data.copy() for k, m in service.live_maps.skill_maps.items()}
    reply = observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0, sx=0.6, sy=0.6))
    assert reply.ok, reply.body
    assert reply.body["revision"] == 1
    assert reply.body["upserted"] == [TABLE]
    changed = {(m["storey"], m["skill"]) for m in reply.body["maps"]}  # type: ignore[union-attr]
    assert changed == {("ground-floor", "navigation"), ("ground-floor", "lab-navigation")}
    for skill in ("navigation", "lab-navigation"):
        assert (cells(service, skill, 6.32, 1.72, 6.88, 2.28) == OCCUPIED).all()
        diff = np.argwhere(grid_of(service, skill) != before[("ground-floor", skill)])
        frame = service.live_maps.skill_maps[("ground-floor", skill)].plan.frame
        footprint = frame.window_for(OX + 6.3, OY + 1.7, OX + 6.9, OY + 2.3)
        assert diff[:, 0].min() >= footprint.row0 and diff[:, 0].max() < footprint.row1
        assert diff[:, 1].min() >= footprint.col0 and diff[:, 1].max() < footprint.col1
    for skill in ("localization", "lab-localization"):
        np.testing.assert_array_equal(grid_of(service, skill), before[("ground-floor", skill)])
    updates = rec.of(MapUpdated)
    assert {(u.storey, u.skill) for u in updates} == changed
    u = updates[0]
    m = service.live_maps.skill_maps[(u.storey, u.skill)]
    np.testing.assert_array_equal(
        u.data, m.data[u.window.row0 : u.window.row1, u.window.col0 : u.window.col1]
    )
    assert_equals_rebuild(service)


def test_removing_the_table_restores_the_original_maps_bit_for_bit() -> None:
    service, _ = started()
    before = {k: m.data.copy() for k, m in service.live_maps.skill_maps.items()}
    assert observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0)).ok
    reply = observe(service, "robot1", f"<{TABLE}> <{TWIN}removed> true .".encode())
    assert reply.ok and reply.body["removed"] == [TABLE]
    for key, m in service.live_maps.skill_maps.items():
        np.testing.assert_array_equal(m.data, before[key], err_msg=str(key))


def test_opening_the_door_frees_its_cells_and_closing_it_blocks_them_again() -> None:
    service, _ = started()
    door = element_iri(spec("Door A"))
    leaf, gap = (1.6, -0.11, 2.4, -0.09), (1.6, -0.19, 2.4, -0.01)
    assert (cells(service, "navigation", *leaf) == OCCUPIED).all()
    assert observe(service, "robot1", f"<{door}> <{TWIN}isOpen> true .".encode()).ok
    assert not (cells(service, "navigation", *gap) == OCCUPIED).any()
    assert observe(service, "robot1", f"<{door}> <{TWIN}isOpen> false .".encode()).ok
    assert (cells(service, "navigation", *leaf) == OCCUPIED).all()
    assert_equals_rebuild(service)


def test_moving_an_imported_element_moves_it_in_the_maps() -> None:
    service, _ = started()
    table = element_iri(spec("Table"))
    x0, y0, _, x1, y1, _ = spec("Table").box
    placement = np.eye(4)
    placement[:3, 3] = ((x0 + x1) / 2 + 0.8, (y0 + y1) / 2 - 1.0, 0.375)
    text = " ".join(repr(float(v)) for v in placement.ravel())
    reply = observe(service, "robot1", f'<{table}> <{TWIN}placement> "{text}"^^<{TWIN}Matrix4x4> .'.encode())
    assert reply.ok, reply.body
    assert (cells(service, "navigation", 2.3, 1.7, 3.3, 2.3) == OCCUPIED).all()
    assert not (cells(service, "navigation", 1.5, 2.7, 2.5, 3.3) == OCCUPIED).any()
    assert_equals_rebuild(service)


@pytest.mark.parametrize(
    ("payload", "message"),
    [
        (b"this is not turtle", "not valid Turtle"),
        (PREFIX.encode() + f'<{TABLE}> twin:colour "red" .'.encode(), "unknown term"),
        (box_turtle(TABLE, 6.6, 2.0).replace(b" 0.375 ", b" NaN "), "NaN or infinite"),
        (box_turtle(TABLE, 6.6, 2.0, sx=500.0), "box size sx=500.0"),
        (box_turtle(TABLE, 6.6, 2.0, storey="attic"), "unknown storey 'attic'"),
        (box_turtle(TABLE, 6.6, 2.0, cls="IfcSpaceship"), "not an IFC element class"),
        (box_turtle(TABLE, 900.0, 2.0), "outside the site's extent"),
        (box_turtle(TABLE, 6.6, 2.0, cls="IfcWall"), "lacks the 'static' right"),
        (f"<{element_iri(spec('Wall A west'))}> <{TWIN}removed> true .".encode(), "lacks the 'static' right"),
        (f"<{element_iri(spec('Table'))}> <{TWIN}isOpen> true .".encode(), "not a door"),
        (f"<{TABLE}> <{TWIN}removed> true .".encode(), "no such element"),
        (PREFIX.encode() + f'<{TABLE}> twin:storey "ground-floor" .'.encode(), "give its twin:ifcClass"),
        (b" " * (2 << 20), "more than the 1,048,576 allowed"),
    ],
)
def test_bad_observations_are_refused_naming_the_problem_and_change_nothing(
    payload: bytes, message: str
) -> None:
    service, rec = started()
    triples = len(service.store)
    before = {k: m.data.copy() for k, m in service.live_maps.skill_maps.items()}
    reply = observe(service, "robot1", payload)
    assert not reply.ok
    assert message in str(reply.body["error"])
    assert json.loads(reply.to_json())["ok"] is False
    assert len(service.store) == triples and service.revision == 0
    for key, m in service.live_maps.skill_maps.items():
        np.testing.assert_array_equal(m.data, before[key])
    assert rec.of(ObservationRejected)[-1].error == reply.body["error"]
    assert observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0)).ok  # still serving


def test_a_robot_with_the_static_right_may_change_structure() -> None:
    cfg = load_config()
    cfg = type(cfg)(
        **{
            **{f: getattr(cfg, f) for f in cfg.__dataclass_fields__},
            "default_rights": frozenset({"create", "static"}),
        }
    )
    service, _ = started(config=cfg)
    wall = element_iri(spec("Wall corridor south"))
    assert observe(service, "builder", f"<{wall}> <{TWIN}removed> true .".encode()).ok
    assert not (cells(service, "navigation", 4.5, 1.25, 7.5, 1.35) == OCCUPIED).any()


def test_provenance_is_in_the_graph() -> None:
    service, _ = started()
    observe(service, "robot7", box_turtle(TABLE, 6.6, 2.0))
    rows = service.store.select(
        f"SELECT ?by ?at ?rev WHERE {{ <{TABLE}> twin:observedBy ?by ; twin:observedAt ?at ; "
        "twin:revision ?rev }"
    )
    assert rows == [{"by": "robot7", "at": rows[0]["at"], "rev": "1"}]
    assert rows[0]["at"] and rows[0]["at"].startswith("20")
    assert service.store.ask(f'ASK {{ <{TABLE}> twin:ifcType "IfcFurnishingElement" }}')


def test_a_restarted_service_serves_the_same_maps_in_the_same_frames() -> None:
    store = imported(box_lab())
    service, _ = started(store)
    observe(service, "robot1", box_turtle(TABLE, 11.5, 3.5))  # near the building's edge
    observe(service, "robot1", box_turtle("urn:robot1:crate", 2.0, 1.0))
    again, _ = started(store)
    assert again.revision == 2
    for key, m in service.live_maps.skill_maps.items():
        other = again.live_maps.skill_maps[key]
        assert other.plan.frame == m.plan.frame
        np.testing.assert_array_equal(other.data, m.data, err_msg=str(key))


def test_skills_are_added_and_removed_at_run_time_and_survive_a_restart() -> None:
    store = imported(box_lab())
    service, rec = started(store)
    replies = []
    service.submit_skill("tall", b'{"kind": "navigation", "robot_height_m": 2.0}', replies.append)
    service.submit_skill("lab-localization", None, replies.append)
    service.submit_skill("bad", b'{"kind": "flying"}', replies.append)
    service.process()
    assert [r.ok for r in replies] == [True, True, False]
    assert "field 'kind'" in str(replies[2].body["error"])
    assert ("ground-floor", "tall") in service.live_maps.skill_maps
    assert ("ground-floor", "lab-localization") not in service.live_maps.skill_maps
    assert any(isinstance(e, MapPublished) and e.grid.skill == "tall" for e in rec.events)
    assert any(isinstance(e, MapRemoved) and e.skill == "lab-localization" for e in rec.events)
    again, _ = started(store)
    assert "tall" in again.skills and "lab-localization" not in again.skills


def test_the_sparql_view_is_read_only_and_bounded() -> None:
    service, _ = started()
    media, body = service.query("SELECT (COUNT(*) AS ?n) WHERE { ?e a bot:Element }")
    assert media == "application/sparql-results+json" and b'"n"' in body
    with pytest.raises(QueryError, match="read-only"):
        service.query("PREFIX x: <urn:x#>\nINSERT DATA { <urn:a> <urn:b> <urn:c> }")
    with pytest.raises(QueryError, match="SERVICE"):
        service.query("SELECT * WHERE { SERVICE <http://127.0.0.1:9/> { ?s ?p ?o } }")
    media, body = service.query("CONSTRUCT { ?e a bot:Element } WHERE { ?e a bot:Element } LIMIT 2")
    assert media == "text/turtle"


def test_a_failing_sink_never_stops_the_service() -> None:
    class Broken:
        def emit(self, event: object) -> None:
            raise RuntimeError("disk full")

    store = imported(box_lab())
    service = TwinService(store, load_config(), sinks=[Broken()])
    service.start()
    assert observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0)).ok


def test_accepted_observations_report_the_new_elements_with_their_geometry() -> None:
    service, rec = started()
    observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0))
    event = rec.of(ObservationAccepted)[-1]
    assert [e.iri for e in event.upserted] == [TABLE]
    assert event.upserted[0].ifc_class == "IfcFurniture" and event.upserted[0].mesh.triangle_count == 12
    status = service.status()
    assert status["revision"] == 1
    assert status["observations"] == {"accepted": 1, "unchanged": 0, "rejected": 0}


def test_an_observed_glass_pane_is_seen_as_glass_and_a_fiberglass_crate_is_not() -> None:
    service, _ = started()
    for iri, material, x in (("urn:r:pane", "Glass - Clear", 6.6), ("urn:r:crate", "Fiberglass", 2.0)):
        doc = box_turtle(iri, x, 2.0, cls="IfcBuildingElementProxy").decode()
        doc = doc.rstrip(" .\n") + f' ; <{TWIN}material> "{material}" .'
        assert observe(service, "robot1", doc.encode()).ok
    skill = service.skills["lab-navigation"]
    glassless = type(skill)(
        **{**{f: getattr(skill, f) for f in skill.__dataclass_fields__}, "exclude_materials": ("glass",)}
    )
    only = ["urn:r:pane", "urn:r:crate"]
    by_store = {r["element"] for r in service.store.select(selection_query(glassless, only))}
    in_memory = {i for i in only if selects(glassless, service.states[i], has_geometry=True)}
    assert by_store == in_memory == {"urn:r:crate"}


def test_queued_observations_commit_one_by_one_and_share_one_map_pass_that_equals_a_rebuild() -> None:
    service, rec = started()
    other, _ = started()  # the same observations, one at a time
    payloads = [
        box_turtle("urn:robot1:a", 6.0, 2.0),
        box_turtle("urn:robot1:a", 7.5, 2.2, yaw=0.4),  # moves what the batch just added
        box_turtle("urn:robot1:b", 5.0, 2.4),
        b"this is not turtle",
        f"{PREFIX}<urn:robot1:a> twin:removed true .".encode(),
        box_turtle("urn:robot1:b", 8.0, 1.9),
        box_turtle("urn:robot1:a", 6.5, 2.1),  # re-created after its removal, in the same batch
    ]
    replies: list = [None] * len(payloads)
    for i, p in enumerate(payloads):
        service.submit_observation("robot1", p, lambda r, i=i: replies.__setitem__(i, r))
    assert service.process() == len(payloads)
    one_by_one = [observe(other, "robot1", p) for p in payloads]
    assert (
        [r.ok for r in replies] == [r.ok for r in one_by_one] == [True, True, True, False, True, True, True]
    )
    assert [r.body.get("revision") for r in replies] == [1, 2, 3, None, 4, 5, 6]
    assert service.revision == 6
    assert len(rec.of(ObservationAccepted)) == 6 and len(rec.of(ObservationRejected)) == 1
    assert_equals_rebuild(service)
    for key, m in service.live_maps.skill_maps.items():  # the batch ends where one-by-one processing ends
        np.testing.assert_array_equal(m.data, other.live_maps.skill_maps[key].data, err_msg=str(key))
    updates = rec.of(MapUpdated)
    assert updates and all(u.revision == 6 for u in updates[-len(replies[-1].body["maps"]) :])
    rows = service.store.select(
        "SELECT ?e ?rev WHERE { ?e twin:revision ?rev . FILTER(STRSTARTS(STR(?e), 'urn:robot1:')) }"
    )
    assert {r["e"]: int(r["rev"] or -1) for r in rows} == {"urn:robot1:a": 6, "urn:robot1:b": 5}
