"""One-way lanes (a routes skill's ``one_way`` stretches): written once, their way, in the Open-RMF nav
graph and the nav2 GeoJSON (read back as the fleet adapter and the route server read them), and as
``EDGE_TYPE_UNIDIRECTIONAL`` edges of the ``BuildingMap``; the other lanes stay two-way."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from adapters.ros.building_map import EDGE_TYPE_BIDIRECTIONAL, EDGE_TYPE_UNIDIRECTIONAL, building_map
from adapters.ros.routes import write_route_files
from tests.adapters.ros.route_readers import read_nav2_geojson, read_rmf_nav_graph
from tests.conftest import imported
from tests.twin.box_lab import box_lab
from twin.config import load_config
from twin.errors import ConfigError, RouteError
from twin.graph.store import GraphStore
from twin.maps.scene import Scene, load_scene
from twin.routes import parse_routes
from twin.routes.build import build_routes
from twin.routes.graph import RouteGraph

CORRIDOR = {"x1": 13.0, "y1": 7.0, "x2": 18.5, "y2": 7.0}
"""Along the lab's corridor (world x 14.2 to 17.8 between y 6.4 and 7.6) and its doors, eastwards."""


@pytest.fixture(scope="module")
def lab() -> tuple[GraphStore, Scene]:
    store = imported(box_lab())
    return store, load_scene(store)


def _graph(lab: tuple[GraphStore, Scene], **keys: object) -> RouteGraph:
    cfg = load_config()
    skills = {**cfg.skills, "nav": replace(cfg.skills["lab-navigation"], name="nav", inflation_radius_m=0.25)}
    routes = parse_routes("fleet", {"kind": "routes", "navigation": "nav", **keys})
    return build_routes(*lab, routes, skills)


def test_lanes_along_a_one_way_stretch_are_written_once_its_way(
    lab: tuple[GraphStore, Scene], tmp_path: Path
) -> None:
    graph = _graph(lab, one_way=[CORRIDOR])
    two_way = _graph(lab)
    s = graph.storeys[0]
    one_way = [lane for lane in s.lanes if lane.one_way]
    assert one_way and len(one_way) < len(s.lanes)
    assert [(lane.a, lane.b) for lane in s.lanes if not lane.one_way] != []
    assert {frozenset((lane.a, lane.b)) for lane in s.lanes} == {
        frozenset((lane.a, lane.b)) for lane in two_way.storeys[0].lanes
    }  # the same lanes, some directed
    for lane in one_way:  # eastwards, along the corridor
        a, b = s.vertices[lane.a], s.vertices[lane.b]
        assert b.x > a.x and 6.5 < a.y < 7.5 and 6.5 < b.y < 7.5
    assert graph.to_json()["storeys"][0]["one_way"] == [i for i, lane in enumerate(s.lanes) if lane.one_way]

    files = write_route_files(graph, tmp_path)
    rmf = read_rmf_nav_graph(files.nav_graph)
    directed = {(lane.begin, lane.end) for lane in rmf.lanes}
    assert len(rmf.lanes) == 2 * len(s.lanes) - len(one_way)
    for lane in s.lanes:
        assert (lane.a, lane.b) in directed
        assert ((lane.b, lane.a) in directed) is not lane.one_way
    nav2 = read_nav2_geojson(files.geojson[0])
    edges = {(start, end) for start, end, *_ in nav2.edges.values()}
    assert len(nav2.edges) == len(edges) == 2 * len(s.lanes) - len(one_way)
    assert all((lane.b, lane.a) not in edges for lane in one_way)

    msg = building_map([graph], {}, building=graph.building)
    types = [e.edge_type for e in msg.levels[0].nav_graphs[0].edges]
    assert types.count(EDGE_TYPE_UNIDIRECTIONAL) == len(one_way)
    assert types.count(EDGE_TYPE_BIDIRECTIONAL) == len(s.lanes) - len(one_way)


def test_a_stretch_no_lane_runs_along_is_a_note_and_bad_ones_are_refused(
    lab: tuple[GraphStore, Scene],
) -> None:
    nowhere = {"x1": 0.0, "y1": 0.0, "x2": 0.0, "y2": 3.0, "within_m": 0.1}
    graph = _graph(lab, one_way=[nowhere])
    assert not any(lane.one_way for s in graph.storeys for lane in s.lanes)
    assert "one_way (0, 0) -> (0, 3): no lane runs along it" in graph.notes
    with pytest.raises(RouteError, match="one_way storey 'roof' is not served; served: ground-floor"):
        _graph(lab, one_way=[{**CORRIDOR, "storey": "roof"}])
    with pytest.raises(ConfigError, match=r"\(1.0, 1.0\) -> \(1.0, 1.05\) is shorter than 0.1 m"):
        parse_routes("fleet", {"kind": "routes", "navigation": "nav", "one_way": [
            {"x1": 1.0, "y1": 1.0, "x2": 1.0, "y2": 1.05}]})  # fmt: skip


def test_a_one_way_door_is_passed_only_towards_its_given_side_and_networkx_follows(
    lab: tuple[GraphStore, Scene],
) -> None:
    graph = _graph(lab, one_way=[{"door": "Door A", "x2": 12.0, "y2": 7.0}])  # into Room A only
    s = graph.storeys[0]
    (lane,) = [lane for lane in s.lanes if lane.door == "Door_A"]
    assert lane.one_way and s.vertices[lane.b].y > 4.9 > s.vertices[lane.a].y  # outside -> inside
    assert sum(other.one_way for other in s.lanes) == 1
    g = graph.to_networkx()
    inside, outside = (s.storey, lane.b), (s.storey, lane.a)
    assert g.has_edge(outside, inside) and not g.has_edge(inside, outside)
    two_way = next(other for other in s.lanes if not other.one_way)
    assert g.has_edge((s.storey, two_way.a), (s.storey, two_way.b))
    assert g.has_edge((s.storey, two_way.b), (s.storey, two_way.a))
    none = _graph(lab, one_way=[{"door": "Door Z", "x2": 12.0, "y2": 7.0}])
    assert "one_way door Door Z: no lane passes it" in none.notes
    with pytest.raises(ConfigError, match="one-way door 'Door A': give x2, y2"):
        parse_routes("fleet", {"kind": "routes", "navigation": "nav", "one_way": [
            {"door": "Door A", "x1": 1.0, "y1": 1.0, "x2": 1.0, "y2": 3.0}]})  # fmt: skip
