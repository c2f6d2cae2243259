"""A structural change while the daemon serves makes a new route graph version, on Zenoh, on
Open-RMF's ``/map`` and in the files of ``[serve] route_files``; furniture does not; nor does a change
that leaves the graph as it was; a change of the navigation skill does; the rebuild runs after a
quiet spell, off the writer's thread."""

from __future__ import annotations

import dataclasses
import json
import threading
import time
from pathlib import Path
from typing import Any

import networkx as nx
import zenoh

from adapters.cli.map_routes import ServedRoutes, serve_routes
from adapters.cli.route_updates import RouteUpdates
from adapters.ros.building_map import decode_building_map
from adapters.zenoh.latched import declare_latched_subscriber
from adapters.zenoh.session import client_config, session_config
from adapters.zenoh.settings import ZenohSettings
from tests.conftest import imported
from tests.integration.conftest import free_port
from tests.twin.box_lab import box_lab
from tests.twin.live_helpers import box_turtle, observe, started
from twin.config import load_config

PREFIX = "twin/lab"
SITE = """
[skills.nav25]
kind = "navigation"
robot_height_m = 0.5
inflation_radius_m = 0.25
[skills.small]
kind = "routes"
navigation = "nav25"
"""


def parts(graph: dict[str, Any]) -> int:
    """The number of connected parts of a served graph's storeys."""
    g = nx.Graph()
    for s in graph["storeys"]:
        g.add_nodes_from((s["storey"], i) for i in range(len(s["vertices"])))
        g.add_edges_from(((s["storey"], a), (s["storey"], b)) for a, b, _ in s["lanes"])
    return int(nx.number_connected_components(g))


def test_a_wall_across_the_corridor_and_a_wider_robot_make_new_graph_versions_and_a_table_does_not(
    tmp_path: Path,
) -> None:
    (tmp_path / "site.toml").write_text(SITE + f'[serve]\nroute_files = "{tmp_path / "routes"}"\n')
    yaml_file = tmp_path / "routes" / "small.nav_graph.yaml"
    cfg = load_config(tmp_path / "site.toml")
    cfg = dataclasses.replace(cfg, default_rights=frozenset({"create", "dynamic", "static"}))
    service, _ = started(imported(box_lab()), cfg)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    daemon = zenoh.open(session_config(ZenohSettings(), mode="peer", listen=[endpoint], connect=[]))
    fleet = zenoh.open(client_config([endpoint]))
    routes: ServedRoutes | None = None
    updates: RouteUpdates | None = None
    graphs: list[dict[str, Any]] = []
    maps: list[Any] = []
    arrived = threading.Condition()

    def on_graph(sample: zenoh.Sample) -> None:
        with arrived:
            graphs.append(json.loads(sample.payload.to_bytes()))
            arrived.notify_all()

    def on_map(sample: zenoh.Sample) -> None:
        with arrived:
            maps.append(decode_building_map(sample.payload.to_bytes()))
            arrived.notify_all()

    subs: list[Any] = []
    try:
        routes = serve_routes(daemon, cfg, service.store, service.live_maps.scene, prefix=PREFIX)
        assert routes is not None and routes.building_map is not None
        updates = RouteUpdates(
            routes,
            cfg,
            service.store,
            skills=lambda: service.skills,
            debounce_s=0.2,
            static=(iri for iri, s in service.states.items() if s.is_static),
        )
        service.sinks.append(updates)
        subs.append(declare_latched_subscriber(fleet, f"{PREFIX}/routes/small", on_graph))
        subs.append(declare_latched_subscriber(fleet, routes.building_map.topic.bridge_key, on_map))
        with arrived:
            assert arrived.wait_for(lambda: graphs and maps, 10.0)
        assert graphs[-1]["version"] == 1
        first = yaml_file.read_text()
        assert (tmp_path / "routes" / "ground-floor__small.geojson").is_file()

        table = box_turtle("urn:robot1:table", 6.0, 2.0)  # furniture in the corridor: dynamic
        assert observe(service, "robot1", table).ok
        time.sleep(0.8)
        assert updates.rebuilds == 0 and len(graphs) == 1

        wall = box_turtle("urn:builder:wall", 5.0, 2.0, sx=0.2, sy=1.3, sz=2.5, cls="IfcWall")
        assert observe(service, "builder", wall).ok  # the corridor is cut in two
        with arrived:
            assert arrived.wait_for(lambda: len(graphs) >= 2 and len(maps) >= 2, 15.0)
        assert updates.rebuilds == 1
        assert graphs[-1]["version"] == 2 and parts(graphs[-1]) > parts(graphs[0])  # the corridor is cut
        assert maps[-1].levels[0].nav_graphs[0].edges != maps[0].levels[0].nav_graphs[0].edges
        assert yaml_file.read_text() != first  # RMF's fleet adapters read the new file at launch

        wider = b'{"kind": "navigation", "robot_height_m": 0.5, "inflation_radius_m": 0.35}'
        replies: list[Any] = []
        service.submit_skill("nav25", wider, replies.append)  # the fleet's robots got wider
        service.process()
        assert replies[0].ok
        with arrived:
            assert arrived.wait_for(lambda: len(graphs) >= 3, 15.0)
        assert graphs[-1]["version"] == 3 and graphs[-1]["robot_radius_m"] == 0.35
    finally:
        for sub in subs:
            sub.undeclare()
        if updates is not None:
            updates.close()
            assert not updates._thread.is_alive()
        if routes is not None:
            routes.close()
        fleet.close()
        daemon.close()
