"""Routes skills in the configuration: parsed beside the map skills, checked against them."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.config import config_schema, load_config
from twin.errors import ConfigError
from twin.routes import RouteError, check_routes, parse_routes


def _config(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "site.toml"
    path.write_text(text)
    return path


def test_a_routes_skill_is_read_with_its_fleet_waypoints_and_defaults(tmp_path: Path) -> None:
    cfg = load_config(
        _config(
            tmp_path,
            """
[skills.cleaners]
kind = "routes"
navigation = "lab-navigation"
fleet = "cleanerbots"
speed_m_s = 0.7
storeys = ["ground-floor"]
waypoints.charger1 = { storey = "ground-floor", x = 12.0, y = 8.0, charger = true }
waypoints.desk = { at = "Room A", parking_spot = true, dock = "desk_dock" }
""",
        )
    )
    routes = cfg.routes["cleaners"]
    assert "cleaners" not in cfg.skills  # the map skills stay maps
    assert (routes.fleet, routes.graph_name, routes.speed_m_s, routes.max_lane_m) == (
        "cleanerbots",
        "cleaners",
        0.7,
        3.0,
    )
    charger, desk = routes.waypoints
    assert (charger.name, charger.storey, charger.x, charger.charger) == (
        "charger1",
        "ground-floor",
        12.0,
        True,
    )
    assert (desk.at, desk.parking_spot, desk.dock) == ("Room A", True, "desk_dock")


def test_a_routes_skill_naming_a_missing_navigation_skill_is_refused_in_one_line(tmp_path: Path) -> None:
    path = _config(tmp_path, '[skills.fleet]\nkind = "routes"\nnavigation = "nope"\n')
    with pytest.raises(
        ConfigError,
        match=r"^Configuration \[skills.fleet\]: .*navigation skill 'nope' is not configured; "
        r"navigation skills: .*lab-navigation",
    ) as err:
        load_config(path)
    assert "\n" not in str(err.value)


def test_a_routes_skill_naming_a_localization_skill_is_refused() -> None:
    cfg = load_config()
    routes = parse_routes("fleet", {"kind": "routes", "navigation": "localization"})
    with pytest.raises(RouteError, match="navigation skill 'localization' is a localization skill"):
        check_routes(routes, cfg.skills)


def test_a_routes_skill_naming_a_missing_keepout_skill_is_refused() -> None:
    cfg = load_config()
    routes = parse_routes("fleet", {"kind": "routes", "navigation": "navigation", "keepout": ["zones"]})
    with pytest.raises(RouteError, match="keepout 'zones' is not a configured keepout skill"):
        check_routes(routes, cfg.skills)


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"kind": "routes"}, r"\[skills.fleet\] navigation: is required"),
        ({"kind": "routes", "navigation": "n", "speed_m_s": 0}, r"speed_m_s: expected a number > 0"),
        ({"kind": "routes", "navigation": "n", "max_lane_m": 0.1}, r"max_lane_m: expected a number >= 0.5"),
        ({"kind": "routes", "navigation": "n", "lanes": 1}, r"lanes: unknown key"),
        (
            {"kind": "routes", "navigation": "n", "waypoints": {"c": {"x": 1.0}}},
            r"waypoints.c\]: give either storey, x and y, or at",
        ),
        ({"kind": "routes", "navigation": "n", "waypoints": {"a b": {"at": "Room"}}}, r"waypoint name 'a b'"),
    ],
)
def test_bad_routes_tables_are_refused_naming_the_key(table: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_routes("fleet", table)


def test_the_schema_knows_the_routes_kind_and_its_keys() -> None:
    skill = config_schema()["properties"]["skills"]["additionalProperties"]
    assert "routes" in skill["properties"]["kind"]["enum"]
    assert {"navigation", "fleet", "max_lane_m", "waypoints"} <= set(skill["properties"])


def test_vertex_spacing_defaults_to_half_a_metre_and_never_exceeds_the_longest_lane() -> None:
    assert parse_routes("r", {"kind": "routes", "navigation": "n"}).spacing_m == 0.5
    assert (
        parse_routes(
            "r", {"kind": "routes", "navigation": "n", "spacing_m": 2.0, "max_lane_m": 1.0}
        ).spacing_m
        == 1.0
    )
    with pytest.raises(ConfigError, match=r"spacing_m: expected a number >= 0.2"):
        parse_routes("r", {"kind": "routes", "navigation": "n", "spacing_m": 0.1})
