"""The ingestion in one process with a real Zenoh session (its own puts reach its own subscribers):
a robot's TF and detections on the bridge keys become one observation whose view is cut by the
structure map the ingestion follows as a sink (the fusion terms on), and its counts are in the
status. ``submit`` is a plain function that keeps the documents and acks them. The robots' messages are
translated in a worker process (``[ros] ingest_workers``) or in the ingest thread (0 workers)."""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pyoxigraph as ox
import pytest
import zenoh
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.serialization import deserialize_message

from adapters.zenoh.ros_ingest import RosIngest
from adapters.zenoh.session import client_config
from tests.adapters.ros_reports import OPTICAL, Det, Tf, cdr_detections, cdr_tf
from twin.config import load_config
from twin.live.events import MapPublished, MapUpdated, TwinStarted
from twin.live.requests import Reply, ReplyFn
from twin.maps.grid import GridFrame, OccupancyGrid, Window

TWIN = "https://w3id.org/building-twin#"
FRAME = GridFrame(10.0, 2.0, 0.05, 200, 200)  # x 10..20, y 2..12


@pytest.fixture(params=[1, 0], ids=["one worker process", "in the ingest thread"])
def ingest(
    tmp_path: Path, request: pytest.FixtureRequest
) -> Iterator[tuple[RosIngest, zenoh.Session, list[bytes]]]:
    path = tmp_path / "c.toml"
    path.write_text(
        '[robots.robot1]\nnamespace = "/robot1"\nstorey = "ground-floor"\nros = ["bridge"]\n'
        '[robots.robot1.detections]\nclasses = { table = "IfcFurniture" }\nrange_m = 8.0\n'
        "diagnostics = true\noptical = true\n"
    )
    docs: list[bytes] = []

    def submit(owner: str, document: bytes, reply: ReplyFn, received_ns: int | None = None) -> None:
        assert owner == "robot1"
        docs.append(document)
        reply(Reply(True, {"ok": True, "unchanged": len(docs) > 1}))

    with zenoh.open(client_config([])) as session:
        ing = RosIngest(
            session,
            load_config(path),
            submit,
            storey_of=lambda _: "ground-floor",
            fusion_terms=True,
            typed=False,  # Turtle: the test reads the documents
            workers=request.param,
        )
        ing.emit(TwinStarted("lab", 0, 0, (("ground-floor", "Ground floor", 0.0),), (), {}))
        data = np.zeros((FRAME.height, FRAME.width), dtype=np.int8)
        data[:, 120] = 100  # a wall at x = 16.0 .. 16.05
        ing.emit(MapPublished(OccupancyGrid(FRAME, data, "ground-floor", "localization", 0.0), 0, 1, 0))
        yield ing, session, docs
        ing.close()


def view_xs(document: bytes) -> np.ndarray:
    (polygon,) = [
        q.object.value
        for q in ox.parse(document, format=ox.RdfFormat.TURTLE)
        if q.predicate.value == TWIN + "polygon"
    ]
    return np.array(polygon.split(), dtype=float).reshape(-1, 2)[:, 0]


def send_array(session: zenoh.Session, stamp: int) -> None:
    session.put("robot1/tf", cdr_tf([Tf("map", "base_link", (12.0, 7.0, 0.0), stamp_ns=stamp)]))
    table = Det((("table", 0.9),), (0.0, 0.625, 2.4), (0.6, 0.6, 0.75), (0.5, -0.5, 0.5, 0.5), id="7")
    session.put("robot1/detections", cdr_detections(stamp, "camera_optical_frame", [table]))


def wait(test: object, timeout_s: float = 30.0) -> None:
    """Until ``test()`` holds; the deadline only bounds a failure (a worker starts slowly under load)."""
    deadline = time.monotonic() + timeout_s
    while not test():  # type: ignore[operator]
        assert time.monotonic() < deadline
        time.sleep(0.02)


def test_the_view_stops_at_the_structure_and_follows_its_map_updates(
    ingest: tuple[RosIngest, zenoh.Session, list[bytes]],
) -> None:
    ing, session, docs = ingest
    session.put(
        "robot1/tf_static",
        cdr_tf(
            [
                Tf("base_link", "camera_link", (0.2, 0, 1.0)),
                Tf("camera_link", "camera_optical_frame", (0, 0, 0), OPTICAL),
            ]
        ),
    )
    stamp = time.time_ns()
    send_array(session, stamp)
    wait(lambda: len(docs) == 1)
    session_label = f"s{stamp // 10**9}".encode()  # the tracker session: the first array's stamp
    assert b"<urn:twin-ros:robot1:det:" + session_label + b":7> twin:ifcClass" in docs[0]
    xs = view_xs(docs[0])
    assert xs[0] == pytest.approx(12.2) and xs.max() <= 16.0 and xs.max() > 15.9  # cut at the wall
    cleared = np.zeros((FRAME.height, 10), dtype=np.int8)  # the wall's column and its neighbours: free
    ing.emit(
        MapUpdated("ground-floor", "localization", FRAME, Window(0, 115, FRAME.height, 125), cleared, 1, 2, 0)
    )
    send_array(session, stamp + 10**8)
    wait(lambda: len(docs) == 2)
    assert view_xs(docs[1]).max() > 19.9  # on to the map's edge at x = 20 (nothing is known beyond it)
    wait(lambda: ing.status()["ros_ingest"]["counts"]["robot1"]["unchanged"] == 1)  # type: ignore[index]
    counts = ing.status()["ros_ingest"]["counts"]["robot1"]  # type: ignore[index]
    assert counts["accepted"] == 1 and counts["messages"] == {"detections": 2, "tf": 2, "tf_static": 1}


def test_a_diagnostic_array_with_the_counts_is_published_and_warns_after_a_refusal(
    ingest: tuple[RosIngest, zenoh.Session, list[bytes]],
) -> None:
    _, session, _ = ingest
    got: list[DiagnosticArray] = []
    sub = session.declare_subscriber(
        "robot1/diagnostics", lambda s: got.append(deserialize_message(s.payload.to_bytes(), DiagnosticArray))
    )
    session.put("robot1/detections", b"\x00\x01\x00\x00not cdr")
    wait(lambda: any(a.status and a.status[0].level == b"\x01" for a in got))
    warned = next(a for a in got if a.status[0].level == b"\x01").status[0]
    assert warned.name == "twin_ingest: robot1"
    values = {kv.key: kv.value for kv in warned.values}
    assert values["refused.malformed"] == "1" and values["last_refusal"].startswith("malformed: ")
    count = len(got)
    wait(lambda: len(got) > count)
    assert got[-1].status[0].level == b"\x00"  # nothing refused since: OK again
    sub.undeclare()


@pytest.mark.parametrize("ingest", [1], indirect=True, ids=["one worker process"])
def test_a_worker_that_dies_is_started_again_and_its_robot_resumes_with_nothing_sent_twice(
    ingest: tuple[RosIngest, zenoh.Session, list[bytes]],
) -> None:
    ing, session, docs = ingest
    assert ing._pool is not None
    static = [
        Tf("base_link", "camera_link", (0.2, 0, 1.0)),
        Tf("camera_link", "camera_optical_frame", (0, 0, 0), OPTICAL),
    ]
    session.put("robot1/tf_static", cdr_tf(static))
    stamp = time.time_ns()
    send_array(session, stamp)
    wait(lambda: len(docs) == 1)
    ing._pool.workers[0].process.kill()
    wait(lambda: ing.status()["ros_ingest"]["worker_restarts"] == 1)
    send_array(session, stamp + 10**8)  # the static TF and the map are fed to the new worker again
    wait(lambda: len(docs) == 2)
    assert b"twin:polygon" in docs[1]  # its view: the camera's frame resolved through the replayed tf_static
    iri = re.compile(rb"<urn:twin-ros:robot1:det:[^>]*>")
    assert iri.findall(docs[1]) == iri.findall(docs[0])  # the tracker session goes on, not a new one
    assert view_xs(docs[1]).max() <= 16.0
    time.sleep(0.5)
    assert len(docs) == 2
    counts = ing.status()["ros_ingest"]["counts"]["robot1"]  # type: ignore[index]
    assert counts["submitted"] == 2 and counts["refused"] == {} and counts["worker_restarts"] == 1
