from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.twin.box_lab import GROUND, spec
from twin.config import load_config
from twin.errors import ConfigError, QueryError, SkillError
from twin.graph.rdf import literal_value
from twin.graph.store import GraphStore
from twin.selection.skill_selection import selection_query
from twin.selection.skills import parse_skill, parse_skill_json


def test_shipped_profiles_reproduce_the_paper() -> None:
    cfg = load_config()
    loc, nav = cfg.skill("localization"), cfg.skill("navigation")
    assert loc.kind == "localization"
    assert loc.lidar_height_m == 0.5
    assert set(loc.exclude_types) == {
        "IfcOpeningElement",
        "IfcFurnishingElement",
        "IfcBuildingElementProxy",
        "IfcFlowTerminal",
    }
    assert loc.exclude_materials == ("glass",)
    assert nav.robot_height_m == 1.5
    assert cfg.skill("lab-localization").lidar_height_m == 0.1
    assert cfg.skill("lab-navigation").robot_height_m == 0.5


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"kind": "flying"}, "field 'kind'"),
        ({"kind": "navigation", "robot_height_m": -1.0}, "field 'robot_height_m'"),
        ({"kind": "navigation", "robot_height_m": float("nan")}, "field 'robot_height_m'"),
        ({"kind": "localization", "lidar_height_m": "high"}, "field 'lidar_height_m'"),
        ({"kind": "localization", "colour": "red"}, "unknown field 'colour'.$"),
        ({"kind": "navigation", "robot_hieght_m": 1.0}, r"\(did you mean robot_height_m\?\)"),
        ({"kind": "navigation", "lidar_height_m": 0.2}, "belongs to localization"),
        ({"kind": "navigation", "sparql": "?element a ?"}, "field 'sparql' does not parse"),
        ({"kind": "navigation", "exclude_types": ["wall"]}, "field 'exclude_types'"),
        ({"kind": "navigation", "floor_clearance_m": 1.0, "robot_height_m": 0.5}, "floor_clearance_m"),
    ],
)
def test_bad_profiles_are_rejected_naming_the_field(data: dict[str, object], message: str) -> None:
    with pytest.raises(SkillError, match=message):
        parse_skill("bad", data)


def test_a_profile_round_trips_through_json() -> None:
    skill = parse_skill("x", {"kind": "navigation", "robot_height_m": 0.7, "exclude_materials": ["Glass"]})
    assert parse_skill_json("x", json.dumps(skill.to_json())) == skill


def test_selection_by_type_includes_subtypes_and_excludes_glass(box_store: GraphStore) -> None:
    skill = parse_skill(
        "walls", {"kind": "localization", "include_types": ["IfcWall"], "exclude_materials": ["GLASS"]}
    )
    got = {literal_value(r["element"]) for r in box_store.select(selection_query(skill))}
    rows = box_store.select("SELECT ?e ?g WHERE { ?e props:globalIdIfcRoot_attribute_simple ?g }")
    guid = {literal_value(r["e"]): literal_value(r["g"]) for r in rows}
    walls = {s.global_id for s in GROUND if s.ifc_class == "IfcWall"}
    assert {guid[e] for e in got} == walls - {spec("Glass wall").global_id}


def test_a_raw_sparql_pattern_narrows_the_selection(box_store: GraphStore) -> None:
    skill = parse_skill("furniture", {"kind": "navigation", "sparql": "?element a furn:Furniture ."})
    assert len(box_store.select(selection_query(skill))) == 1


def test_a_user_config_overrides_and_adds_skills(tmp_path: Path) -> None:
    path = tmp_path / "site.toml"
    path.write_text('[site]\nname = "hq"\n[skills.tall]\nkind = "navigation"\nrobot_height_m = 2.0\n')
    cfg = load_config(path)
    assert cfg.site == "hq"
    assert cfg.skill("tall").robot_height_m == 2.0
    assert "localization" in cfg.skills
    with pytest.raises(SkillError, match="Unknown skill 'nope'"):
        cfg.skill("nope")


def test_a_bad_config_file_names_the_problem(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text("[skills.x]\nkind = 3\n")
    with pytest.raises(ConfigError, match="field 'kind'"):
        load_config(path)
    path.write_text("not toml ===")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(path)


def test_profiles_load_from_json_and_bad_json_is_named() -> None:
    skill = parse_skill_json("tall", b'{"kind": "navigation", "robot_height_m": 2.0}')
    assert skill.robot_height_m == 2.0
    with pytest.raises(SkillError, match="not valid JSON"):
        parse_skill_json("tall", b"{kind: navigation")
    with pytest.raises(SkillError, match="must be an object"):
        parse_skill_json("tall", b"[1, 2]")
    with pytest.raises(SkillError, match="64 KiB"):
        parse_skill_json("tall", b" " * 70000)


def test_a_user_pattern_cannot_undo_the_material_filter(box_store: GraphStore) -> None:
    skill = parse_skill(
        "sneaky",
        {
            "kind": "localization",
            "exclude_materials": ["glass"],
            "sparql": '?element twin:material ?material . FILTER(?material != "Steel")',
        },
    )
    rows = box_store.select("SELECT ?e ?g WHERE { ?e props:globalIdIfcRoot_attribute_simple ?g }")
    guid = {literal_value(r["e"]): literal_value(r["g"]) for r in rows}
    got = {guid[literal_value(r["element"])] for r in box_store.select(selection_query(skill))}
    assert spec("Glass wall").global_id not in got
    assert got


def test_remote_service_calls_are_rejected_in_profiles_and_queries(box_store: GraphStore) -> None:
    with pytest.raises(SkillError, match="SERVICE"):
        parse_skill("x", {"kind": "navigation", "sparql": "SERVICE <http://127.0.0.1:9/> { ?element ?p ?o }"})
    with pytest.raises(QueryError, match="SERVICE"):
        box_store.select("SELECT * WHERE { SERVICE <http://127.0.0.1:9/sparql> { ?s ?p ?o } }")


def test_deeply_nested_json_is_a_skill_error() -> None:
    with pytest.raises(SkillError, match="nested too deeply"):
        parse_skill_json("x", "[" * 60000)
