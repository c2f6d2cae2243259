"""Configuration: one schema per table, errors that name the table and key, defaults in one place,
and the sections through which adapters add their own tables (the core knows no transport)."""

from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path
from typing import ClassVar

import pytest
from pydantic import model_validator

from twin.config import DEFAULT_CONFIG, ConfigSection, Limits, config_schema, load_config
from twin.config.base import Flag, Whole
from twin.config.load import CORE_TABLES
from twin.errors import ConfigError


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "c.toml"
    path.write_text(text)
    return path


class Lights(ConfigSection):
    """A made-up adapter's table, to try the mechanism without any real transport."""

    table: ClassVar[str] = "lights"
    enabled: Flag = False
    channel: Whole = 3


class Archive(ConfigSection):
    """A made-up adapter that adds a key to the core's ``[store]`` table."""

    table: ClassVar[str] = "store"
    archive_every_s: Whole = 0


class Beacon(ConfigSection):
    """A made-up adapter that adds keys to every ``[robots.NAME]`` and reads the core's ``storey``."""

    table: ClassVar[str] = "robots"
    each: ClassVar[bool] = True
    beacon: Whole | None = None
    storey: str | None = None

    @model_validator(mode="after")
    def _placed(self) -> Beacon:
        if self.beacon is not None and self.storey is None:
            raise ValueError("a robot with a beacon needs 'storey'")
        return self


def test_the_store_is_flushed_every_minute_unless_configured(tmp_path: Path) -> None:
    assert load_config().store_flush_every_s == 60.0
    assert load_config(write(tmp_path, "[store]\nflush_every_s = 15\n")).store_flush_every_s == 15.0


@pytest.mark.parametrize(
    ("value", "problem"),
    [
        ("0", "expected a number >= 1.0, got 0"),
        ("-5", "expected a number >= 1.0, got -5"),
        ("7200", "expected a number <= 3600.0, got 7200"),
        ("true", "expected a number, got True"),
        ('"often"', "expected a number, got 'often'"),
    ],
)
def test_a_bad_flush_interval_is_refused_by_name(tmp_path: Path, value: str, problem: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(f"Configuration [store] flush_every_s: {problem}.")):
        load_config(write(tmp_path, f"[store]\nflush_every_s = {value}\n"))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[maps]\nmargin = 2", "[maps] margin: unknown key (did you mean margin_m?)"),
        ("[limits]\nbytes = 2", "[limits] bytes: unknown key (known: box_size_m, elements_per_observation"),
        ('[import]\nthreads = "2"', "[import] threads: expected an integer, got '2'"),
        ("[import]\nthreads = 2.0", "[import] threads: expected an integer, got 2.0"),
        (
            '[import]\nkernels = "manifold"',
            "[import] kernels: expected a list of geometry kernels, got 'manifold'",
        ),
        ('[import]\nkernels = ["occ"]', "[import] kernels[0]: expected 'manifold', 'opencascade', "),
        ("[import]\nkernels = []", "[import] kernels: expected at least 1 item(s)"),
        (
            '[import]\nstatic_types = ["Wall"]',
            "[import] static_types[0]: expected an IFC class name, got 'Wall'",
        ),
        ("[maps]\nmargin_m = nan", "[maps] margin_m: expected a finite number, got nan"),
        ('[site]\nname = "a/b"', "[site] name: expected a string matching ^[A-Za-z0-9_-]{1,64}$, got 'a/b'"),
        ("[limits]\npayload_bytes = 0", "[limits] payload_bytes: expected a number > 0, got 0"),
        (
            '[rights]\ndefault = ["fly"]',
            "[rights] default[0]: expected 'create', 'dynamic', 'doors', 'static'",
        ),
        ("maps = 3", "[maps]: expected a table, got 3"),
    ],
)
def test_a_bad_value_is_refused_naming_its_table_and_key(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(f"Configuration {message}")):
        load_config(write(tmp_path, text + "\n"))


def test_every_problem_of_a_file_is_named_at_once(tmp_path: Path) -> None:
    path = write(tmp_path, "[maps]\nmargin_m = -1\n[import]\nthreads = 0\n")
    with pytest.raises(ConfigError, match=r"\[import\] threads: .*; \[maps\] margin_m: "):
        load_config(path)


def test_a_skill_problem_names_the_skill_and_field(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"Configuration \[skills\]: Skill 'x': .*field 'kind'"):
        load_config(write(tmp_path, "[skills.x]\nkind = 3\n"))


def test_the_defaults_file_shows_the_schemas_defaults(tmp_path: Path) -> None:
    with DEFAULT_CONFIG.open("rb") as fh:
        shipped = tomllib.load(fh)
    for name, model in CORE_TABLES.items():
        written = {k: v for k, v in shipped[name].items() if k in model.model_fields}
        assert model.model_validate(written) == model(), name
    assert load_config().limits == Limits()


def test_without_sections_the_core_keeps_the_adapters_tables_as_written(tmp_path: Path) -> None:
    cfg = load_config(write(tmp_path, "[lights]\nchannel = 7\n[store]\narchive_every_s = 60\n"))
    assert cfg.tables["lights"] == {"channel": 7}
    assert cfg.section(Lights) == Lights(enabled=False, channel=7)  # parsed when asked for
    assert cfg.section(Archive).archive_every_s == 60


def test_a_section_asked_for_later_names_its_bad_key(tmp_path: Path) -> None:
    cfg = load_config(write(tmp_path, "[lights]\nchanel = 7\n"))
    with pytest.raises(ConfigError, match=re.escape("[lights] chanel: unknown key (did you mean channel?)")):
        cfg.section(Lights)


def test_with_sections_the_whole_file_is_checked_at_load(tmp_path: Path) -> None:
    defaults = tmp_path / "defaults.toml"
    defaults.write_text("[store]\npath = 'here'\n")  # no other adapter's table
    cfg = load_config(
        write(tmp_path, "[lights]\nenabled = true\n"), sections=[Lights, Archive], defaults=defaults
    )
    assert (cfg.section(Lights).enabled, cfg.section(Archive).archive_every_s, cfg.store_path) == (
        True,
        0,
        Path("here"),
    )
    message = "Configuration [lights] enabled: expected true or false, got 1."
    with pytest.raises(ConfigError, match=re.escape(message)):
        load_config(write(tmp_path, "[lights]\nenabled = 1\n"), sections=[Lights], defaults=defaults)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[lihgts]\nchannel = 1", "[lihgts]: unknown table (did you mean lights?)"),
        ("[store]\narchive_every = 1", "[store] archive_every: unknown key (did you mean archive_every_s?)"),
        ("[lights]\nchanel = 1", "[lights] chanel: unknown key (did you mean channel?)"),
    ],
)
def test_with_sections_an_unknown_table_or_key_is_refused(tmp_path: Path, text: str, message: str) -> None:
    defaults = tmp_path / "defaults.toml"
    defaults.write_text("")
    with pytest.raises(ConfigError, match=re.escape(message)):
        load_config(write(tmp_path, text), sections=[Lights, Archive], defaults=defaults)


def test_an_adapter_adds_keys_to_every_robot_the_core_keeps_its_own_and_checks_a_typo_only_with_sections(
    tmp_path: Path,
) -> None:
    defaults = tmp_path / "defaults.toml"
    defaults.write_text("")
    text = '[robots.r1]\nbeacon = 7\nstorey = "ground-floor"\n[robots.r2]\nbeacn = 1\nstorey = "roof"\n'
    alone = load_config(write(tmp_path, text), defaults=defaults)  # the core's keys only
    assert (alone.robots["r1"].storey, alone.robots["r2"].storey) == ("ground-floor", "roof")
    assert alone.each(Beacon)["r1"] == Beacon(beacon=7, storey="ground-floor")  # parsed when asked for
    assert alone.each(Beacon)["r2"] == Beacon(storey="roof")  # beacn: maybe another adapter's key
    with pytest.raises(TypeError, match=r"read it with Config.each"):
        alone.section(Beacon)
    message = "[robots.r2] beacn: unknown key (did you mean beacon?)"
    with pytest.raises(ConfigError, match=re.escape(message)):
        load_config(write(tmp_path, text), sections=[Beacon], defaults=defaults)
    checked = load_config(
        write(tmp_path, text.replace("beacn", "beacon")), sections=[Beacon], defaults=defaults
    )
    assert dict(checked.each(Beacon)) == {
        "r1": Beacon(beacon=7, storey="ground-floor"),
        "r2": Beacon(beacon=1, storey="roof"),
    }


def test_an_adapters_check_of_a_robot_names_the_robot_at_load_or_when_asked_for(tmp_path: Path) -> None:
    defaults = tmp_path / "defaults.toml"
    defaults.write_text("")
    path = write(tmp_path, "[robots.r1]\nbeacon = 7\n")
    message = "Configuration [robots.r1]: a robot with a beacon needs 'storey'."
    with pytest.raises(ConfigError, match=re.escape(message)):
        load_config(path, sections=[Beacon], defaults=defaults)
    with pytest.raises(ConfigError, match=re.escape(message)):
        load_config(path, defaults=defaults).each(Beacon)


def test_the_shipped_defaults_need_the_adapters_sections_to_load_strictly() -> None:
    with pytest.raises(ConfigError, match=re.escape("[zenoh]: unknown table")):
        load_config(sections=[Lights, Archive])  # the defaults' [zenoh] without the zenoh adapter's section


def test_the_json_schema_describes_every_table_and_refuses_unknown_ones() -> None:
    schema = config_schema([Lights, Archive])
    assert schema["additionalProperties"] is False
    assert {
        "site",
        "store",
        "import",
        "maps",
        "limits",
        "rights",
        "skills",
        "robots",
        "sources",
        "lights",
    } <= set(schema["properties"])
    skill = schema["properties"]["skills"]["additionalProperties"]
    assert (skill["required"], skill["additionalProperties"]) == (["kind"], False)
    assert {"lidar_height_m", "robot_height_m", "exclude_materials", "sparql"} <= set(skill["properties"])
    store = schema["$defs"][schema["properties"]["store"]["$ref"].split("/")[-1]]
    assert {"path", "flush_every_s", "snapshot", "snapshot_every_s", "archive_every_s"} == set(
        store["properties"]
    )
    assert store["properties"]["flush_every_s"] == {
        "default": 60.0,
        "description": "How often 'twin serve' flushes the embedded store's write buffers, seconds.",
        "maximum": 3600.0,
        "minimum": 1.0,
        "title": "Flush Every S",
        "type": "number",
    }


def test_a_file_that_is_not_toml_or_not_there_is_named(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(write(tmp_path, "not toml ==="))
    with pytest.raises(ConfigError, match=r"No configuration file at .*nope.toml"):
        load_config(tmp_path / "nope.toml")


def test_the_site_counts_as_chosen_only_when_a_configuration_file_names_it(tmp_path: Path) -> None:
    assert load_config().site == "lab"
    assert not load_config().site_set
    other = tmp_path / "other.toml"
    other.write_text("[store]\nflush_every_s = 15\n")
    assert not load_config(other).site_set
    named = tmp_path / "named.toml"
    named.write_text('[site]\nname = "north"\n')
    assert (load_config(named).site, load_config(named).site_set) == ("north", True)


def test_the_snapshot_is_on_and_rewritten_every_five_minutes_unless_configured(tmp_path: Path) -> None:
    cfg = load_config()
    assert cfg.store_snapshot and cfg.store_snapshot_every_s == 300.0
    cfg = load_config(write(tmp_path, "[store]\nsnapshot = false\nsnapshot_every_s = 60\n"))
    assert not cfg.store_snapshot and cfg.store_snapshot_every_s == 60.0


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("snapshot = 1", "[store] snapshot: expected true or false, got 1."),
        ("snapshot_every_s = 0", "[store] snapshot_every_s:"),
    ],
)
def test_a_bad_snapshot_setting_is_refused_by_name(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(message)):
        load_config(write(tmp_path, f"[store]\n{text}\n"))


def test_fusion_values_per_ifc_class_override_the_defaults_for_that_class_and_its_subtypes(
    tmp_path: Path,
) -> None:
    path = tmp_path / "fusion.toml"
    path.write_text(
        "[fusion]\nconfirm_angle_deg = 20.0\n[fusion.classes.IfcFurniture]\nconfirm_distance_m = 0.05\n"
    )
    rules = load_config(path).fusion
    chair = rules.of(("IfcChair", "IfcFurniture", "IfcFurnishingElement"))
    assert chair.confirm_distance_m == 0.05
    assert chair.confirm_angle_rad == pytest.approx(math.radians(20.0))  # not overridden: the table's
    assert rules.of(("IfcWall",)).confirm_distance_m == 0.15
