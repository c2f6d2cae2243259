"""Access control and transport security: the daemon as a process with zenoh's ACL, user/password
authentication, TLS and mutual TLS; robots as zenoh sessions that authenticate (or try to cheat)."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import zenoh

from adapters.ros.pcd import POINT_CLOUD2, decode_point_cloud2
from adapters.ros.rmw_zenoh import RosTopic
from adapters.zenoh.client import TwinClient
from adapters.zenoh.errors import DaemonTimeoutError, TransportError
from adapters.zenoh.latched import declare_latched_subscriber
from adapters.zenoh.settings import AuthSettings, TlsSettings, ZenohSettings
from tests.integration.certs import CertificateAuthority
from tests.integration.conftest import Daemon, lines_until, start_daemon

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

TWIN = "https://w3id.org/building-twin#"
LAB = "twin/lab"  # under access control a robot sees only its site's keys: no discovery, the site is given
MAP = "twin/lab/map/ground-floor/lab-navigation"
UPDATES = "twin/lab/map_updates/ground-floor/lab-navigation"
ROBOTS = {"robot1": "pw-robot1", "robot2": "pw-robot2", "operator": "pw-operator"}


def table(iri: str, x: float = 16.6) -> str:
    return (
        f'<{iri}> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "ground-floor" ; '
        f'<{TWIN}box> "{x} 7.0 0.375 0.6 0.6 0.75 0.0" .'
    )


def exists(client: TwinClient, iri: str) -> bool:
    answer = client.sparql(f"ASK {{ <{iri}> ?p ?o }}")
    assert isinstance(answer, dict)
    return bool(answer["boolean"])


def stopped(d: Daemon) -> None:
    d.stop_cleanly()


# --- user/password identities and the ACL ------------------------------------------------------------
@pytest.fixture(scope="module")
def secrets(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("secrets")
    (root / "users.txt").write_text("".join(f"{u}:{p}\n" for u, p in ROBOTS.items()))
    for user, password in ROBOTS.items():
        (root / f"{user}.password").write_text(password + "\n")
    (root / "wrong.password").write_text("not-the-password\n")
    return root


def as_robot(d: Daemon, secrets: Path, user: str, *, password: str | None = None) -> TwinClient:
    """A robot's client; its requests wait as long as a loaded machine needs (a denied one ends at once)."""
    auth = AuthSettings(user=user, password_file=secrets / f"{password or user}.password")
    return TwinClient.connect(
        [d.endpoint], settings=ZenohSettings(auth=auth), mode="client", timeout_s=30.0, prefix=LAB
    )


@pytest.fixture(scope="module")
def guarded(lab_store_dir: Path, secrets: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Daemon]:
    """The lab's daemon with access control: robot1 and robot2 are robots, operator is an operator."""
    import shutil

    root = tmp_path_factory.mktemp("guarded")
    shutil.copytree(lab_store_dir, root / "store")
    config = root / "site.toml"
    config.write_text(
        f'[zenoh.auth]\nusers_file = "{secrets / "users.txt"}"\n'
        '[zenoh.access]\nenabled = true\noperators = ["operator"]\n'
        "[robots.robot1]\n[robots.robot2]\n"
    )
    d = start_daemon(root / "store", "--no-record", config=config)
    yield d
    stopped(d)


def test_a_robot_observes_under_its_own_name_but_not_under_another_robots(
    guarded: Daemon, secrets: Path
) -> None:
    with as_robot(guarded, secrets, "robot1") as robot1:
        ack = robot1.observe("robot1", table("urn:test:own-table"))
        assert ack["ok"] and exists(robot1, "urn:test:own-table")
        t0 = time.monotonic()
        with pytest.raises(DaemonTimeoutError):
            robot1.observe("robot2", table("urn:test:stolen-table", x=18.0))
        assert time.monotonic() - t0 < 15.0, "a denied query should end at once, not by its 30 s timeout"
        robot1.publish_observation("robot2", table("urn:test:stolen-put", x=19.0))
        time.sleep(0.5)
        assert not exists(robot1, "urn:test:stolen-table")
        assert not exists(robot1, "urn:test:stolen-put")
        assert robot1.status()["revision"] == ack["revision"]


def _collect(session: zenoh.Session, key: str) -> tuple[list[bytes], zenoh.Subscriber[None]]:
    got: list[bytes] = []
    lock = threading.Lock()

    def on(sample: zenoh.Sample) -> None:
        with lock:
            got.append(sample.payload.to_bytes())

    return got, session.declare_subscriber(key, on)


def test_the_serving_line_says_that_access_control_is_on_and_for_whom(guarded: Daemon) -> None:
    serving = next(line for line in guarded.log if line.startswith("serving site"))
    assert ", access control on for twin/lab/** (robots and operators: " in serving
    assert "robot1" in serving and "operator" in serving


def test_no_robot_or_operator_can_publish_a_map_or_an_update(guarded: Daemon, secrets: Path) -> None:
    with as_robot(guarded, secrets, "robot1") as robot1:
        maps, sub_maps = _collect(robot1.session, MAP)
        updates, sub_updates = _collect(robot1.session, UPDATES)
        grid0, revision0, version0 = robot1.get_map("ground-floor", "lab-navigation")
        for forger in ("robot2", "operator"):
            with as_robot(guarded, secrets, forger) as other:
                time.sleep(0.3)
                other.session.put(MAP, b"forged map")
                other.session.put(UPDATES, b"forged update")
                time.sleep(0.5)
        # the control: the daemon's own update does reach robot1 on the same subscribers
        robot1.observe("robot1", table("urn:test:after-forgery", x=14.0))
        deadline = time.monotonic() + 5
        while not updates and time.monotonic() < deadline:
            time.sleep(0.05)
        sub_maps.undeclare()
        sub_updates.undeclare()
        assert updates, "the daemon's update never arrived"
        assert b"forged map" not in maps and b"forged update" not in updates
        grid, revision, version = robot1.get_map("ground-floor", "lab-navigation")
        while version == version0 and time.monotonic() < deadline:  # a get answers the current map
            grid, revision, version = robot1.get_map("ground-floor", "lab-navigation")
        assert version > version0 and revision > revision0 and grid.data.shape == grid0.data.shape


def test_skills_are_changed_by_operators_and_not_by_robots(guarded: Daemon, secrets: Path) -> None:
    profile = {"kind": "navigation", "robot_height_m": 0.8, "resolution_m": 0.1}
    with as_robot(guarded, secrets, "robot1") as robot1, as_robot(guarded, secrets, "operator") as operator:
        robot1.put_skill("robot-made", profile)
        operator.put_skill("operator-made", profile)
        deadline = time.monotonic() + 10
        while "operator-made" not in robot1.skills() and time.monotonic() < deadline:
            time.sleep(0.1)
        skills = robot1.skills()
        assert "operator-made" in skills
        assert "robot-made" not in skills


REFUSED = r"^Cannot open a Zenoh session to .*: .* accepted the connection but refused the Zenoh session:"


def test_a_wrong_password_or_an_unknown_robot_cannot_connect(guarded: Daemon, secrets: Path) -> None:
    with pytest.raises(TransportError, match=REFUSED + r" check the user and password \(\[zenoh.auth\]\)"):
        as_robot(guarded, secrets, "robot1", password="wrong")
    (secrets / "intruder.password").write_text("guess\n")
    with pytest.raises(TransportError, match=REFUSED):
        as_robot(guarded, secrets, "intruder")


def test_a_peer_without_credentials_is_told_at_once_that_its_session_was_refused(guarded: Daemon) -> None:
    t0 = time.monotonic()
    with pytest.raises(TransportError, match=r"refused the Zenoh session: check whether it requires"):
        TwinClient.connect([guarded.endpoint], timeout_s=60.0)  # peer mode, no site: finds the daemon
    assert time.monotonic() - t0 < 30.0  # told once the probe says why, not after the 60 s timeout


def test_the_daemon_logs_a_session_it_refused(guarded: Daemon, secrets: Path) -> None:
    with pytest.raises(TransportError):
        as_robot(guarded, secrets, "robot2", password="wrong")
    seen = lines_until(guarded, lambda line: "Invalid password" in line)
    assert any("Invalid password" in line for line in seen), seen


def test_a_port_where_nothing_listens_is_told_apart_from_a_refused_session() -> None:
    from tests.integration.conftest import free_port

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with pytest.raises(TransportError, match=rf"nothing listens at {endpoint} \(connection refused\)"):
        TwinClient.connect([endpoint], mode="client", prefix=LAB)


def test_without_access_control_a_clients_forged_map_would_reach_other_robots(daemon: Daemon) -> None:
    """The reason for the ACL: the daemon routes its clients' puts to each other."""
    with (
        TwinClient.connect([daemon.endpoint], mode="client", prefix=LAB) as robot1,
        TwinClient.connect([daemon.endpoint], mode="client", prefix=LAB) as robot2,
    ):
        maps, sub = _collect(robot1.session, "twin/lab/map/ground-floor/navigation")
        time.sleep(0.3)
        robot2.session.put("twin/lab/map/ground-floor/navigation", b"forged map")
        deadline = time.monotonic() + 5
        while b"forged map" not in maps and time.monotonic() < deadline:
            time.sleep(0.05)
        sub.undeclare()
        assert b"forged map" in maps


# --- TLS and mutual TLS --------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> CertificateAuthority:
    ca = CertificateAuthority.create(tmp_path_factory.mktemp("pki"), "building-twin test CA")
    for name in ("daemon", "robot1", "robot2"):
        ca.issue(name)
    return ca


def tls_settings(
    ca: CertificateAuthority, name: str | None = None, *, root: Path | None = None
) -> ZenohSettings:
    cert = key = None
    if name is not None:
        cert, key = ca.directory / f"{name}.pem", ca.directory / f"{name}.key"
    return ZenohSettings(tls=TlsSettings(root_ca=root or ca.path, certificate=cert, private_key=key))


def tls_daemon(
    store_dir: Path,
    root: Path,
    ca: CertificateAuthority,
    *,
    mutual: bool,
    extra: str = "[robots.robot1]\n[robots.robot2]\n",
) -> Daemon:
    import shutil

    shutil.copytree(store_dir, root / "store")
    config = root / "site.toml"
    text = (
        f'[zenoh.tls]\nroot_ca = "{ca.path}"\ncertificate = "{ca.directory / "daemon.pem"}"\n'
        f'private_key = "{ca.directory / "daemon.key"}"\nmutual = {json.dumps(mutual)}\n'
    )
    if mutual:
        text += '[zenoh.access]\nenabled = true\nidentity = "certificate"\n' + extra
    config.write_text(text)
    return start_daemon(root / "store", "--no-record", config=config, scheme="tls")


def test_robots_reach_the_daemon_over_tls_and_a_foreign_authority_is_refused(
    lab_store_dir: Path, pki: CertificateAuthority, tmp_path: Path
) -> None:
    d = tls_daemon(lab_store_dir, tmp_path, pki, mutual=False)
    try:
        assert d.endpoint.startswith("tls/")
        with TwinClient.connect([d.endpoint], settings=tls_settings(pki), mode="client", prefix=LAB) as robot:
            assert robot.observe("robot1", table("urn:test:tls-table"))["ok"]
        other = CertificateAuthority.create(tmp_path / "other", "someone else's CA")
        with pytest.raises(TransportError, match=REFUSED + r" check the certificates"):
            TwinClient.connect([d.endpoint], settings=tls_settings(pki, root=other.path), mode="client")
        plain = d.endpoint.replace("tls/", "tcp/")
        with pytest.raises(TransportError, match="Cannot open a Zenoh session"):
            TwinClient.connect([plain], mode="client")
    finally:
        stopped(d)


def test_with_mutual_tls_a_robot_is_its_certificate(
    lab_store_dir: Path, pki: CertificateAuthority, tmp_path: Path
) -> None:
    d = tls_daemon(lab_store_dir, tmp_path, pki, mutual=True)
    try:
        with TwinClient.connect(
            [d.endpoint], settings=tls_settings(pki, "robot1"), mode="client", timeout_s=30.0, prefix=LAB
        ) as robot1:
            assert robot1.observe("robot1", table("urn:test:mtls-table"))["ok"]
            robot1.timeout_s = 3.0  # denied: no answer
            with pytest.raises(DaemonTimeoutError):
                robot1.observe("robot2", table("urn:test:mtls-stolen", x=18.0))
            robot1.timeout_s = 30.0
            assert exists(robot1, "urn:test:mtls-table")
            assert not exists(robot1, "urn:test:mtls-stolen")
        with pytest.raises(TransportError, match="Cannot open a Zenoh session"):
            TwinClient.connect([d.endpoint], settings=tls_settings(pki), mode="client")  # no certificate
    finally:
        stopped(d)


# --- point clouds under the same rules as maps ---------------------------------------------------------
CLOUD = "twin/lab/points/ground-floor/lidar3d"
CLOUDS_SITE = """
[skills.lidar3d]
kind = "points"
resolution_m = 0.25
[robots.robot1]
namespace = "/robot1"
storey = "ground-floor"
ros = ["bridge", "rmw_zenoh"]
[robots.robot2]
"""


@pytest.fixture(scope="module")
def clouds(
    lab_store_dir: Path, pki: CertificateAuthority, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[Daemon]:
    """The lab's daemon with mutual TLS and access control by certificate, a points skill and a ROS robot;
    ``stranger`` holds a certificate of the same authority but is no robot of the site."""
    pki.issue("stranger")
    root = tmp_path_factory.mktemp("clouds")
    d = tls_daemon(lab_store_dir, root, pki, mutual=True, extra=CLOUDS_SITE)
    yield d
    stopped(d)


def as_certified(d: Daemon, ca: CertificateAuthority, name: str, timeout_s: float = 30.0) -> TwinClient:
    return TwinClient.connect(
        [d.endpoint], settings=tls_settings(ca, name), mode="client", timeout_s=timeout_s, prefix=LAB
    )


def _wait(got: list[bytes], n: int = 1, timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while len(got) < n and time.monotonic() < deadline:
        time.sleep(0.05)


def test_a_robot_reads_the_clouds_as_it_reads_maps_and_a_stranger_reads_neither(
    clouds: Daemon, pki: CertificateAuthority
) -> None:
    ros = RosTopic(0, "/robot1", "points_map", POINT_CLOUD2)
    with as_certified(clouds, pki, "robot1") as robot1:
        latched: dict[str, list[bytes]] = {CLOUD: [], ros.bridge_key: [], ros.data_key: []}
        subs = [
            declare_latched_subscriber(
                robot1.session, key, lambda s, got=got: got.append(s.payload.to_bytes())
            )
            for key, got in latched.items()
        ]
        for got in latched.values():
            _wait(got)
        for s in subs:
            s.undeclare()
        xyz, revision, version = robot1.get_points("ground-floor", "lidar3d")  # a get, as for a map
        assert len(xyz) > 1000 and version >= 1 and revision >= 0
        for key, got in latched.items():  # late joiners on the native key and both ROS 2 layouts
            assert got, f"robot1 got no cloud on {key}"
            np.testing.assert_array_equal(decode_point_cloud2(got[0])[0], xyz)
    with as_certified(clouds, pki, "stranger", timeout_s=1.5) as stranger:
        for get in (lambda: stranger.get_map("ground-floor", "lab-navigation"),
                    lambda: stranger.get_points("ground-floor", "lidar3d")):  # fmt: skip
            with pytest.raises(DaemonTimeoutError):
                get()
        got: list[bytes] = []
        sub = declare_latched_subscriber(stranger.session, CLOUD, lambda s: got.append(s.payload.to_bytes()))
        time.sleep(1.0)  # robot1's arrived within a fraction of that
        sub.undeclare()
        assert not got


def test_no_robot_publishes_a_cloud_on_the_sites_key_or_a_robots_points_map(
    clouds: Daemon, pki: CertificateAuthority
) -> None:
    ros = RosTopic(0, "/robot1", "points_map", POINT_CLOUD2)
    with as_certified(clouds, pki, "robot1") as robot1:
        native, sub_native = _collect(robot1.session, CLOUD)
        bridge, sub_bridge = _collect(robot1.session, ros.bridge_key)
        with as_certified(clouds, pki, "robot2") as robot2:
            time.sleep(0.3)
            robot2.session.put(CLOUD, b"forged cloud")
            robot2.session.put(ros.bridge_key, b"forged cloud")
            time.sleep(0.5)
        # the control: the daemon's own next cloud reaches robot1 on the same subscribers
        door = robot1.sparql('SELECT ?door WHERE { ?door twin:ifcClass "IfcDoor" } LIMIT 1')
        assert isinstance(door, dict)
        iri = door["results"]["bindings"][0]["door"]["value"]
        assert robot1.observe("robot1", f"<{iri}> <{TWIN}isOpen> true .")["ok"]
        _wait(native)
        _wait(bridge)
        sub_native.undeclare()
        sub_bridge.undeclare()
        assert native and bridge, "the daemon's next cloud never arrived"
        assert b"forged cloud" not in native + bridge
