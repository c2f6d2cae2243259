"""``[robots.NAME.detections]`` and ``[sources.NAME]``: what ROS 2 robots and the building's Open-RMF
systems report, configured, and the errors that name the key."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from adapters.cli.config_cmd import load
from adapters.ros.settings import ros_robots, ros_sources
from twin.config.load import Config
from twin.errors import ConfigError

ROBOT = '[robots.r1]\nnamespace = "/r1"\nstorey = "ground-floor"\n'


def config(tmp_path: Path, text: str) -> Config:
    path = tmp_path / "c.toml"
    path.write_text(text)
    return load(path)


def test_a_robots_detections_table_gives_its_topic_class_table_camera_and_tf(tmp_path: Path) -> None:
    cfg = config(
        tmp_path,
        ROBOT + '[robots.r1.detections]\nclasses = { table = "IfcFurniture" }\nfov_deg = 87\n'
        'sensor_frame = "cam_optical"\nz_reference = "building"\n',
    )
    d = ros_robots(cfg)["r1"].detections
    assert d is not None
    assert (d.topic, d.classes, d.fov_deg, d.sensor_frame, d.z_reference) == (
        "detections", (("table", "IfcFurniture"),), 87.0, "cam_optical", "building"
    )  # fmt: skip
    assert (d.tf, d.tf_static, d.min_score, d.view_skill) == ("tf", "tf_static", 0.5, "localization")


@pytest.mark.parametrize(
    ("table", "match"),
    [
        ('classes = { table = "Furniture" }', "an IFC class name"),
        ("classes = {}", "classes"),
        ('classes = { t = "IfcFurniture" }\nmin_score = 1.5', "min_score"),
        ('classes = { t = "IfcFurniture" }\nview_skill = "nope"', "unknown skill 'nope'"),
        ('classes = { t = "IfcFurniture" }\ntopic = "map"', "clash"),
        ('classes = { t = "IfcFurniture" }\ntopic = "a b"', "ROS topic name"),
        ('classes = { t = "IfcFurniture" }\nheights_m = [0.5, 0.1]', r"low <= high.*\[0.5, 0.1\]"),
        ('classes = { t = "IfcFurniture" }\nheights_m = 0.5', "two heights"),
        ('classes = { t = "IfcFurniture" }\noptical = "yes"', "optical"),
        ('classes = { t = "IfcFurniture" }\ncamera_info = "storey"', "clash"),
    ],
)
def test_a_bad_detections_table_is_refused_naming_the_key(tmp_path: Path, table: str, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        config(tmp_path, ROBOT + "[robots.r1.detections]\n" + table + "\n")


def test_the_camera_s_axis_fields_of_view_blind_zone_and_band_are_configured(tmp_path: Path) -> None:
    d = ros_robots(config(tmp_path, ROBOT + '[robots.r1.detections]\nclasses = { t = "IfcFurniture" }\n'))[
        "r1"
    ].detections
    assert d is not None
    assert (d.optical, d.vfov_deg, d.near_m, d.heights_m, d.camera_info) == (
        False,
        None,
        0.0,
        (0.1, 0.5),
        None,
    )
    d = ros_robots(
        config(
            tmp_path,
            ROBOT
            + '[robots.r1.detections]\nclasses = { t = "IfcFurniture" }\noptical = true\nvfov_deg = 58\n'
            'near_m = 0.3\nheights_m = [0.2, 0.8]\ncamera_info = "camera/camera_info"\n',
        )
    )["r1"].detections
    assert d is not None
    assert (d.optical, d.vfov_deg, d.near_m, d.heights_m, d.camera_info) == (
        True, 58.0, 0.3, (0.2, 0.8), "camera/camera_info"
    )  # fmt: skip


def test_detections_without_a_namespace_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="needs the robot's 'namespace'"):
        config(tmp_path, '[robots.r1.detections]\nclasses = { t = "IfcFurniture" }\n')


def test_sources_are_identities_of_their_own_with_default_rights_per_kind(tmp_path: Path) -> None:
    cfg = config(
        tmp_path,
        '[sources.doors]\nkind = "rmf_doors"\ndoors = { main = "Door 1" }\n'
        '[sources.obst]\nkind = "rmf_obstacles"\nclasses = { human = "IfcBuildingElementProxy" }\n'
        'levels.L1 = { storey = "ground-floor", x = 1.5, yaw_deg = 90 }\n',
    )
    doors, obst = ros_sources(cfg)["doors"], ros_sources(cfg)["obst"]
    assert (doors.topic, doors.namespace, doors.doors) == ("door_states", "/", (("main", "Door 1"),))
    assert cfg.rights_of("doors") == frozenset({"doors"})
    assert cfg.rights_of("obst") == frozenset({"create", "dynamic"})
    ((name, level),) = obst.levels
    assert name == "L1" and level.storey == "ground-floor" and level.x == 1.5
    assert level.yaw_rad == pytest.approx(math.pi / 2)
    assert "doors" not in cfg.robots


def test_a_source_named_like_a_robot_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"\[sources.r1\]: a robot has that name too"):
        config(tmp_path, ROBOT + '[sources.r1]\nkind = "rmf_doors"\n')


def test_an_unknown_source_kind_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="kind"):
        config(tmp_path, '[sources.s]\nkind = "rmf_lifts"\n')


def test_absolute_tf_topics_are_kept_for_robots_that_publish_the_global_tf(tmp_path: Path) -> None:
    cfg = config(tmp_path, ROBOT + '[robots.r1.detections]\nclasses = { t = "IfcFurniture" }\ntf = "/tf"\n')
    d = ros_robots(cfg)["r1"].detections
    assert d is not None and (d.tf, d.tf_static) == ("/tf", "tf_static")


def test_a_class_id_may_carry_a_descriptive_type_and_a_bad_one_is_refused_naming_it(tmp_path: Path) -> None:
    cfg = config(
        tmp_path,
        ROBOT + '[robots.r1.detections]\nclasses = { table = "IfcFurniture", '
        'chair = { ifc = "IfcFurniture", type = "furn:Chair" } }\n',
    )
    d = ros_robots(cfg)["r1"].detections
    assert d is not None
    assert d.classes == (("table", "IfcFurniture"), ("chair", "IfcFurniture"))
    assert d.types == (("chair", "http://pi.pauwel.be/voc/furniture#Chair"),)
    with pytest.raises(ConfigError, match=r"furn:Chair or beo:Door.*'Chair'"):
        config(
            tmp_path,
            ROBOT + '[robots.r1.detections]\nclasses = { c = { ifc = "IfcFurniture", type = "Chair" } }\n',
        )
