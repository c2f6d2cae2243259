"""A fleet's route graph for Open-RMF and nav2: the nav graph YAML and the Route Server's GeoJSON.

**Open-RMF** (``<skill>.nav_graph.yaml``): one nav graph of every level, as ``building_map_generator
nav`` writes it (open-rmf/rmf_traffic_editor ``building_map/building.py`` and ``level.py``) and
``rmf_fleet_adapter`` reads it (open-rmf/rmf_ros2 ``agv/parse_graph.cpp``)::

    building_name: Lab
    levels:
      L1:
        vertices: [[x, y, {name, is_holding_point, is_parking_spot, is_charger, is_passthrough_point,
                           lift?}], ...]
        lanes: [[v1, v2, {speed_limit, door_name?, dock_name?, undock_name?}], ...]   # directed
    lifts: {Lift_1: {position: [x, y, yaw], dims: [width, depth]}}
    doors: {Door_A: {endpoints: [[x1, y1], [x2, y2]], map: L1}}

Lane ends index the level's own vertices; every lane is written directed (a two-way lane twice, as
the generator's ``always_unidirectional`` does; a one-way lane once, its way); ``speed_limit`` is the
fleet's nominal speed in m/s; a lane into a waypoint with a ``dock`` carries ``dock_name`` and the
lane out ``undock_name``.
Vertices in a lift's cabin name it in ``lift``: the fleet adapter joins the levels through them (it
refuses a lift whose vertices are more than 0.1 m apart, and lift vertex names must be unique: they
are prefixed by their level). Coordinates are each RMF level's: the ``levels`` tables of the
configured ``[sources.NAME]`` say where each level lies in the twin (``twin_from_level``); a storey
no table names is a level of its own key, in the twin's frame. A lift whose cabin lands more than
0.1 m apart in the frames of the levels it serves is refused (the fleet adapter would refuse it).

**nav2** (``<storey>__<skill>.geojson``, ros-navigation/navigation2 ``nav2_route``'s
``GeoJsonGraphFileLoader``): a FeatureCollection per storey in the twin's map frame (``[ros]
frame_id``), nodes as ``Point`` features (``id``, ``frame``, ``metadata``), each two-way lane as two
directed ``MultiLineString`` edges, a one-way lane as one (``id``, ``startid``, ``endid``, ``cost`` =
length in metres, ``metadata``: ``speed_limit`` in percent and ``abs_speed_limit`` in m/s, ``door`` on
a door's lane).
Ids are unique across nodes and edges and at most 65,535. With ``open_door_operations`` a door's
edges carry an ``open_door`` operation (``ON_ENTER``, ``metadata.door_id``): a plugin of that type must
be loaded on the route server.

Example::

    files = write_route_files(graph, Path("maps"), levels=rmf_levels(ros_sources(cfg).values()))
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from adapters.ros._common import write_atomic
from adapters.ros.settings import LevelConfig, RosSource
from twin.errors import RouteError
from twin.routes.graph import RouteGraph, RouteLane, RouteVertex, StoreyRoutes

__all__ = ["MAX_GEOJSON_ID", "RouteFiles", "nav_graph", "rmf_levels", "route_geojson", "write_route_files"]

MAX_GEOJSON_ID = 65_535
"""nav2's route server keys its dynamic edges by ``uint16``: every id fits."""
LIFT_ALIGNMENT_M = 0.1
"""``parse_graph`` refuses a lift whose waypoints lie further apart than this on different levels."""
_UNSAFE_FILE_CHARS = re.compile(r"[^\w.\-]")


@dataclass(frozen=True, slots=True)
class RouteFiles:
    """What :func:`write_route_files` wrote: the RMF nav graph and a GeoJSON graph per storey."""

    nav_graph: Path
    geojson: tuple[Path, ...]


def rmf_levels(sources: Iterable[RosSource]) -> dict[str, tuple[str, LevelConfig]]:
    """Storey key -> (RMF level name, where the level lies in the twin), from the configured
    sources' ``levels`` tables (inverted; the first source to name a storey wins)."""
    out: dict[str, tuple[str, LevelConfig]] = {}
    for source in sources:
        for level, config in source.levels:
            out.setdefault(config.storey, (level, config))
    return out


def to_level(config: LevelConfig | None, x: float, y: float) -> tuple[float, float]:
    """Twin (x, y) in the level's frame: the inverse of ``twin_from_level``."""
    if config is None:
        return float(x), float(y)
    dx, dy = float(x) - config.x, float(y) - config.y
    c, s = math.cos(config.yaw_rad), math.sin(config.yaw_rad)
    return round(c * dx + s * dy, 6), round(-s * dx + c * dy, 6)


def nav_graph(
    graph: RouteGraph, levels: Mapping[str, tuple[str, LevelConfig]] | None = None
) -> dict[str, Any]:
    """The Open-RMF nav graph (a YAML-ready dict) of ``graph`` (see the module's docstring)."""
    levels = levels or {}
    names = {s.storey: levels.get(s.storey, (s.storey, None))[0] for s in graph.storeys}
    if len(set(names.values())) < len(names):
        msg = f"Route graph {graph.skill!r}: two storeys map to one RMF level ({sorted(names.values())})."
        raise RouteError(msg)
    out_levels: dict[str, Any] = {}
    for s in graph.storeys:
        config = levels.get(s.storey, (s.storey, None))[1]
        vertices = []
        for v in s.vertices:
            x, y = to_level(config, v.x, v.y)
            vertices.append(_Row([x, y, _vertex_params(v)]))
        lanes = []
        for lane in s.lanes:
            for a, b in _directions(lane):
                params: dict[str, Any] = {"speed_limit": graph.speed_m_s}
                if lane.door:
                    params["door_name"] = lane.door
                if s.vertices[b].dock:
                    params["dock_name"] = s.vertices[b].dock
                if s.vertices[a].dock:
                    params["undock_name"] = s.vertices[a].dock
                lanes.append(_Row([a, b, params]))
        out_levels[names[s.storey]] = {"vertices": vertices, "lanes": lanes}
    lifts: dict[str, Any] = {}
    for lift in graph.lifts:
        stops = {
            names[st]: to_level(levels.get(st, (st, None))[1], lift.x, lift.y)
            for st in lift.storeys
            if st in names
        }
        spread = max(math.dist(p, q) for p in stops.values() for q in stops.values()) if stops else 0.0
        if spread > LIFT_ALIGNMENT_M:
            msg = (
                f"Route graph {graph.skill!r}: lift {lift.name!r} lies {spread:.2f} m apart in the frames of "
                f"levels {', '.join(stops)} (the levels tables of [sources] place them differently); "
                f"Open-RMF needs a lift's waypoints within {LIFT_ALIGNMENT_M} m on every level."
            )
            raise RouteError(msg)
        first = lift.storeys[0]
        config = levels.get(first, (first, None))[1]
        x, y = to_level(config, lift.x, lift.y)
        yaw = lift.yaw - (config.yaw_rad if config is not None else 0.0)
        lifts[lift.name] = {"position": [x, y, round(yaw, 6)], "dims": [lift.width_m, lift.depth_m]}
    doors: dict[str, Any] = {}
    for door in graph.doors:
        config = levels.get(door.storey, (door.storey, None))[1]
        ends = [list(to_level(config, *p)) for p in door.endpoints]
        doors[door.name] = {"endpoints": ends, "map": names.get(door.storey, door.storey)}
    return {"building_name": graph.building, "levels": out_levels, "lifts": lifts, "doors": doors}


class _Row(list[Any]):
    """A vertex or lane: one line of the YAML (``[x, y, {...}]``), as the generator writes them."""


class _Dumper(yaml.SafeDumper):  # type: ignore[misc]  # yaml has no stubs here
    pass


_Dumper.add_representer(
    _Row, lambda d, row: d.represent_sequence("tag:yaml.org,2002:seq", row, flow_style=True)
)


def _vertex_params(v: RouteVertex) -> dict[str, Any]:
    params: dict[str, Any] = {
        "name": v.name,
        "is_holding_point": v.holding_point,
        "is_parking_spot": v.parking_spot,
        "is_charger": v.charger,
        "is_passthrough_point": False,
    }
    if v.lift:
        params["lift"] = v.lift
    if v.dock:
        params["dock_name"] = v.dock
    return params


def _directions(lane: RouteLane) -> tuple[tuple[int, int], ...]:
    """The directed lanes a lane is written as: both ways, or only ``a`` -> ``b`` when one-way."""
    return ((lane.a, lane.b),) if lane.one_way else ((lane.a, lane.b), (lane.b, lane.a))


def route_geojson(
    graph: RouteGraph, storey: StoreyRoutes, *, frame_id: str = "map", open_door_operations: bool = False
) -> dict[str, Any]:
    """One storey's nav2 Route Server graph (a JSON-ready dict; see the module's docstring)."""
    n = len(storey.vertices)
    edges = sum(len(_directions(lane)) for lane in storey.lanes)
    if n + edges - 1 > MAX_GEOJSON_ID:
        msg = (
            f"Route graph {graph.skill!r} on storey {storey.storey!r}: {n} nodes and "
            f"{edges} edges need ids beyond nav2's {MAX_GEOJSON_ID}; "
            "use a larger spacing_m."
        )
        raise RouteError(msg)
    features: list[dict[str, Any]] = []
    for i, v in enumerate(storey.vertices):
        meta: dict[str, Any] = {"kind": v.kind}
        for key in ("name", "lift", "dock"):
            if getattr(v, key):
                meta[key] = getattr(v, key)
        for key in ("charger", "holding_point", "parking_spot"):
            if getattr(v, key):
                meta[key] = True
        features.append(
            {
                "type": "Feature",
                "properties": {"id": i, "frame": frame_id, "metadata": meta},
                "geometry": {"type": "Point", "coordinates": [v.x, v.y]},
            }
        )
    edge_id = n
    for lane in storey.lanes:
        for a, b in _directions(lane):
            va, vb = storey.vertices[a], storey.vertices[b]
            meta = {"speed_limit": 100.0, "abs_speed_limit": float(graph.speed_m_s)}
            props: dict[str, Any] = {
                "id": edge_id,
                "startid": a,
                "endid": b,
                "cost": round(math.hypot(va.x - vb.x, va.y - vb.y), 6),
                "overridable": True,
                "metadata": meta,
            }
            if lane.door:
                meta["door"] = lane.door
                if open_door_operations:
                    props["operations"] = {
                        "open_door": {
                            "type": "open_door",
                            "trigger": "ON_ENTER",
                            "metadata": {"door_id": lane.door},
                        }
                    }
            features.append(
                {
                    "type": "Feature",
                    "properties": props,
                    "geometry": {"type": "MultiLineString", "coordinates": [[[va.x, va.y], [vb.x, vb.y]]]},
                }
            )
            edge_id += 1
    return {
        "type": "FeatureCollection",
        "name": f"{graph.graph_name}__{storey.storey}",
        "features": features,
    }


def write_route_files(
    graph: RouteGraph,
    out_dir: Path,
    *,
    levels: Mapping[str, tuple[str, LevelConfig]] | None = None,
    frame_id: str = "map",
    open_door_operations: bool = False,
) -> RouteFiles:
    """Write ``<skill>.nav_graph.yaml`` and ``<storey>__<skill>.geojson`` per storey into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    skill = _UNSAFE_FILE_CHARS.sub("_", graph.skill)
    nav_path = out_dir / f"{skill}.nav_graph.yaml"
    text = yaml.dump(
        nav_graph(graph, levels), Dumper=_Dumper, sort_keys=False, default_flow_style=None, width=200
    )
    write_atomic(nav_path, text.encode())
    paths = []
    for storey in graph.storeys:
        path = out_dir / f"{_UNSAFE_FILE_CHARS.sub('_', storey.storey)}__{skill}.geojson"
        doc = route_geojson(graph, storey, frame_id=frame_id, open_door_operations=open_door_operations)
        write_atomic(path, (json.dumps(doc, indent=1) + "\n").encode())
        paths.append(path)
    return RouteFiles(nav_path, tuple(paths))
