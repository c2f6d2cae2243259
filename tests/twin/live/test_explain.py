"""Why is this cell occupied? The elements that occupy a cell (with who observed them), or why the
elements near a free cell are not drawn: a glass wall, an open door, a table in a lidar map."""

from __future__ import annotations

import pytest

from tests.twin.box_lab import OX, OY, element_iri, spec
from tests.twin.live_helpers import PREFIX, box_turtle, observe, started
from twin.live import TwinService
from twin.live.membership import rejection
from twin.live.requests import Reply
from twin.selection.skill_selection import selection_query

GROUND = "ground-floor"
TABLE = "urn:robot1:table-1"


def explain(service: TwinService, skill: str, x: float, y: float, storey: str = GROUND) -> Reply:
    replies: list[Reply] = []
    service.submit_explain(storey, skill, OX + x, OY + y, replies.append)
    service.process()
    assert len(replies) == 1
    return replies[0]


def names(entries: object) -> list[str]:
    return [e["name"] or e["iri"] for e in entries]  # type: ignore[attr-defined]


def test_an_observed_table_occupies_its_cells_with_the_robot_time_and_revision_that_put_it_there() -> None:
    service, _ = started()
    assert observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0)).body["revision"] == 1
    answer = explain(service, "navigation", 6.6, 2.0).body
    assert answer["ok"] and answer["state"] == "occupied" and answer["value"] == 100
    (table,) = answer["occupied_by"]  # type: ignore[misc]
    assert table["iri"] == TABLE and table["class"] == "IfcFurniture"
    assert table["observed"]["robot"] == "robot1" and table["observed"]["revision"] == 1
    assert table["observed"]["at"].startswith("20")  # an xsd:dateTime
    lidar = explain(service, "localization", 6.6, 2.0).body  # furniture is not in the lidar map
    assert lidar["state"] == "free"
    near = {e["iri"]: e["why_not"] for e in lidar["near"]}  # type: ignore[attr-defined]
    assert near[TABLE] == "excluded type IfcFurnishingElement"


def test_a_free_cell_beside_the_glass_wall_says_the_glass_is_excluded_and_the_wall_is_named() -> None:
    service, _ = started()
    answer = explain(service, "localization", 11.9, 2.0).body  # just inside the glass wall (x 12.0-12.1)
    assert answer["state"] == "free" and answer["occupied_by"] == []
    near = {e["name"]: e for e in answer["near"]}  # type: ignore[attr-defined]
    assert near["Glass wall"]["why_not"] == "made of glass (Glass)"
    assert near["Glass wall"]["global_id"] == spec("Glass wall").global_id
    on_glass = explain(service, "navigation", 12.05, 2.0).body  # the navigation skill draws glass
    assert names(on_glass["occupied_by"]) == ["Glass wall"]


def test_a_door_occupies_its_cells_until_it_is_seen_open() -> None:
    service, _ = started()
    door = element_iri(spec("Door A"))
    closed = explain(service, "navigation", 2.0, -0.1).body
    assert names(closed["occupied_by"]) == ["Door A"]
    observe(service, "robot1", f"{PREFIX}<{door}> twin:isOpen true .".encode())
    opened = explain(service, "navigation", 2.0, -0.1).body
    assert opened["state"] == "free"
    near = {e["name"]: e["why_not"] for e in opened["near"]}  # type: ignore[attr-defined]
    assert near["Door A"] == "a door observed open (passable)"


@pytest.mark.parametrize(
    ("storey", "skill", "x", "message"),
    [
        ("ground-floor", "flying", 1.0, "No map ground-floor/flying; the twin's maps are"),
        ("attic", "navigation", 1.0, "No map attic/navigation"),
        ("ground-floor", "navigation", 500.0, "is outside the map ground-floor/navigation"),
        ("ground-floor", "navigation", float("nan"), "finite coordinates"),
    ],
)
def test_an_unknown_map_or_a_point_outside_it_is_refused_by_name(
    storey: str, skill: str, x: float, message: str
) -> None:
    service, _ = started()
    reply = explain(service, skill, x, 1.0, storey=storey)
    assert not reply.ok and message in str(reply.body["error"])


def test_explain_gives_the_selection_s_own_reasons_and_none_only_for_what_sparql_selects() -> None:
    service, _ = started()
    observe(service, "robot1", box_turtle(TABLE, 11.5, 2.0))
    observe(service, "robot1", f"{PREFIX}<{element_iri(spec('Door A'))}> twin:isOpen true .".encode())
    for skill in service.skills.values():
        by_store = {r["element"] for r in service.store.select(selection_query(skill))}
        for iri, state in service.states.items():
            reason = rejection(skill, state, has_geometry=service.live_maps.shape_of(iri) is not None)
            assert (reason is None) == (iri in by_store), (skill.name, iri, reason)
    answer = explain(service, "localization", 11.9, 2.0).body  # the glass wall and the table are near
    near = {e["iri"]: e["why_not"] for e in answer["near"]}  # type: ignore[attr-defined]
    skill = service.skills["localization"]
    assert {near[i] for i in near} >= {"made of glass (Glass)", "excluded type IfcFurnishingElement"}
    for iri, why in near.items():
        reason = rejection(skill, service.states[iri], has_geometry=True)
        assert why == reason or (reason is None and why.startswith(("outside the height band", "selected")))
