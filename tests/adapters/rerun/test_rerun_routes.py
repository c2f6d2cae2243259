"""Route graphs in the Rerun recording: lanes and named vertices over each storey's maps, under the
routes skill's entity path, logged again at each graph version (read back from the file)."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from adapters.cli.map_routes import route_graph
from adapters.rerun import RerunRecorder
from tests.adapters.rerun.test_rerun import chunks_by_entity, column
from tests.conftest import imported
from tests.twin.box_lab import box_lab
from tests.twin.live_helpers import box_turtle, observe, started
from twin.config import load_config
from twin.live.events import RoutesPublished
from twin.maps.scene import load_scene

SITE = """
[skills.nav25]
kind = "navigation"
robot_height_m = 0.5
inflation_radius_m = 0.25
[skills.small]
kind = "routes"
navigation = "nav25"
one_way = [{ x1 = 13.0, y1 = 7.0, x2 = 18.5, y2 = 7.0 }]  # along the corridor, eastwards
"""


def test_each_graph_version_is_drawn_over_its_storeys_maps_with_named_vertices_and_one_way_arrows(
    tmp_path: Path,
) -> None:
    (tmp_path / "site.toml").write_text(SITE)
    cfg = load_config(tmp_path / "site.toml")
    cfg = dataclasses.replace(cfg, default_rights=frozenset({"create", "static"}))
    path = tmp_path / "twin.rrd"
    recorder = RerunRecorder(path=path)
    service, kept = started(imported(box_lab()), cfg)
    for event in kept.events:
        recorder.emit(event)
    service.sinks.append(recorder)
    first = route_graph(cfg, service.store, load_scene(service.store), "small")
    recorder.emit(RoutesPublished(first, "nav25", 1, time.time_ns()))
    wall = box_turtle("urn:builder:wall", 5.0, 2.0, sx=0.2, sy=1.3, sz=2.5, cls="IfcWall")
    assert observe(service, "builder", wall).ok
    second = route_graph(cfg, service.store, load_scene(service.store), "small")
    recorder.emit(RoutesPublished(second, "nav25", 2, time.time_ns()))
    recorder.close()

    entities = chunks_by_entity(path)
    lanes = [
        strips
        for b in entities["/maps/ground-floor/small/lanes"]
        if "LineStrips3D:strips" in b.schema.names
        for strips in column(b, "LineStrips3D:strips")
    ]
    counts = [len(s.lanes) for g in (first, second) for s in g.storeys]
    assert [len(strips) for strips in lanes] == counts and counts[0] != counts[1]
    z = first.storeys[0].elevation_m + 0.02
    assert all(abs(p[2] - z) < 1e-4 for strip in lanes[0] for p in strip)  # just over the storey's maps
    labels = [
        row
        for b in entities["/maps/ground-floor/small/vertices"]
        if "Points3D:labels" in b.schema.names
        for row in column(b, "Points3D:labels")
    ]
    assert len(labels) == 2 and labels[0] == [v.name for v in first.storeys[0].vertices]
    assert any(name.endswith("Room_A") for name in labels[0])  # the spaces' vertices by name
    versions = [
        v
        for b in entities["/maps/ground-floor/small"]
        if "graph_version" in b.schema.names
        for v in column(b, "graph_version")
    ]
    assert versions == [[1], [2]]
    arrows = [
        row
        for b in entities["/maps/ground-floor/small/one_way"]
        if "Arrows3D:vectors" in b.schema.names
        for row in column(b, "Arrows3D:vectors")
    ]
    ways = [sum(lane.one_way for lane in g.storeys[0].lanes) for g in (first, second)]
    assert [len(a) for a in arrows] == ways and ways[0] > 0
    assert all(v[0] > 0 for v in arrows[0])  # eastwards, the stretch's way
