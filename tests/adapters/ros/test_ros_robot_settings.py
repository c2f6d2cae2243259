"""The ROS 2 keys of ``[robots.NAME]`` (``adapters/ros/settings.py``): a namespaced robot's topics ->
skills, the old single ``skill``, and the errors, as ``twin`` loads them (the core's tables and every
adapter's section) and as an adapter reads them from a file the core loaded alone."""

from __future__ import annotations

from pathlib import Path

import pytest

from adapters.cli.config_cmd import load
from adapters.ros.settings import DEFAULT_ROBOT_MAPS, RosRobot, ros_robots
from twin.config import RobotConfig, load_config
from twin.errors import ConfigError


def robots(tmp_path: Path, text: str) -> dict[str, RosRobot]:
    path = tmp_path / "robots.toml"
    path.write_text(text)
    return ros_robots(load(path))


def test_a_namespaced_robot_without_topics_gets_localization_on_map_and_navigation_on_navigation_map(
    tmp_path: Path,
) -> None:
    (robot,) = robots(tmp_path, '[robots.r1]\nnamespace = "/r1"\nstorey = "ground-floor"\n').values()
    assert robot.maps == DEFAULT_ROBOT_MAPS == (("map", "localization"), ("navigation_map", "navigation"))
    assert robot.skills == ("localization", "navigation")


def test_maps_pair_topics_under_the_namespace_with_skills_in_the_order_written(tmp_path: Path) -> None:
    text = (
        '[robots.r1]\nnamespace = "r1/"\nstorey = "ground-floor"\n'
        '[robots.r1.maps]\nmap = "lab-localization"\n"costmap/static" = "lab-navigation"\n'
    )
    robot = robots(tmp_path, text)["r1"]
    assert robot.namespace == "/r1"
    assert robot.maps == (("map", "lab-localization"), ("costmap/static", "lab-navigation"))


def test_the_old_single_skill_key_means_that_skill_on_map(tmp_path: Path) -> None:
    text = '[robots.r1]\nnamespace = "/r1"\nskill = "lab-navigation"\nstorey = "ground-floor"\n'
    assert robots(tmp_path, text)["r1"].maps == (("map", "lab-navigation"),)


@pytest.mark.parametrize(
    ("table", "error"),
    [
        ('skill = "navigation"\nmaps = { map = "navigation" }', "both 'skill' and 'maps'"),
        ('maps = { map = "flying" }', r"\[robots.r1\] maps: topic 'map' names unknown skill 'flying'"),
        ('skill = "flying"', r"\[robots.r1\] skill: topic 'map' names unknown skill 'flying'"),
        ("maps = {}", r"\[robots.r1\] maps: must map topic names to skills"),
        ('maps = { "/abs" = "navigation" }', r"\[robots.r1\] maps: topic '/abs' must be a relative ROS"),
        ('maps = { storey = "navigation" }', r"\[robots.r1\] maps: topic 'storey' is taken"),
        ('maps = { map_updates = "navigation" }', r"\[robots.r1\] maps: topic 'map_updates' is taken"),
        ("domain_id = 233", r"\[robots.r1\] domain_id: expected a number <= 232, got 233"),
        ('ros = ["dds"]', r"\[robots.r1\] ros\[0\]: expected 'bridge' or 'rmw_zenoh', got 'dds'"),
        ('namespace_ = "/r1"', r"\[robots.r1\] namespace_: unknown key \(did you mean namespace\?\)"),
    ],
)
def test_a_bad_topic_table_is_refused_naming_the_key(tmp_path: Path, table: str, error: str) -> None:
    with pytest.raises(ConfigError, match=error):
        robots(tmp_path, f'[robots.r1]\nnamespace = "/r1"\nstorey = "ground-floor"\n{table}\n')


def test_a_namespaced_robot_needs_the_storey_it_starts_on(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"\[robots.r1\]: a robot with a namespace needs 'storey'"):
        robots(tmp_path, '[robots.r1]\nnamespace = "/r1"\n')


def test_a_robot_name_that_cannot_be_a_key_expression_chunk_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"\[robots\] name 'a b': expected a string matching"):
        robots(tmp_path, '[robots."a b"]\n')


def test_a_robot_without_namespace_has_no_topics(tmp_path: Path) -> None:
    robot = robots(tmp_path, "[robots.r1]\n")["r1"]
    assert (robot.maps, robot.storey, robot.namespace) == ((), None, None)


def test_a_robot_without_namespace_keeps_its_starting_storey_on_both_sides(tmp_path: Path) -> None:
    path = tmp_path / "robots.toml"
    path.write_text('[robots.r2]\nstorey = "ground-floor"\n')
    cfg = load(path)
    # the writer starts r2 there, and its storey key over Zenoh answers the same
    assert cfg.robots["r2"].storey == ros_robots(cfg)["r2"].storey == "ground-floor"
    assert ros_robots(cfg)["r2"].maps == ()


def test_full_every_s_names_topics_of_the_robot_with_seconds(tmp_path: Path) -> None:
    text = '[robots.r1]\nnamespace = "/r1"\nstorey = "ground-floor"\n[robots.r1.full_every_s]\nmap = 10\n'
    assert robots(tmp_path, text)["r1"].full_every_s == (("map", 10.0),)
    assert (
        robots(tmp_path, '[robots.r2]\nnamespace = "/r2"\nstorey = "ground-floor"\n')["r2"].full_every_s == ()
    )


@pytest.mark.parametrize(
    ("table", "error"),
    [
        (
            "[robots.r1.full_every_s]\nmapp = 10\n",
            "'mapp', not a map topic of this robot (its topics: map, navigation_map",
        ),
        ("[robots.r1.full_every_s]\nmap = 0\n", "full_every_s"),
        ('[robots.r1.full_every_s]\nmap = "often"\n', "full_every_s"),
    ],
)
def test_a_bad_full_every_s_is_refused_naming_the_topic_or_value(
    tmp_path: Path, table: str, error: str
) -> None:
    with pytest.raises(ConfigError, match="full_every_s") as err:
        robots(tmp_path, f'[robots.r1]\nnamespace = "/r1"\nstorey = "ground-floor"\n{table}')
    assert error in str(err.value)


def test_full_every_s_of_a_robot_without_a_namespace_says_it_needs_one_not_that_map_is_unknown(
    tmp_path: Path,
) -> None:
    with pytest.raises(ConfigError, match="full_every_s") as err:
        robots(tmp_path, "[robots.robot1.full_every_s]\nmap = 10.0\n")
    text = str(err.value)
    assert "not a map topic" not in text
    assert 'this robot has none without a namespace: add namespace = "/<robot>"' in text


def test_the_core_alone_keeps_a_robots_name_rights_and_storey_and_the_ros_side_reads_the_rest(
    tmp_path: Path,
) -> None:
    path = tmp_path / "robots.toml"
    path.write_text('[robots.r1]\nnamespace = "/r1"\nstorey = "ground-floor"\nrights = ["create"]\n')
    cfg = load_config(path)  # no sections: the core's tests and tools
    assert cfg.robots == {"r1": RobotConfig("r1", frozenset({"create"}), "ground-floor")}
    assert ros_robots(cfg) == ros_robots(load(path))
    assert ros_robots(cfg)["r1"].namespace == "/r1"


def test_a_bad_ros_key_in_a_file_the_core_loaded_alone_is_refused_when_the_adapter_reads_it(
    tmp_path: Path,
) -> None:
    path = tmp_path / "robots.toml"
    path.write_text('[robots.r1]\nnamespace = "/r1"\nstorey = "ground-floor"\ndomain_id = 233\n')
    cfg = load_config(path)
    with pytest.raises(ConfigError, match=r"\[robots.r1\] domain_id: expected a number <= 232, got 233"):
        ros_robots(cfg)


def test_a_typo_in_any_robot_key_is_refused_at_load_naming_the_robot_and_key(tmp_path: Path) -> None:
    path = tmp_path / "robots.toml"
    path.write_text('[robots.r1]\nrigths = ["create"]\n')
    with pytest.raises(ConfigError, match=r"\[robots.r1\] rigths: unknown key \(did you mean rights\?\)"):
        load(path)


def test_robot_defaults_give_every_robot_its_detections_settings_and_a_robot_overrides_a_key(
    tmp_path: Path,
) -> None:
    text = (
        '[robot_defaults]\nstorey = "ground-floor"\n'
        '[robot_defaults.detections]\nclasses = { table = "IfcFurniture" }\nrange_m = 6.0\noptical = true\n'
        + "".join(f'[robots.r{i}]\nnamespace = "/r{i}"\n' for i in range(25))
        + '[robots.r3.detections]\nrange_m = 3.0\n'
    )
    fleet = robots(tmp_path, text)
    assert len(fleet) == 25
    assert all(r.detections is not None and dict(r.detections.classes) == {"table": "IfcFurniture"}
               for r in fleet.values())  # fmt: skip
    ranges = {name: r.detections.range_m for name, r in fleet.items() if r.detections is not None}
    assert ranges["r3"] == 3.0 and ranges["r0"] == ranges["r24"] == 6.0
    assert fleet["r3"].detections is not None and fleet["r3"].detections.optical  # the rest of the defaults


def test_robot_defaults_that_are_no_table_are_refused_by_name(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"\[robot_defaults\]: expected a table"):
        robots(tmp_path, 'robot_defaults = 3\n[robots.r1]\nnamespace = "/r1"\nstorey = "ground-floor"\n')
