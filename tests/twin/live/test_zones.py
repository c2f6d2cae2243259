"""Keepout and speed zones: operators mark elements (or draw virtual ones), and the nav2 filter masks
(``keepout`` and ``speed`` skills) follow incrementally, equal to a rebuild; robots cannot mark."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import imported
from tests.twin.box_lab import OX, OY, box_lab, element_iri, spec
from tests.twin.live_helpers import PREFIX, box_turtle, observe, started
from twin.config import Config, load_config
from twin.errors import ObservationError, SkillError
from twin.live import TwinService
from twin.live.parse import parse_observation
from twin.selection.skills import parse_skill

ZONE = "urn:operator:zone-1"
GROUND = "ground-floor"


def zone_config(tmp_path: Path) -> Config:
    path = tmp_path / "zones.toml"
    path.write_text(
        """
[skills.keepout]
kind = "keepout"
resolution_m = 0.05
[skills.slow]
kind = "speed"
resolution_m = 0.05
limit_percent = 30
[robots.operator]
rights = ["create", "dynamic", "doors", "static", "zones"]
"""
    )
    return load_config(path)


def zoned(tmp_path: Path) -> TwinService:
    service, _ = started(imported(box_lab()), zone_config(tmp_path))
    return service


def assert_all_equal_rebuild(service: TwinService) -> None:
    for key, m in service.live_maps.skill_maps.items():
        np.testing.assert_array_equal(m.data, service.live_maps.rebuild(m), err_msg=str(key))


def test_masks_start_empty_when_no_zone_is_marked(tmp_path: Path) -> None:
    service = zoned(tmp_path)
    for skill in ("keepout", "slow"):
        assert not service.live_maps.skill_maps[(GROUND, skill)].data.any()


def test_an_operator_marking_the_table_keepout_changes_the_mask_by_an_update_and_unmarking_restores_it(
    tmp_path: Path,
) -> None:
    service = zoned(tmp_path)
    table = element_iri(spec("Table"))
    before = service.live_maps.skill_maps[(GROUND, "keepout")].data.copy()
    reply = observe(service, "operator", f"{PREFIX}<{table}> twin:keepout true .".encode())
    assert reply.ok, reply.body
    updates = [m for m in reply.body["maps"] if m["skill"] == "keepout"]
    assert len(updates) == 1
    u = updates[0]
    mask = service.live_maps.skill_maps[(GROUND, "keepout")]
    frame = mask.plan.frame
    # the update is the table's footprint (1.2 x 0.8 m), not the whole storey
    assert u["width"] * u["height"] < frame.width * frame.height / 20
    assert set(np.unique(mask.data)) == {0, 100}
    x, y = OX + 2.0, OY + 3.0  # the table's centre
    col, row = int((x - frame.origin_x) / frame.resolution_m), int((y - frame.origin_y) / frame.resolution_m)
    assert mask.data[row, col] == 100
    assert not service.live_maps.skill_maps[(GROUND, "slow")].data.any()
    assert_all_equal_rebuild(service)
    unmarked = observe(service, "operator", f"{PREFIX}<{table}> twin:keepout false .".encode())
    assert unmarked.ok and unmarked.body["revision"] == 2
    np.testing.assert_array_equal(mask.data, before)


def test_a_speed_zone_shows_its_percent_only_in_the_mask_of_that_limit(tmp_path: Path) -> None:
    service = zoned(tmp_path)
    table = element_iri(spec("Table"))
    assert observe(service, "operator", f"{PREFIX}<{table}> twin:speedLimit 30 .".encode()).ok
    slow = service.live_maps.skill_maps[(GROUND, "slow")].data
    assert set(np.unique(slow)) == {0, 30}
    assert not service.live_maps.skill_maps[(GROUND, "keepout")].data.any()
    assert_all_equal_rebuild(service)
    assert observe(service, "operator", f"{PREFIX}<{table}> twin:speedLimit 60 .".encode()).ok
    assert not slow.any()  # 60 % is another profile's limit
    assert observe(service, "operator", f"{PREFIX}<{table}> twin:speedLimit 60 .".encode()).body["unchanged"]


def test_a_virtual_zone_drawn_by_an_operator_is_in_the_mask_but_in_no_map_of_the_building(
    tmp_path: Path,
) -> None:
    service = zoned(tmp_path)
    nav_before = service.live_maps.skill_maps[(GROUND, "navigation")].data.copy()
    loc_before = service.live_maps.skill_maps[(GROUND, "localization")].data.copy()
    zone = box_turtle(ZONE, 9.0, 2.0, sx=2.0, sy=2.0, sz=2.0, cls="IfcVirtualElement").decode()
    reply = observe(service, "operator", (zone.rstrip(" .\n") + " ; twin:keepout true .").encode())
    assert reply.ok, reply.body
    assert {m["skill"] for m in reply.body["maps"]} == {"keepout"}
    assert int((service.live_maps.skill_maps[(GROUND, "keepout")].data == 100).sum()) >= 40 * 40
    np.testing.assert_array_equal(service.live_maps.skill_maps[(GROUND, "navigation")].data, nav_before)
    np.testing.assert_array_equal(service.live_maps.skill_maps[(GROUND, "localization")].data, loc_before)
    assert_all_equal_rebuild(service)


def test_a_robot_without_the_zones_right_cannot_mark_a_zone_and_nothing_changes(tmp_path: Path) -> None:
    service = zoned(tmp_path)
    observe(service, "robot1", box_turtle("urn:robot1:table-9", 9.0, 2.0))
    revision = service.revision
    reply = observe(service, "robot1", f"{PREFIX}<urn:robot1:table-9> twin:keepout true .".encode())
    assert not reply.ok
    assert "zones" in reply.body["error"] and "urn:robot1:table-9" in reply.body["error"]
    assert service.revision == revision
    assert not service.live_maps.skill_maps[(GROUND, "keepout")].data.any()


def test_zone_marks_survive_a_restart(tmp_path: Path) -> None:
    store = imported(box_lab())
    config = zone_config(tmp_path)
    service, _ = started(store, config)
    table = element_iri(spec("Table"))
    observe(service, "operator", f"{PREFIX}<{table}> twin:keepout true ; twin:speedLimit 30 .".encode())
    marked = {k: m.data.copy() for k, m in service.live_maps.skill_maps.items()}
    again, _ = started(store, config)
    for key, data in marked.items():
        np.testing.assert_array_equal(again.live_maps.skill_maps[key].data, data, err_msg=str(key))
    assert again.states[table].keepout and again.states[table].speed_limit == 30


@pytest.mark.parametrize(
    ("triple", "message"),
    [
        ("twin:speedLimit 130", "percent from 0 (no limit) to 100, got '130'"),
        ("twin:speedLimit -1", "percent from 0 (no limit) to 100, got '-1'"),
        ('twin:speedLimit "fast"', "must be a literal of type integer"),
        ('twin:keepout "yes"', "must be a literal of type boolean"),
    ],
)
def test_a_bad_zone_mark_is_refused_by_name(triple: str, message: str) -> None:
    with pytest.raises(ObservationError, match=re.escape(message)):
        parse_observation(f"{PREFIX}<urn:x> {triple} .", limits=load_config().limits)


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"kind": "speed", "limit_percent": 0}, "'limit_percent' must be an integer from 1 to 100, got 0"),
        ({"kind": "speed", "limit_percent": 50.5}, "'limit_percent' must be an integer from 1 to 100"),
        (
            {"kind": "keepout", "limit_percent": 50},
            "unknown field 'limit_percent' \\(limit_percent belongs to speed",
        ),
        ({"kind": "keepout", "lidar_height_m": 0.3}, "belongs to localization skills"),
    ],
)
def test_a_bad_mask_profile_is_refused_by_field(table: dict[str, object], message: str) -> None:
    with pytest.raises(SkillError, match=message):
        parse_skill("zones", table)
