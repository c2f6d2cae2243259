"""Open-RMF's ``rmf_building_map_msgs/msg/BuildingMap`` of the twin, as ``building_map_server`` serves it.

One message for the building: per storey a ``Level`` (its RMF level name and the storey's elevation),
with an ``AffineImage`` of the storey's map (a PNG of a navigation map: ``scale`` in metres per pixel,
``x_offset``/``y_offset`` the image's lower-left corner in the level's frame), its ``doors`` and the
fleets' ``nav_graphs`` (one ``Graph`` per routes skill serving it, named by its ``graph_name``:
``GraphNode`` per waypoint with its name and RMF flags as ``Param``s, one ``GraphEdge`` per lane,
``EDGE_TYPE_BIDIRECTIONAL`` (a one-way lane ``EDGE_TYPE_UNIDIRECTIONAL``, ``v1`` to ``v2``), with
``door_name`` and ``speed_limit`` params); and a ``Lift`` per lift (the RMF level names it serves,
its cabin's centre, yaw, width and depth).

Doors: the type follows the IFC door's ``OperationType`` (:func:`door_type`): swinging doors
``DOOR_TYPE_SINGLE_SWING`` / ``DOUBLE_SWING`` with ``motion_range`` 90 (**degrees**, as the message
defines it), sliding ones ``SINGLE_SLIDING`` / ``DOUBLE_SLIDING`` (``motion_range`` 0: the message
needs none), revolving, folding and rolling doors ``DOOR_TYPE_UNDEFINED``, and a door whose model does
not say a single swing. ``v1`` is the hinge (or the end a single sliding leaf slides towards) where the
operation type has a hand (``*_LEFT``, ``*_RIGHT``), else the leaf's first end; ``motion_direction`` is
1 for a clockwise swing seen from above, -1 anticlockwise (as ``building_map_generator`` turns a
swing door: about -z for 1), 1 when unknown. Coordinates are each level's (``[sources.NAME] levels``,
as the nav graph YAML's: :func:`adapters.ros.routes.to_level`).

Example::

    payload = encode_building_map(graphs, maps, building="Lab", levels=levels)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from adapters.ros.building_map_msgs import BUILDING_MAP
from adapters.ros.cdr import _deserialize, _serialize, _typestore
from adapters.ros.png import png_bytes
from adapters.ros.routes import to_level
from adapters.ros.settings import LevelConfig
from twin.maps.grid import OccupancyGrid
from twin.routes.graph import RouteGraph, RouteVertex

__all__ = ["DOOR_MOTION_RANGE_DEG", "decode_building_map", "door_type", "encode_building_map"]

DOOR_TYPE_UNDEFINED = 0
DOOR_TYPE_SINGLE_SLIDING = 1
DOOR_TYPE_DOUBLE_SLIDING = 2
DOOR_TYPE_SINGLE_SWING = 5
DOOR_TYPE_DOUBLE_SWING = 6
DOOR_MOTION_RANGE_DEG = 90.0
"""``Door.motion_range`` of a swing door: a swing of 90 degrees (the message's unit)."""
PARAM_STRING, PARAM_DOUBLE, PARAM_BOOL = 1, 3, 4
EDGE_TYPE_BIDIRECTIONAL = 0
EDGE_TYPE_UNIDIRECTIONAL = 1


def _msg(kind: str, /, **fields: Any) -> Any:
    return _typestore().types[f"rmf_building_map_msgs/msg/{kind}"](**fields)


def _param(name: str, value: str | float | bool) -> Any:
    if isinstance(value, bool):
        return _msg(
            "Param",
            name=name,
            type=PARAM_BOOL,
            value_int=0,
            value_float=0.0,
            value_string="",
            value_bool=value,
        )
    if isinstance(value, str):
        return _msg(
            "Param",
            name=name,
            type=PARAM_STRING,
            value_int=0,
            value_float=0.0,
            value_string=value,
            value_bool=False,
        )
    return _msg(
        "Param",
        name=name,
        type=PARAM_DOUBLE,
        value_int=0,
        value_float=float(value),
        value_string="",
        value_bool=False,
    )


def door_type(operation: str) -> int:
    """The ``rmf_building_map_msgs/Door`` type of an IFC door ``OperationType`` (IFC4
    ``IfcDoorTypeOperationEnum``, IFC2X3 ``IfcDoorStyleOperationEnum``, IFC4X3's additions)."""
    if not operation or operation in ("NOTDEFINED", "USERDEFINED"):
        return DOOR_TYPE_SINGLE_SWING  # the model does not say: the common door
    double = operation.startswith("DOUBLE_DOOR")
    if "SLIDING" in operation:
        return DOOR_TYPE_DOUBLE_SLIDING if double else DOOR_TYPE_SINGLE_SLIDING
    if "SWING" in operation:
        return DOOR_TYPE_DOUBLE_SWING if double else DOOR_TYPE_SINGLE_SWING
    return DOOR_TYPE_UNDEFINED  # revolving, folding, rolling up, lifting: no RMF door type


def _empty_graph() -> Any:
    return _msg("Graph", name="", vertices=[], edges=[], params=[])


def _node(v: RouteVertex, config: LevelConfig | None) -> Any:
    x, y = to_level(config, v.x, v.y)
    params = [
        _param("is_holding_point", v.holding_point),
        _param("is_parking_spot", v.parking_spot),
        _param("is_charger", v.charger),
    ]
    if v.lift:
        params.append(_param("lift", v.lift))
    if v.dock:
        params.append(_param("dock_name", v.dock))
    return _msg("GraphNode", x=x, y=y, name=v.name, params=params)


def building_map(
    graphs: Sequence[RouteGraph],
    maps: Mapping[str, OccupancyGrid],
    *,
    building: str,
    levels: Mapping[str, tuple[str, LevelConfig]] | None = None,
) -> Any:
    """The ``BuildingMap`` message (a rosbags message object) of ``graphs`` over the storeys' ``maps``
    (storey key -> the map drawn as each level's image)."""
    levels = levels or {}
    storeys: dict[str, float] = {}
    for graph in graphs:
        for s in graph.storeys:
            storeys.setdefault(s.storey, s.elevation_m)
    for key, storey_map in maps.items():
        storeys.setdefault(key, storey_map.elevation_m)
    out_levels = []
    for key, elevation in sorted(storeys.items(), key=lambda kv: (kv[1], kv[0])):
        name, config = levels.get(key, (key, None))
        images = []
        grid = maps.get(key)
        if grid is not None:
            ox, oy = to_level(config, grid.frame.origin_x, grid.frame.origin_y)
            yaw = -(config.yaw_rad if config is not None else 0.0)
            images.append(
                _msg(
                    "AffineImage",
                    name=f"{key}__{grid.skill}",
                    x_offset=ox,
                    y_offset=oy,
                    yaw=yaw,
                    scale=grid.frame.resolution_m,
                    encoding="png",
                    data=_bytes(png_bytes(grid)),
                )
            )
        doors: dict[str, Any] = {}
        nav_graphs = []
        for graph in graphs:
            for door in graph.doors:
                if door.storey == key and door.name not in doors:
                    (x1, y1), (x2, y2) = (to_level(config, *p) for p in door.endpoints)
                    doors[door.name] = _msg(
                        "Door",
                        name=door.name,
                        v1_x=x1,
                        v1_y=y1,
                        v2_x=x2,
                        v2_y=y2,
                        door_type=(kind := door_type(door.operation)),
                        motion_range=(
                            DOOR_MOTION_RANGE_DEG
                            if kind in (DOOR_TYPE_SINGLE_SWING, DOOR_TYPE_DOUBLE_SWING)
                            else 0.0
                        ),
                        motion_direction=door.swing or 1,
                    )
            served = [s for s in graph.storeys if s.storey == key]
            if not served:
                continue
            s = served[0]
            edges = []
            for lane in s.lanes:
                params = [_param("speed_limit", graph.speed_m_s)]
                if lane.door:
                    params.append(_param("door_name", lane.door))
                edges.append(
                    _msg(
                        "GraphEdge",
                        v1_idx=lane.a,
                        v2_idx=lane.b,
                        params=params,
                        edge_type=EDGE_TYPE_UNIDIRECTIONAL if lane.one_way else EDGE_TYPE_BIDIRECTIONAL,
                    )
                )
            nav_graphs.append(
                _msg(
                    "Graph",
                    name=graph.graph_name,
                    vertices=[_node(v, config) for v in s.vertices],
                    edges=edges,
                    params=[_param("fleet", graph.fleet)],
                )
            )
        out_levels.append(
            _msg(
                "Level",
                name=name,
                elevation=elevation,
                images=images,
                places=[],
                doors=list(doors.values()),
                nav_graphs=nav_graphs,
                wall_graph=_empty_graph(),
            )
        )
    lifts: dict[str, Any] = {}
    for graph in graphs:
        for lift in graph.lifts:
            if lift.name in lifts:
                continue
            first = levels.get(lift.storeys[0], (lift.storeys[0], None))[1]
            x, y = to_level(first, lift.x, lift.y)
            yaw = lift.yaw - (first.yaw_rad if first is not None else 0.0)
            lifts[lift.name] = _msg(
                "Lift",
                name=lift.name,
                levels=[levels.get(k, (k, None))[0] for k in lift.storeys],
                doors=[],
                wall_graph=_empty_graph(),
                ref_x=x,
                ref_y=y,
                ref_yaw=yaw,
                width=lift.width_m,
                depth=lift.depth_m,
            )
    return _msg("BuildingMap", name=building, levels=out_levels, lifts=list(lifts.values()))


def _bytes(blob: bytes) -> Any:
    return np.frombuffer(blob, dtype=np.uint8).copy()


def encode_building_map(
    graphs: Sequence[RouteGraph],
    maps: Mapping[str, OccupancyGrid],
    *,
    building: str,
    levels: Mapping[str, tuple[str, LevelConfig]] | None = None,
) -> bytes:
    """The CDR bytes of :func:`building_map`."""
    return _serialize(building_map(graphs, maps, building=building, levels=levels), BUILDING_MAP)


def decode_building_map(payload: bytes | bytearray | memoryview) -> Any:
    """The ``BuildingMap`` message object of CDR ``payload`` (a MapError if it is not one)."""
    return _deserialize(payload, BUILDING_MAP)
