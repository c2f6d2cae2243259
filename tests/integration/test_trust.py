"""Association you can trust, with the daemon as a process and robots as processes (issue 36 cases 1,
3 and 4): a chair under the imported table never replaces it, a reused tracker id never moves it, and a
robot whose clock is 1.5 s behind never gets a chair removed that it keeps seeing."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from adapters.ros.interfaces import DETECTION_3D_ARRAY, TF_MESSAGE
from adapters.zenoh.client import TwinClient
from tests.adapters.ros_reports import OPTICAL, Det, Tf, cdr_detections, cdr_tf
from tests.integration.conftest import ROOT, Daemon, lines_until, start_daemon, twin
from tests.integration.test_fleet import cell
from tests.integration.test_ros_ingest import Publisher, counts, wait_until
from tests.integration.test_ros_ingest import config as ros_config
from twin.maps.grid import OCCUPIED

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

TABLE_XY = (12.0, 8.0)  # the sample lab's imported table (1.2 x 0.8, IfcFurnishingElement) in the world


def observe(d: Daemon, robot: str, iri: str, box: str) -> dict[str, object]:
    r = twin(
        "observe", "--connect", d.endpoint, "--robot", robot, "--id", iri, "--box", box,
        "--class", "IfcFurniture", "--storey", "ground-floor", timeout=60,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    ack: dict[str, object] = json.loads(r.stdout[r.stdout.index("{") :])
    return ack


def table_iri(client: TwinClient) -> str:
    rows = client.sparql('SELECT ?e WHERE { ?e twin:ifcClass "IfcFurnishingElement" }')["results"]["bindings"]
    assert len(rows) == 1, rows
    return str(rows[0]["e"]["value"])


def test_a_chair_under_the_imported_table_and_a_reused_tracker_id_never_move_or_resize_the_table(
    daemon: Daemon,
) -> None:
    with TwinClient.connect([daemon.endpoint]) as client:
        table = table_iri(client)
        revision = client.status()["revision"]
        for _ in range(2):  # case 1: a 0.55 m chair tucked under the table (smaller, inside it)
            ack = observe(daemon, "robot1", "urn:robot1:det:3", "12.3,8.0,0.45,0.55,0.55,0.9,0")
            assert ack["resolved"] == {"urn:robot1:det:3": table} and ack["unchanged"], ack
        assert client.status()["revision"] == revision and cell(client, 11.5, 8.0) == OCCUPIED
        # case 3: a tracker id resolves to the table, then (the detector restarted) is a chair elsewhere
        first = observe(daemon, "robot2", "urn:robot2:det:3", "12.0,8.0,0.375,1.2,0.8,0.75,0")
        assert first["resolved"] == {"urn:robot2:det:3": table}
        chair = observe(daemon, "robot2", "urn:robot2:det:3", "16.6,7.0,0.45,0.5,0.5,0.9,0")
        assert chair["upserted"] == ["urn:robot2:det:3"] and "resolved" not in chair
        assert cell(client, *TABLE_XY) == OCCUPIED and cell(client, 11.5, 8.0) == OCCUPIED
        assert cell(client, 16.6, 7.0) == OCCUPIED


def test_a_robot_whose_clock_is_1_5_s_behind_keeps_the_chair_it_sees_in_another_robots_views(
    fresh_store: Path,
) -> None:
    d = start_daemon(fresh_store, "--no-record")
    try:

        def robot(name: str, offset: str, count: str, kind: str) -> subprocess.Popen[str]:
            args = [
                sys.executable,
                "-m",
                "tests.integration.clock_robot",
                d.endpoint,
                name,
                offset,
                count,
                kind,
            ]
            return subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=ROOT)

        chair = robot("robot1", "-1.5", "0", "chair")  # until its stdin closes
        # robot1's clock offset is known ([fusion] clock_settle_s) before robot2 looks: the daemon says so
        settled = lines_until(d, lambda line: "Robot 'robot1''s clock is off" in line, 120.0)
        assert settled and "clock is off" in settled[-1], settled[-20:]
        view = robot("robot2", "0", "30", "view")
        looked = json.loads(view.communicate(timeout=120)[0].splitlines()[-1])
        saw = json.loads(chair.communicate(timeout=60)[0].splitlines()[-1])  # its stdin closed: it ends
        assert saw["sent"] > 1 and saw["stale"] == saw["refused"] == 0 and looked["sent"] == 30, (saw, looked)
        with TwinClient.connect([d.endpoint]) as client:
            rows = client.sparql("SELECT ?r WHERE { <urn:robot1:chair> twin:removed ?r }")
            assert not rows["results"]["bindings"], "the chair robot1 kept seeing was removed"
            offsets = client.status()["fusion"]["clock_offsets"]
            assert 1.4 < offsets["robot1"] < 2.0 and abs(offsets["robot2"]) < 0.5, offsets
    finally:
        d.stop()


def test_via_ros_a_restarted_detectors_reused_id_is_a_new_object_and_a_daemon_restart_keeps_the_session(
    fresh_store: Path, tmp_path: Path
) -> None:
    path = tmp_path / "robots.toml"
    path.write_text(ros_config("rmw_zenoh"))
    d = start_daemon(fresh_store, "--no-record", config=path)
    try:
        robot = Publisher(d, "rmw_zenoh")

        def see(stamp: int, det: Det) -> None:
            robot.send(
                "/robot1/tf",
                TF_MESSAGE,
                cdr_tf(
                    [
                        Tf("map", "base_link", (13.0, 7.0, 0.0), stamp_ns=stamp - 10**8),
                        Tf("map", "base_link", (15.0, 7.0, 0.0), stamp_ns=stamp + 10**8),
                    ]
                ),
            )
            robot.send(
                "/robot1/detections", DETECTION_3D_ARRAY, cdr_detections(stamp, "camera_optical_frame", [det])
            )

        camera = [
            Tf("base_link", "camera_link", (0.2, 0.0, 1.0)),
            Tf("camera_link", "camera_optical_frame", (0, 0, 0), OPTICAL),
        ]
        robot.send("/robot1/tf_static", TF_MESSAGE, cdr_tf(camera), latched=True)
        table = Det((("table", 0.9),), (0.0, 0.625, 2.4), (0.6, 0.6, 0.75), (0.5, -0.5, 0.5, 0.5), id="3")
        chair = Det((("table", 0.9),), (0.0, 0.55, 3.4), (0.5, 0.5, 0.9), (0.5, -0.5, 0.5, 0.5), id="3")
        with TwinClient.connect([d.endpoint]) as client:
            see(time.time_ns() - 11 * 10**9, table)  # track 3: a table at (16.6, 7.0)
            wait_until(client, lambda s: counts(s, "robot1")["accepted"] == 1)
            see(time.time_ns(), chair)  # 11 s later, the detector restarted: its track 3 is a chair
            status = wait_until(client, lambda s: counts(s, "robot1")["accepted"] == 2)
            sessions = status["ros_ingest"]["tracker_sessions"]["robot1"]
            assert sessions["restarts"] == 1, sessions
            assert cell(client, 16.6, 7.0) == OCCUPIED and cell(client, 17.6, 7.0) == OCCUPIED
            rows = client.sparql('SELECT ?e WHERE { ?e twin:ifcClass "IfcFurniture" }')["results"]["bindings"]
            assert len(rows) == 2, rows
        robot.close_stdin_and_wait()
        assert d.stop()[0] == 0
        d = start_daemon(fresh_store, "--no-record", config=path)  # the same tracker, a new daemon
        robot = Publisher(d, "rmw_zenoh")
        robot.send("/robot1/tf_static", TF_MESSAGE, cdr_tf(camera), latched=True)
        with TwinClient.connect([d.endpoint]) as client:
            see(time.time_ns(), chair)
            status = wait_until(client, lambda s: counts(s, "robot1")["unchanged"] == 1)
            assert status["ros_ingest"]["tracker_sessions"]["robot1"] == {
                "session": sessions["session"],
                "restarts": 0,
            }
        robot.close_stdin_and_wait()
    finally:
        d.stop()
