"""Readers of route graph files, written from the consumers' own code, for the tests.

:func:`read_rmf_nav_graph` follows open-rmf/rmf_ros2 ``rmf_fleet_adapter/src/rmf_fleet_adapter/agv/
parse_graph.cpp`` (``parse_graph``) rule by rule; :func:`read_nav2_geojson` follows
ros-navigation/navigation2 ``nav2_route/src/plugins/graph_file_loaders/geojson_graph_file_loader.cpp``.
Each raises ``ValueError`` where its original throws or returns false.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml


@dataclass
class RmfWaypoint:
    map_name: str
    x: float
    y: float
    name: str = ""
    lift: str = ""
    charger: bool = False
    parking_spot: bool = False
    holding_point: bool = False


@dataclass
class RmfLane:
    begin: int
    end: int
    entry: tuple[str, ...] = ()
    exit: tuple[str, ...] = ()
    speed_limit: float | None = None


@dataclass
class RmfGraph:
    waypoints: list[RmfWaypoint] = field(default_factory=list)
    lanes: list[RmfLane] = field(default_factory=list)
    keys: dict[str, int] = field(default_factory=dict)
    lifts: dict[str, tuple[float, float, float, float, float]] = field(default_factory=dict)
    doors: dict[str, tuple[tuple[float, float], tuple[float, float], str]] = field(default_factory=dict)


def read_rmf_nav_graph(path: Path) -> RmfGraph:
    """``parse_graph(graph_file, vehicle_traits)``: the waypoints, keys, directed lanes with their
    events, lifts and doors of an Open-RMF nav graph."""
    config = yaml.safe_load(path.read_text())
    graph = RmfGraph()
    has_lifts = "lifts" in config and config["lifts"] is not None
    for name, lift in (config.get("lifts") or {}).items():
        pos, dims = lift["position"], lift["dims"]
        graph.lifts[str(name)] = (float(pos[0]), float(pos[1]), float(pos[2]), float(dims[0]), float(dims[1]))
    for name, door in (config.get("doors") or {}).items():
        ends = door["endpoints"]
        graph.doors[str(name)] = (
            (float(ends[0][0]), float(ends[0][1])),
            (float(ends[1][0]), float(ends[1][1])),
            str(door["map"]),
        )
    levels = config.get("levels")
    if levels is None:
        raise ValueError("is missing the [levels] key")
    if not isinstance(levels, dict):
        raise ValueError("The [levels] key does not point to a map")
    wps_of_lift: dict[str, list[int]] = {}
    lift_of_wp: dict[int, str] = {}
    vnum = 0
    for map_name, level in levels.items():
        vnum_temp = 0
        for vertex in level["vertices"]:
            options = vertex[2]
            wp = RmfWaypoint(str(map_name), float(vertex[0]), float(vertex[1]))
            index = len(graph.waypoints)
            graph.waypoints.append(wp)
            name = options.get("name")
            if name:
                if name in graph.keys:
                    raise ValueError(f"Duplicated waypoint name [{name}]")
                graph.keys[name] = index
                wp.name = name
            vnum_temp += 1
            wp.parking_spot = bool(options.get("is_parking_spot", False))
            wp.holding_point = bool(options.get("is_holding_point", False))
            wp.charger = bool(options.get("is_charger", False))
            lift = options.get("lift")
            if lift:
                wps_of_lift.setdefault(lift, []).append(index)
                lift_of_wp[index] = lift
                if has_lifts and lift not in graph.lifts:
                    raise ValueError(f"Lift properties for [{lift}] were not provided")
                wp.lift = lift
        for lane in level["lanes"]:
            options = lane[2] or {}
            constraint = options.get("orientation_constraint")
            if constraint is not None and constraint not in ("forward", "backward"):
                raise ValueError(f"Unrecognized orientation constraint label [{constraint}]")
            begin, end = int(lane[0]) + vnum, int(lane[1]) + vnum
            entry: list[str] = []
            exit_: list[str] = []
            begin_in, end_in = begin in lift_of_wp, end in lift_of_wp
            if begin_in or end_in:
                if not begin_in and end_in:
                    entry.append(f"LiftSessionBegin:{lift_of_wp[end]}")
                elif begin_in and end_in:
                    if lift_of_wp[begin] != lift_of_wp[end]:
                        raise ValueError("two connected waypoints are in different lifts")
                else:
                    entry.append(f"LiftDoorOpen:{lift_of_wp[begin]}")
                    exit_.append(f"LiftSessionEnd:{lift_of_wp[begin]}")
            elif "door_name" in options:
                entry.append(f"DoorOpen:{options['door_name']}")
                exit_.append(f"DoorClose:{options['door_name']}")
            dock = options.get("dock_name")
            if dock:
                entry.append(f"Dock:{dock}")
            speed = options.get("speed_limit")
            graph.lanes.append(
                RmfLane(begin, end, tuple(entry), tuple(exit_), float(speed) if speed and speed > 0 else None)
            )
        vnum += vnum_temp
    for lift, wps in wps_of_lift.items():
        largest = 0.0
        for i in range(len(wps) - 1):
            graph.lanes.append(RmfLane(wps[i], wps[i + 1], (f"LiftMove:{lift}",)))
            graph.lanes.append(RmfLane(wps[i + 1], wps[i], (f"LiftMove:{lift}",)))
            pi = graph.waypoints[wps[i]]
            for j in range(i + 1, len(wps)):
                pj = graph.waypoints[wps[j]]
                largest = max(largest, math.hypot(pj.x - pi.x, pj.y - pi.y))
        if largest > 0.1:
            raise ValueError(f"Bad vertical alignment for the waypoints in lift [{lift}]")
    return graph


@dataclass
class Nav2Graph:
    nodes: dict[int, tuple[float, float, str, dict[str, Any]]] = field(default_factory=dict)
    edges: dict[int, tuple[int, int, float | None, dict[str, Any], list[dict[str, Any]]]] = field(
        default_factory=dict
    )


_TRIGGERS = ("NODE", "ON_ENTER", "ON_EXIT")


def _metadata(value: Any) -> Any:
    """``convertMetaDataFromJson``: objects recurse, arrays of primitives, primitives."""
    if isinstance(value, dict):
        return {k: _metadata(v) for k, v in value.items()}
    if isinstance(value, list):
        if any(isinstance(v, dict | list) for v in value):
            raise ValueError("Failed to convert")  # arrays hold primitives only
        return list(value)
    if value is None:
        raise ValueError("Failed to convert")
    return value


def _operations(props: dict[str, Any]) -> list[dict[str, Any]]:
    out = []
    operations = props.get("operations", {})
    for op in operations.values() if isinstance(operations, dict) else operations:
        if not isinstance(op.get("type"), str) or op.get("trigger") not in _TRIGGERS:
            raise ValueError(f"bad operation {op!r}")
        out.append(op)
    return out


def read_nav2_geojson(path: Path) -> Nav2Graph:
    """``GeoJsonGraphFileLoader::loadGraphFromFile``: the nodes and directed edges of a route graph."""
    doc = json.loads(path.read_text())
    nodes, edges = [], []
    for feature in doc["features"]:
        kind = feature["geometry"]["type"]
        if kind == "Point":
            nodes.append(feature)
        elif kind in ("MultiLineString", "LineString"):
            edges.append(feature)
    if not nodes or not edges:
        raise ValueError("The graph is malformed. Is does not contain nodes or edges.")
    graph = Nav2Graph()
    for node in nodes:
        props = node["properties"]
        nodeid = props["id"]
        if not isinstance(nodeid, int) or nodeid < 0:
            raise ValueError(f"node id {nodeid!r} is not an unsigned integer")
        x, y = node["geometry"]["coordinates"][:2]
        _operations(props)
        graph.nodes[nodeid] = (
            float(x),
            float(y),
            props.get("frame", ""),
            _metadata(props.get("metadata", {})),
        )
    for edge in edges:
        props = edge["properties"]
        eid, start, end = props["id"], props["startid"], props["endid"]
        if start not in graph.nodes:
            raise ValueError(f"Start id {start} does not exist for edge id {eid}")
        if end not in graph.nodes:
            raise ValueError(f"End id of {end} does not exist for edge id {eid}")
        cost = props.get("cost")
        graph.edges[eid] = (start, end, cost, _metadata(props.get("metadata", {})), _operations(props))
    return graph
