"""The daemon as users run it: a real process on loopback, robots and subscribers as other processes."""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from adapters.zenoh.client import TwinClient
from adapters.zenoh.errors import RemoteError
from tests.integration.conftest import Daemon, JsonLinesProcess, start_daemon, twin
from tests.integration.settled import settled, settled_map
from twin.maps.grid import OCCUPIED

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

TWIN = "https://w3id.org/building-twin#"
TABLE_BOX = "16.6,7.0,0.375,0.6,0.6,0.75,0.0"  # in the corridor, east of the arch
TABLE = "urn:twin:robot1:table-1"


def observe(d: Daemon, *args: str) -> subprocess.CompletedProcess[str]:
    return twin("observe", "--connect", d.endpoint, "--robot", "robot1", *args, timeout=60)


def door_of(client: TwinClient) -> str:
    rows = client.sparql('SELECT ?door WHERE { ?door twin:ifcClass "IfcDoor" } LIMIT 1')
    assert isinstance(rows, dict)
    return str(rows["results"]["bindings"][0]["door"]["value"])


def _box_turtle(*, box: str = "16.6 7.0 0.375 0.6 0.6 0.75 0.0", storey: str = "ground-floor") -> str:
    return f'<{TABLE}> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "{storey}" ; <{TWIN}box> "{box}" .'


class Subscriber(JsonLinesProcess):
    """The subscriber process: its JSON lines, and the final copies it writes when told to stop."""

    def __init__(self, d: Daemon, out: Path, *skills: str) -> None:
        super().__init__("tests.integration.subscriber", d.endpoint, str(out), "ground-floor", *skills)
        self.out = out
        while "ready" not in self.next():  # a version may come first: the watches start before "ready"
            pass

    def until(self, skill: str, version: int) -> None:
        while not any(ln.get("skill") == skill and ln.get("version") == version for ln in self.lines):
            self.next()

    def finish(self) -> dict[str, np.ndarray]:
        self.close_stdin_and_wait()
        return {p.stem.split("__")[1]: np.load(p) for p in self.out.glob("*.npy")}


def test_a_table_reaches_the_navigation_map_by_an_update_and_its_removal_restores_the_map(
    daemon: Daemon, tmp_path: Path
) -> None:
    with TwinClient.connect([daemon.endpoint]) as client:
        nav0, _, v0 = client.get_map("ground-floor", "navigation")
        loc0, _, _ = client.get_map("ground-floor", "localization")
    sub = Subscriber(daemon, tmp_path, "navigation", "localization")
    sub.until("navigation", v0)

    r = observe(
        daemon, "--box", TABLE_BOX, "--class", "IfcFurniture", "--storey", "ground-floor", "--id", TABLE
    )
    assert r.returncode == 0, r.stderr + r.stdout
    ack = json.loads(r.stdout)
    assert ack["ok"] and ack["revision"] == 1 and ack["upserted"] == [TABLE]
    changed = {(m["storey"], m["skill"]) for m in ack["maps"]}
    assert ("ground-floor", "navigation") in changed and ("ground-floor", "localization") not in changed
    sub.until("navigation", v0 + 1)
    first = next(ln for ln in sub.lines if ln.get("skill") == "navigation" and ln.get("version") == v0 + 1)
    assert first["via"] == "update"  # the changed rectangle arrives before the full map

    with TwinClient.connect([daemon.endpoint]) as client:
        nav1, rev1, v1 = settled(client, revision=ack["revision"])
        loc1, _, _ = client.get_map("ground-floor", "localization")
    assert rev1 == 1 and v1 == v0 + 1
    diff = np.argwhere(nav1.data != nav0.data)
    m = ack["maps"][[(x["storey"], x["skill"]) for x in ack["maps"]].index(("ground-floor", "navigation"))]
    assert len(diff)
    assert (diff[:, 1] >= m["x"]).all() and (diff[:, 1] < m["x"] + m["width"]).all()
    assert (diff[:, 0] >= m["y"]).all() and (diff[:, 0] < m["y"] + m["height"]).all()
    assert m["width"] * 0.05 < 1.0 and m["height"] * 0.05 < 1.0  # only the 0.6 m table's footprint
    assert (nav1.data[diff[:, 0], diff[:, 1]] == OCCUPIED).all()
    np.testing.assert_array_equal(loc1.data, loc0.data)

    r = observe(daemon, "--remove", TABLE)
    assert r.returncode == 0, r.stderr
    sub.until("navigation", v0 + 2)
    copies = sub.finish()
    np.testing.assert_array_equal(copies["navigation"], nav0.data)  # bit for bit, from the updates
    np.testing.assert_array_equal(copies["localization"], loc0.data)


def test_opening_the_door_frees_its_cells_in_navigation_maps(daemon: Daemon) -> None:
    with TwinClient.connect([daemon.endpoint]) as client:
        before, _, _ = client.get_map("ground-floor", "navigation")
        door = door_of(client)
        ack = client.observe("robot1", f"<{door}> <{TWIN}isOpen> true .")
        assert ack["ok"]
        after = settled_map(client, revision=ack["revision"])
    freed = (before.data == OCCUPIED) & (after.data != OCCUPIED)
    assert freed.sum() > 10
    assert not ((after.data == OCCUPIED) & (before.data != OCCUPIED)).any()


def test_a_late_subscriber_gets_the_current_map_by_get_and_by_history(daemon: Daemon, tmp_path: Path) -> None:
    r = observe(daemon, "--box", TABLE_BOX, "--class", "IfcFurniture", "--storey", "ground-floor")
    assert r.returncode == 0, r.stderr
    with TwinClient.connect([daemon.endpoint]) as client:
        current, revision, version = settled(client, revision=1)
        assert revision == 1 and version == 2
        with client.watch("ground-floor", "navigation") as watcher:
            got = watcher.wait_for(lambda v: v.version == version, timeout_s=10)
    np.testing.assert_array_equal(got.grid.data, current.data)
    assert got.via == "map"


@pytest.mark.parametrize(
    ("turtle", "message"),
    [
        (b"not turtle at all", "not valid Turtle"),
        (f'<{TABLE}> <{TWIN}colour> "red" .'.encode(), "unknown term"),
        (
            _box_turtle(box="NaN 1 1 1 1 1 0").encode(),
            "NaN",
        ),
        (
            _box_turtle(box="16 7 1 900 1 1 0").encode(),
            "box size",
        ),
        (
            _box_turtle(storey="attic").encode(),
            "unknown storey",
        ),
    ],
)
def test_malformed_observations_get_an_error_reply_and_change_nothing(
    daemon: Daemon, tmp_path: Path, turtle: bytes, message: str
) -> None:
    path = tmp_path / "bad.ttl"
    path.write_bytes(turtle)
    r = observe(daemon, "--turtle", str(path))
    assert r.returncode == 1
    assert message in json.loads(r.stdout)["error"]
    with TwinClient.connect([daemon.endpoint]) as client:
        assert client.status()["revision"] == 0


def test_hostile_input_on_both_paths_leaves_the_daemon_serving(daemon: Daemon) -> None:
    with TwinClient.connect([daemon.endpoint]) as client:
        wall = client.sparql(
            'SELECT ?w WHERE { ?w twin:ifcClass ?c . FILTER(STRSTARTS(?c, "IfcWall")) } LIMIT 1'
        )
        assert isinstance(wall, dict)
        iri = wall["results"]["bindings"][0]["w"]["value"]
        with pytest.raises(RemoteError, match="lacks the 'static' right"):
            client.observe("robot1", f"<{iri}> <{TWIN}removed> true .")
        with pytest.raises(RemoteError, match="more than the 1,048,576 allowed"):
            client.observe("robot1", b"#" * (1 << 21))
        client.publish_observation("robot2", b"\xff\xfe garbage")
        client.publish_observation("robot2", f"<{iri}> <{TWIN}removed> true .")
        deadline = time.monotonic() + 10
        while client.status()["observations"]["rejected"] < 4 and time.monotonic() < deadline:
            time.sleep(0.1)
        status = client.status()
        assert status["observations"] == {"accepted": 0, "unchanged": 0, "rejected": 4}
        assert status["revision"] == 0
        assert client.observe("robot1", _box_turtle())["ok"]
    code, _ = daemon.stop()
    assert code == 0
    assert any("Rejected an observation by robot2" in line for line in daemon.log)  # best effort: logged


def test_skills_come_and_go_at_run_time(daemon: Daemon) -> None:
    with TwinClient.connect([daemon.endpoint]) as client:
        client.put_skill(
            "tall-robot", {"kind": "navigation", "robot_height_m": 2.2, "inflation_radius_m": 0.2}
        )
        deadline = time.monotonic() + 10
        while ("ground-floor", "tall-robot") not in client.list_maps() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert "tall-robot" in client.skills()
        grid, _, version = client.get_map("ground-floor", "tall-robot")
        assert version == 1 and (grid.data == OCCUPIED).any()
        client.delete_skill("tall-robot")
        while ("ground-floor", "tall-robot") in client.list_maps() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert ("ground-floor", "tall-robot") not in client.list_maps()
        assert "tall-robot" not in client.skills()


def test_sparql_is_read_only_and_status_reports_the_twin(daemon: Daemon) -> None:
    with TwinClient.connect([daemon.endpoint]) as client:
        with pytest.raises(RemoteError, match="read-only"):
            client.sparql("INSERT DATA { <urn:a> <urn:b> <urn:c> }")
        graph = client.sparql("CONSTRUCT { ?s a bot:Storey } WHERE { ?s a bot:Storey }")
        assert not isinstance(graph, dict) and len(graph) == 2  # an rdflib.Graph of the two storeys
        status = client.status()
        assert status["revision"] == 0 and len(status["maps"]) == 8 and status["queue_depth"] == 0
        assert client.daemon_alive()


def test_sigterm_stops_the_daemon_cleanly_within_two_seconds(daemon: Daemon) -> None:
    code, seconds = daemon.stop()
    assert code == 0, "\n".join(daemon.log)
    assert seconds < 2.0
    assert any("stopped cleanly" in line for line in daemon.log)


def test_serve_imports_an_ifc_file_into_an_empty_store_first(tmp_path: Path) -> None:
    assert twin("sample", "lab", tmp_path / "lab.ifc").returncode == 0
    d = start_daemon(tmp_path / "store", "--ifc", str(tmp_path / "lab.ifc"), "--no-record")
    try:
        with TwinClient.connect([d.endpoint]) as client:
            assert ("ground-floor", "navigation") in client.list_maps()
    finally:
        assert d.stop()[0] == 0


def test_serve_without_a_store_is_a_one_line_error(tmp_path: Path) -> None:
    r = twin("serve", "--store", tmp_path / "nothing", "--listen", "tcp/127.0.0.1:1", "--no-record")
    assert r.returncode == 1
    assert "No store at" in r.stderr and "twin import" in r.stderr
    assert "Traceback" not in r.stderr


def test_a_re_confirmation_from_another_process_is_acked_unchanged_and_publishes_nothing(
    daemon: Daemon, tmp_path: Path
) -> None:
    with TwinClient.connect([daemon.endpoint]) as client:
        first = client.observe("robot1", _box_turtle())
        assert first["ok"] and first["revision"] == 1 and "unchanged" not in first
        _, _, version = settled(client, revision=1)
        sub = Subscriber(daemon, tmp_path, "navigation")
        sub.until("navigation", version)
        for _ in range(10):
            again = client.observe("robot1", _box_turtle(box="16.6004 7.0 0.375 0.6 0.6 0.75 0.00005"))
            assert again == {
                "ok": True,
                "revision": 1,
                "unchanged": True,
                "upserted": [],
                "removed": [],
                "maps": [],
            }
        time.sleep(0.5)  # what a re-confirmation wrongly published would have reached the subscriber
        status = client.status()
        assert status["revision"] == 1
        assert status["observations"] == {"accepted": 1, "unchanged": 10, "rejected": 0}
        moved = client.observe("robot1", _box_turtle(box="16.0 7.0 0.375 0.6 0.6 0.75 0.0"))
        assert moved["revision"] == 2
    sub.until("navigation", version + 1)  # the move is the next version: nothing came in between
    versions = [
        ln["version"] for ln in sub.lines if ln.get("skill") == "navigation" and ln.get("via") == "update"
    ]
    assert versions == [version + 1]
    sub.finish()


def test_twin_explain_names_an_observed_table_with_its_robot_and_a_glass_wall_a_lidar_does_not_see(
    daemon: Daemon,
) -> None:
    box = ["--box", "16.6,7.0,0.375,1.2,0.8,0.75,0", "--class", "IfcFurniture", "--storey", "ground-floor"]
    r = twin("observe", "--connect", daemon.endpoint, "--robot", "robot7", "--id", "urn:robot7:table", *box)
    assert r.returncode == 0, r.stderr
    revision = json.loads(r.stdout)["revision"]
    r = twin("explain", "--connect", daemon.endpoint, "--storey", "ground-floor", "--skill", "navigation",
             "--at", "16.6,7.0")  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "occupied (100)" in r.stdout
    assert "IfcFurniture <urn:robot7:table>, observed by robot7 at 20" in r.stdout
    assert f"(revision {revision})" in r.stdout
    with TwinClient.connect([daemon.endpoint]) as client:
        lidar = client.explain("ground-floor", "localization", 21.95, 7.0)  # inside the glass wall
        with pytest.raises(RemoteError, match="No map ground-floor/flying"):
            client.explain("ground-floor", "flying", 21.95, 7.0)
    assert lidar["state"] == "free"
    glass = next(e for e in lidar["near"] if e["name"] == "Glass wall")
    assert glass["why_not"].startswith("made of glass") and glass["global_id"]
