"""Route graphs on Zenoh: ``twin/<site>/routes/<skill>`` latched for late joiners and answered to a
``get``, built the way ``twin serve`` builds them; a routes skill that cannot make a graph is logged
in one line and the others are served (a robot wider than every door, a storey without free space)."""

from __future__ import annotations

import json
import logging
import threading
import time
from pathlib import Path

import pytest
import zenoh

from adapters.cli.map_routes import ServedRoutes, serve_routes
from adapters.zenoh.latched import declare_latched_subscriber
from adapters.zenoh.session import client_config, session_config
from adapters.zenoh.settings import ZenohSettings
from tests.conftest import imported
from tests.integration.conftest import free_port
from tests.twin.box_lab import box_lab
from twin.config import load_config
from twin.maps.scene import load_scene

PREFIX = "twin/lab"
SITE = """
[skills.nav25]
kind = "navigation"
robot_height_m = 0.5
inflation_radius_m = 0.25
[skills.wide]
kind = "navigation"
robot_height_m = 0.5
inflation_radius_m = 0.6
[skills.small]
kind = "routes"
navigation = "nav25"
[skills.huge]
kind = "routes"
navigation = "wide"
[skills.vast]
kind = "navigation"
robot_height_m = 0.5
inflation_radius_m = 3.0
[skills.giant]
kind = "routes"
navigation = "vast"
storeys = ["first-floor"]
"""


def _get(session: zenoh.Session, selector: str) -> dict[str, dict[str, object]]:
    out = {}
    for reply in session.get(selector, timeout=5.0):
        assert reply.ok is not None
        out[str(reply.ok.key_expr)] = json.loads(reply.ok.payload.to_bytes())
    return out


def test_the_daemons_graphs_are_latched_and_answered_and_a_bad_skill_is_left_out(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    (tmp_path / "site.toml").write_text(SITE)
    cfg = load_config(tmp_path / "site.toml")
    store = imported(box_lab(storeys=2))
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    daemon = zenoh.open(session_config(ZenohSettings(), mode="peer", listen=[endpoint], connect=[]))
    fleet = zenoh.open(client_config([endpoint]))
    routes: ServedRoutes | None = None
    try:
        with caplog.at_level(logging.ERROR):
            routes = serve_routes(daemon, cfg, store, load_scene(store), prefix=PREFIX)
        assert routes is not None and routes.building_map is not None  # and Open-RMF's /map
        errors = [r.getMessage() for r in caplog.records if r.levelno == logging.ERROR]
        assert len(errors) == 2 and all("\n" not in e and "Traceback" not in e for e in errors)
        giant, huge = sorted(errors)  # a storey without free space; a robot wider than every door
        assert "Routes skill giant is not served" in giant and "'first-floor' has no free space" in giant
        assert "Routes skill huge is not served" in huge and "fits through none of the model's 1" in huge
        deadline = time.monotonic() + 10.0
        got: dict[str, dict[str, object]] = {}
        while not got and time.monotonic() < deadline:
            got = _get(fleet, f"{PREFIX}/routes/**")
        assert list(got) == [f"{PREFIX}/routes/small"]
        graph = got[f"{PREFIX}/routes/small"]
        assert graph["version"] == 1 and graph["fleet"] == "small"
        assert [s["storey"] for s in graph["storeys"]] == ["ground-floor", "first-floor"]  # type: ignore[union-attr,index]

        late: list[dict[str, object]] = []
        arrived = threading.Event()

        def on_sample(sample: zenoh.Sample) -> None:
            late.append(json.loads(sample.payload.to_bytes()))
            arrived.set()

        sub = declare_latched_subscriber(fleet, f"{PREFIX}/routes/*", on_sample)
        try:
            assert arrived.wait(10.0)  # a fleet manager that starts later gets the current graph
            assert late[0]["skill"] == "small" and late[0]["version"] == 1
            arrived.clear()
            assert routes.zenoh.publish("small", {"skill": "small"}) == 2  # a new version replaces it
            assert arrived.wait(10.0)
            assert late[-1] == {"skill": "small", "version": 2}
        finally:
            sub.undeclare()
        assert _get(fleet, f"{PREFIX}/routes/small")[f"{PREFIX}/routes/small"]["version"] == 2
        assert _get(fleet, f"{PREFIX}/routes/other") == {}
    finally:
        if routes is not None:
            routes.close()
        fleet.close()
        daemon.close()
