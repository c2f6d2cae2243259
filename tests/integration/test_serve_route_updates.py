"""``twin serve`` with a routes skill: a wall built by a source with the ``static`` right makes a new
graph version on Zenoh and in the recording, and the daemon still stops cleanly (its rebuild thread
joined)."""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

import pytest
import zenoh

from adapters.zenoh.latched import declare_latched_subscriber
from adapters.zenoh.session import client_config
from tests.adapters.rerun.test_rerun import chunks_by_entity, column
from tests.adapters.zenoh.test_zenoh_route_updates import parts
from tests.integration.conftest import start_daemon
from tests.twin.live_helpers import box_turtle

pytestmark = pytest.mark.slow  # a daemon process

CONFIG = """
[rights]
default = ["create", "dynamic", "doors", "static"]
[skills.nav25]
kind = "navigation"
robot_height_m = 0.5
inflation_radius_m = 0.25
exclude_types = ["IfcOpeningElement"]
[skills.small]
kind = "routes"
navigation = "nav25"
storeys = ["ground-floor"]
"""


def test_a_wall_built_while_serving_makes_graph_version_2_and_the_stop_stays_clean(
    fresh_store: Path, tmp_path: Path
) -> None:
    (tmp_path / "site.toml").write_text(CONFIG)
    rrd = tmp_path / "run.rrd"
    daemon = start_daemon(fresh_store, "--record", str(rrd), config=tmp_path / "site.toml")
    graphs: list[dict[str, Any]] = []
    arrived = threading.Condition()

    def on_graph(sample: zenoh.Sample) -> None:
        with arrived:
            graphs.append(json.loads(sample.payload.to_bytes()))
            arrived.notify_all()

    try:
        with zenoh.open(client_config([daemon.endpoint])) as session:
            sub = declare_latched_subscriber(session, "twin/lab/routes/small", on_graph)
            with arrived:
                assert arrived.wait_for(lambda: graphs, 20.0), "\n".join(daemon.log[-20:])
            wall = box_turtle("urn:builder:wall", 5.0, 2.0, sx=0.2, sy=1.3, sz=2.5, cls="IfcWall")
            replies = list(session.get("twin/lab/observe/builder", payload=wall, timeout=10.0))
            assert replies and replies[0].ok is not None
            assert json.loads(replies[0].ok.payload.to_bytes())["ok"]
            with arrived:
                assert arrived.wait_for(lambda: graphs[-1]["version"] == 2, 20.0)
            sub.undeclare()
    finally:
        daemon.stop_cleanly()
    assert [g["version"] for g in graphs] == [1, 2]
    assert parts(graphs[1]) > parts(graphs[0])  # the wall cuts the corridor: the graph falls apart
    lanes = sum(len(s["lanes"]) for s in graphs[1]["storeys"])
    entities = chunks_by_entity(rrd)
    versions = [
        v
        for b in entities["/maps/ground-floor/small"]
        if "graph_version" in b.schema.names
        for v in column(b, "graph_version")
    ]
    assert versions == [[1], [2]]
    strips = [
        row
        for b in entities["/maps/ground-floor/small/lanes"]
        if "LineStrips3D:strips" in b.schema.names
        for row in column(b, "LineStrips3D:strips")
    ]
    assert len(strips[-1]) == lanes

