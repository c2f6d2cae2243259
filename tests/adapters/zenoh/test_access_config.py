"""The access-control section and the security settings, as configured (no network)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from adapters.cli.app import main
from adapters.cli.config_cmd import load
from adapters.zenoh.access import access_control, site_access_control
from adapters.zenoh.errors import TransportError
from adapters.zenoh.keys import SiteKeys
from adapters.zenoh.session import session_config
from adapters.zenoh.settings import ZenohSettings
from twin.errors import ConfigError


def config(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "site.toml"
    path.write_text(text)
    return path


def test_each_robot_may_write_only_its_own_observation_keys() -> None:
    acl = access_control(SiteKeys("twin/lab"), ["robot1", "robot2"])
    rules = {r["id"]: r for r in acl["rules"]}
    assert rules["write-robot1"]["key_exprs"] == [
        "twin/lab/observations/robot1",
        "twin/lab/observe/robot1",
        "twin/lab/robots/robot1/storey",
    ]
    policies = {tuple(p["subjects"]): p["rules"] for p in acl["policies"]}
    assert "write-robot2" not in policies[("robot-robot1",)]
    assert "operate" not in policies[("robot-robot1",)]
    assert all("no-forged-maps" in rules_ for rules_ in policies.values())
    assert acl["default_permission"] == "deny"
    assert {s["id"]: s["usernames"] for s in acl["subjects"]} == {
        "robot-robot1": ["robot1"],
        "robot-robot2": ["robot2"],
    }


def test_certificate_identity_names_subjects_by_common_name() -> None:
    acl = access_control(SiteKeys("twin/lab"), ["robot1"], identity="certificate", operators=["ops"])
    assert {s["id"]: s["cert_common_names"] for s in acl["subjects"]} == {
        "robot-robot1": ["robot1"],
        "operator-ops": ["ops"],
    }


def test_access_control_with_nobody_to_let_in_is_an_error() -> None:
    with pytest.raises(TransportError, match="at least one robot"):
        access_control(SiteKeys("twin/lab"), [])


def test_access_by_user_name_without_a_users_file_is_refused(tmp_path: Path) -> None:
    cfg = load(config(tmp_path, "[zenoh.access]\nenabled = true\n[robots.robot1]\n"))
    with pytest.raises(TransportError, match="users_file"):
        site_access_control(cfg, SiteKeys("twin/lab"))


def test_access_by_certificate_without_mutual_tls_is_refused(tmp_path: Path) -> None:
    cfg = load(config(tmp_path, '[zenoh.access]\nenabled = true\nidentity = "certificate"\n[robots.r1]\n'))
    with pytest.raises(TransportError, match="mutual TLS"):
        site_access_control(cfg, SiteKeys("twin/lab"))


def test_access_control_is_off_unless_enabled(tmp_path: Path) -> None:
    assert site_access_control(load(), SiteKeys("twin/lab")) is None


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ('[zenoh.access]\nidentity = "fingerprint"\n', "[zenoh.access] identity: expected 'username' or"),
        ('[zenoh.tls]\ncertificate = "a.pem"\n', "[zenoh.tls]: needs both 'certificate' and 'private_key'"),
        ('[zenoh.auth]\nuser = "robot1"\n', "[zenoh.auth]: needs both 'user' and 'password_file'"),
        ("[zenoh.tls]\nmutual = 1\n", "[zenoh.tls] mutual: expected true or false, got 1"),
        ('[zenoh.tls]\nca = "x"\n', "[zenoh.tls] ca: unknown key"),
        ('[zenoh.access]\noperators = ["a b"]\n', "[zenoh.access] operators[0]: expected a string matching"),
    ],
)
def test_bad_security_settings_are_named(tmp_path: Path, text: str, words: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(words)):
        load(config(tmp_path, text))


def test_a_missing_certificate_file_is_named(tmp_path: Path) -> None:
    cfg = load(config(tmp_path, f'[zenoh.tls]\nroot_ca = "{tmp_path / "nope.pem"}"\n'))
    with pytest.raises(
        TransportError, match=r"certificate authority \(zenoh.tls.root_ca\) .*nope.pem does not exist"
    ):
        session_config(cfg.section(ZenohSettings))


def test_a_ros_robot_reads_every_map_topic_and_alone_publishes_its_own_storey_topic(tmp_path: Path) -> None:
    users = tmp_path / "users.txt"
    users.write_text("r1:a\nr2:b\n")
    text = (
        f'[zenoh.auth]\nusers_file = "{users}"\n[zenoh.access]\nenabled = true\n'
        '[robots.r1]\nnamespace = "/r1"\nstorey = "ground-floor"\nros = ["bridge", "rmw_zenoh"]\n'
        '[robots.r2]\nnamespace = "/r2"\nstorey = "ground-floor"\nros = ["bridge"]\n'
    )
    acl = site_access_control(load(config(tmp_path, text)), SiteKeys("twin/lab"))
    assert acl is not None
    rules = {r["id"]: r for r in acl["rules"]}
    reads = rules["read"]["key_exprs"]
    for key in ("r1/navigation_map", "r1/navigation_map_updates", "0/r1/map/**", "r2/map_updates"):
        assert key in reads and f"{key}/@adv/**" in reads
    assert rules["publish-r1"]["key_exprs"] == ["r1/storey", "r1/storey/@adv/**", "0/r1/storey/**",
                                                "0/r1/storey/**/@adv/**"]  # fmt: skip
    assert rules["publish-r2"]["key_exprs"] == ["r2/storey", "r2/storey/@adv/**"]
    policies = {tuple(p["subjects"]): p["rules"] for p in acl["policies"]}
    assert "publish-r1" in policies[("robot-r1",)] and "publish-r1" not in policies[("robot-r2",)]
    assert "twin/lab/robots/r2/storey" not in rules["write-r1"]["key_exprs"]


def test_a_robot_alone_publishes_its_detections_and_tf_and_a_source_alone_its_rmf_topic(
    tmp_path: Path,
) -> None:
    users = tmp_path / "users.txt"
    users.write_text("r1:a\ndoors:b\n")
    text = (
        f'[zenoh.auth]\nusers_file = "{users}"\n[zenoh.access]\nenabled = true\n'
        '[robots.r1]\nnamespace = "/r1"\nstorey = "ground-floor"\nros = ["bridge"]\n'
        '[robots.r1.detections]\nclasses = { table = "IfcFurniture" }\ntf_static = "/tf_static"\n'
        '[sources.doors]\nkind = "rmf_doors"\nros = ["rmw_zenoh"]\ndiagnostics = true\n'
    )
    acl = site_access_control(load(config(tmp_path, text)), SiteKeys("twin/lab"))
    assert acl is not None
    rules = {r["id"]: r for r in acl["rules"]}
    assert {"r1/detections", "r1/tf", "tf_static"} <= set(
        rules["publish-r1"]["key_exprs"]
    )  # "/tf_static": global
    assert rules["publish-doors"]["key_exprs"] == ["0/door_states/**", "0/door_states/**/@adv/**"]
    assert "0/diagnostics/**" in rules["read"]["key_exprs"]  # the daemon's DiagnosticArray, readable
    assert "0/diagnostics/**" in rules["from-daemon"]["key_exprs"]
    policies = {tuple(p["subjects"]): p["rules"] for p in acl["policies"]}
    assert "publish-doors" not in policies[("robot-r1",)] and "publish-r1" not in policies[("robot-doors",)]


def test_point_clouds_and_their_ros_topics_are_read_and_guarded_as_maps_are(tmp_path: Path) -> None:
    users = tmp_path / "users.txt"
    users.write_text("r1:a\n")
    text = (
        f'[zenoh.auth]\nusers_file = "{users}"\n[zenoh.access]\nenabled = true\n'
        '[robots.r1]\nnamespace = "/r1"\nstorey = "ground-floor"\nros = ["bridge", "rmw_zenoh"]\n'
        '[skills.lidar3d]\nkind = "points"\n[skills.lidar-far]\nkind = "points"\nresolution_m = 0.2\n'
    )
    acl = site_access_control(load(config(tmp_path, text)), SiteKeys("twin/lab"))
    assert acl is not None
    rules = {r["id"]: r for r in acl["rules"]}
    clouds = (
        "twin/lab/points/**",
        "r1/points_map_lidar3d",
        "r1/points_map_lidar_far",
        "0/r1/points_map_lidar3d/**",
    )
    for key in clouds:
        for rule in ("read", "no-forged-maps"):
            assert key in rules[rule]["key_exprs"], (key, rule)
        assert key.startswith("twin/lab/") or key in rules["from-daemon"]["key_exprs"]  # site keys: all
        adv = f"{key}/@adv/**"
        assert adv in rules["read"]["key_exprs"] and adv in rules["tokens"]["key_exprs"]
    assert not any("points_map" in key for key in rules["publish-r1"]["key_exprs"])


def test_twin_acl_prints_exactly_the_access_control_the_daemon_applies(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    users = tmp_path / "users.txt"
    users.write_text("r1:a\nr2:b\ndoors:c\nops:d\n")
    path = config(
        tmp_path,
        f'[zenoh.auth]\nusers_file = "{users}"\n[zenoh.access]\nenabled = true\noperators = ["ops"]\n'
        '[robots.r1]\nnamespace = "/r1"\nstorey = "ground-floor"\nros = ["bridge", "rmw_zenoh"]\n'
        '[robots.r1.detections]\nclasses = { table = "IfcFurniture" }\ndiagnostics = true\n'
        '[robots.r2]\nnamespace = "/r2"\nstorey = "ground-floor"\nros = ["bridge"]\n'
        '[sources.doors]\nkind = "rmf_doors"\nros = ["rmw_zenoh"]\ndiagnostics = true\n'
        '[skills.lidar3d]\nkind = "points"\n',
    )
    assert main(["acl", "--config", str(path), "--site", "lab"]) == 0
    printed = json.loads(capsys.readouterr().out)["access_control"]
    cfg = load(path)
    assert printed == site_access_control(cfg, SiteKeys("twin/lab"))  # `twin serve`, `twin router --acl`
    rules = {r["id"]: r for r in printed["rules"]}
    assert {"r1/storey", "r1/detections", "r2/storey"} <= {
        key for rule in ("publish-r1", "publish-r2") for key in rules[rule]["key_exprs"]
    }  # each robot's own /<ns>/storey and detections
    assert "0/door_states/**" in rules["publish-doors"]["key_exprs"]  # the [sources.doors] identity
    assert "r1/diagnostics" in rules["from-daemon"]["key_exprs"]
    assert {s["id"] for s in printed["subjects"]} == {"robot-r1", "robot-r2", "robot-doors", "operator-ops"}
