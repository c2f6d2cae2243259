"""``twin map --skill <routes skill>``: a fleet's route graph as Open-RMF and nav2 files; and ``twin
serve``'s route graphs on Zenoh and as Open-RMF's ``BuildingMap`` on ``/map`` (:func:`serve_routes`).

The RMF door names come from the configured ``[sources.NAME] doors`` tables (RMF name -> the twin
door's IRI, GlobalId or name), the RMF levels from their ``levels`` tables, the GeoJSON's frame from
``[ros] frame_id``.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from pathlib import Path

import zenoh

from adapters.cli.serve_settings import ServeSettings
from adapters.ros.building_map import encode_building_map
from adapters.ros.rmf import DoorIndex
from adapters.ros.routes import RouteFiles, rmf_levels, write_route_files
from adapters.ros.settings import LevelConfig, RosSettings, ros_sources
from adapters.zenoh.ros_building_map import RosBuildingMap
from adapters.zenoh.routes import ZenohRoutes
from twin.config import Config
from twin.errors import TwinError
from twin.graph.rdf import literal_value
from twin.graph.store import GraphStore
from twin.maps.grid import OccupancyGrid
from twin.maps.render import build_map, plan_map
from twin.maps.scene import Scene
from twin.routes.build import build_routes
from twin.routes.graph import RouteGraph
from twin.selection.skill_selection import selection_query

log = logging.getLogger(__name__)

_DOORS = """SELECT ?e ?name WHERE { ?e twin:ifcType "IfcDoor" . OPTIONAL { ?e rdfs:label ?name } }"""


def rmf_door_names(cfg: Config, store: GraphStore) -> dict[str, str]:
    """Door IRI -> the RMF door name a configured door table gives it."""
    rows = store.select(_DOORS)
    index = DoorIndex((literal_value(r["e"]) or "", literal_value(r["name"]) or "") for r in rows)
    out: dict[str, str] = {}
    for source in ros_sources(cfg).values():
        for rmf_name, key in source.doors:
            iri = index.find(key)
            if iri is not None:
                out.setdefault(iri, rmf_name)
    return out


def route_graph(cfg: Config, store: GraphStore, scene: Scene, name: str) -> RouteGraph:
    """The routes skill ``name``'s graph of the store's building."""
    levels = rmf_levels(ros_sources(cfg).values())
    return build_routes(
        store,
        scene,
        cfg.routes[name],
        cfg.skills,
        margin_m=cfg.margin_m,
        door_names=rmf_door_names(cfg, store),
        level_names={storey: level for storey, (level, _) in levels.items()},
    )


def write_routes(cfg: Config, store: GraphStore, scene: Scene, name: str, out: Path) -> RouteFiles:
    """Build and write the routes skill ``name``'s files; prints what it made."""
    t0 = time.perf_counter()
    graph = route_graph(cfg, store, scene, name)
    files = write_route_files(
        graph,
        out,
        levels=rmf_levels(ros_sources(cfg).values()),
        frame_id=cfg.section(RosSettings).frame_id,
        open_door_operations=cfg.routes[name].open_door_operations,
    )
    passable = sum(d.passable for d in graph.doors)
    vertices = sum(len(s.vertices) for s in graph.storeys)
    lanes = sum(len(s.lanes) for s in graph.storeys)
    one_way = sum(lane.one_way for s in graph.storeys for lane in s.lanes)
    print(
        f"{name}: {vertices} waypoints, {lanes} lanes ({one_way} one-way) on {len(graph.storeys)} storeys, "
        f"{passable}/{len(graph.doors)} doors passable, {len(graph.lifts)} lifts, "
        f"{time.perf_counter() - t0:.2f} s -> {files.nav_graph}"
    )
    for note in graph.notes:
        print(f"  {note}")
    return files


class ServedRoutes:
    """What ``twin serve`` serves of the route graphs: the Zenoh keys and Open-RMF's ``/map``, and the
    graphs served (by routes skill). :meth:`update` serves a new version of one graph."""

    def __init__(
        self,
        zenoh_routes: ZenohRoutes,
        building_map: RosBuildingMap | None,
        graphs: dict[str, RouteGraph] | None = None,
        *,
        levels: Mapping[str, tuple[str, LevelConfig]] | None = None,
        files: Path | None = None,
    ) -> None:
        """``files``: the directory where each version's files are written (``[serve] route_files``)."""
        self.zenoh = zenoh_routes
        self.building_map = building_map
        self.graphs = dict(graphs or {})
        self.levels = levels
        self.files = files

    def write(self, graph: RouteGraph, cfg: Config, version: int) -> None:
        """Write ``graph``'s nav graph YAML and GeoJSON files into :attr:`files` (when set); a failure
        is logged in one line and the daemon goes on serving."""
        if self.files is None:
            return
        try:
            written = write_route_files(
                graph,
                self.files,
                levels=self.levels,
                frame_id=cfg.section(RosSettings).frame_id,
                open_door_operations=cfg.routes[graph.skill].open_door_operations,
            )
        except (OSError, TwinError) as err:
            log.error(
                "Routes skill %s: version %d not written to %s: %s", graph.skill, version, self.files, err
            )
            return
        log.info("Routes skill %s: version %d written to %s", graph.skill, version, written.nav_graph)

    def update(self, graph: RouteGraph, cfg: Config, store: GraphStore, scene: Scene) -> int | None:
        """Serve ``graph`` as the next version of its skill's graph (Zenoh, then a new ``BuildingMap``
        on ``/map`` with every graph served); None, and nothing sent, when it equals the one served."""
        old = self.graphs.get(graph.skill)
        if old is not None and old.to_json() == graph.to_json():
            return None
        self.graphs[graph.skill] = graph
        version = self.zenoh.publish(graph.skill, graph.to_json())
        self.write(graph, cfg, version)
        graphs = [self.graphs[name] for name in sorted(self.graphs)]
        payload = encode_building_map(
            graphs, storey_maps(cfg, store, scene, graphs[0]), building=graphs[0].building, levels=self.levels
        )
        if self.building_map is None:
            self.building_map = RosBuildingMap(self.zenoh.session, payload)
        else:
            self.building_map.put(payload)
        return version

    def close(self) -> None:
        if self.building_map is not None:
            self.building_map.close()
        self.zenoh.close()


def serve_routes(
    session: zenoh.Session, cfg: Config, store: GraphStore, scene: Scene, *, prefix: str
) -> ServedRoutes | None:
    """Build every routes skill's graph and publish it on ``<prefix>/routes/<skill>`` (latched JSON),
    and all of them as Open-RMF's ``BuildingMap`` on ``/map`` (both ROS 2 layouts, domain 0), and
    write their files into ``[serve] route_files`` when it is set. A skill that cannot make a graph
    is logged in one line and left out: the others are served. None when no routes skill is
    configured."""
    if not cfg.routes:
        return None
    routes = ZenohRoutes(session, prefix=prefix)
    levels = rmf_levels(ros_sources(cfg).values())
    served = ServedRoutes(routes, None, levels=levels, files=cfg.section(ServeSettings).route_files)
    graphs = []
    for name in sorted(cfg.routes):
        t0 = time.perf_counter()
        try:
            graph = route_graph(cfg, store, scene, name)
        except TwinError as err:
            log.error("Routes skill %s is not served: %s", name, err)
            continue
        graphs.append(graph)
        version = routes.publish(name, graph.to_json())
        served.graphs[name] = graph
        served.write(graph, cfg, version)
        log.info(
            "Routes skill %s: version %d on %s/routes/%s (%.2f s)",
            name,
            version,
            prefix,
            name,
            time.perf_counter() - t0,
        )
    if not graphs:
        return served
    payload = encode_building_map(
        graphs, storey_maps(cfg, store, scene, graphs[0]), building=graphs[0].building, levels=levels
    )
    served.building_map = RosBuildingMap(session, payload)
    return served


def storey_maps(cfg: Config, store: GraphStore, scene: Scene, graph: RouteGraph) -> dict[str, OccupancyGrid]:
    """Each storey's map of ``graph``'s navigation skill: the levels' images of the building map."""
    nav = cfg.skills[cfg.routes[graph.skill].navigation]
    iris = [literal_value(r["element"]) or "" for r in store.select(selection_query(nav))]
    return {
        s.storey: build_map(scene, plan_map(scene, nav, s.storey, iris, margin_m=cfg.margin_m))
        for s in graph.storeys
    }
