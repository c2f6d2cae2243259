"""A fleet's route graph as plain records: waypoints and lanes per storey, doors and lifts.

Coordinates are the twin's map frame (the building's XY plane, metres), as the skill maps' grids;
the writers for Open-RMF and nav2 (``adapters/ros/routes.py``) move them into each RMF level's frame.
A lane is two-way unless ``one_way`` (then from ``a`` to ``b`` only: a configured one-way stretch,
:mod:`twin.routes.one_way`); the writers write a two-way lane in both directions, a one-way lane once.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import networkx as nx

__all__ = ["DoorCrossing", "Lift", "RouteGraph", "RouteLane", "RouteVertex", "StoreyRoutes"]


@dataclass(frozen=True, slots=True)
class RouteVertex:
    """A waypoint: position (m), its unique name (``""``: none) and what RMF should know of it."""

    x: float
    y: float
    name: str = ""
    kind: str = "lane"
    """``lane`` (on the medial axis), ``door`` (beside a door), ``space`` (an IfcSpace's most interior
    point), ``lift`` (in a lift's cabin) or ``waypoint`` (configured)."""
    lift: str = ""
    charger: bool = False
    holding_point: bool = False
    parking_spot: bool = False
    dock: str = ""


@dataclass(frozen=True, slots=True)
class RouteLane:
    """A lane between vertices ``a`` and ``b`` (indices into the storey's vertices): two-way, or from
    ``a`` to ``b`` only when ``one_way``."""

    a: int
    b: int
    door: str = ""
    """The name of the door the lane passes through (``""``: none)."""
    one_way: bool = False


@dataclass(frozen=True, slots=True)
class DoorCrossing:
    """A door on a storey: its name, where its leaf lies (two endpoints, m) and whether the fleet's
    robot fits through it (then a lane passes it, carrying its name).

    ``operation`` is the IFC door's ``OperationType`` ("" when the model does not say). For a door
    hinged or sliding to one side (``*_LEFT``, ``*_RIGHT``) whose placement's x axis lies along its
    width, ``endpoints[0]`` is the hinge (or the end the leaf slides towards) and ``swing`` the way
    it opens seen from above: ``1`` clockwise, ``-1`` anticlockwise (opening towards the door's local
    +y); ``0`` when unknown."""

    name: str
    iri: str
    storey: str
    endpoints: tuple[tuple[float, float], tuple[float, float]]
    width_m: float
    passable: bool
    operation: str = ""
    swing: int = 0


@dataclass(frozen=True, slots=True)
class Lift:
    """A lift: its name, cabin centre (m), yaw (rad), cabin size (width, depth, m), the storeys it
    serves (keys, bottom up)."""

    name: str
    iri: str
    x: float
    y: float
    yaw: float
    width_m: float
    depth_m: float
    storeys: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class StoreyRoutes:
    """One storey's part of the graph."""

    storey: str
    elevation_m: float
    vertices: tuple[RouteVertex, ...]
    lanes: tuple[RouteLane, ...]


@dataclass(frozen=True, slots=True)
class RouteGraph:
    """A fleet's route graph of the building: every storey it serves, its doors and lifts."""

    skill: str
    fleet: str
    graph_name: str
    building: str
    speed_m_s: float
    robot_radius_m: float
    storeys: tuple[StoreyRoutes, ...]
    doors: tuple[DoorCrossing, ...] = ()
    lifts: tuple[Lift, ...] = ()
    notes: tuple[str, ...] = field(default=())
    """What the graph could not do (a door too narrow, a space not reachable), one line each."""

    def storey(self, key: str) -> StoreyRoutes:
        for s in self.storeys:
            if s.storey == key:
                return s
        msg = f"The route graph {self.skill!r} serves no storey {key!r}."
        raise KeyError(msg)

    def to_networkx(self) -> nx.DiGraph:
        """The whole graph (every storey, joined at the lifts) as a weighted, directed networkx graph:
        nodes ``(storey, index)`` with ``x``, ``y``; a two-way lane as an edge each way, a one-way
        lane as one edge its way, each weighted by its length; lift hops both ways, weighted 0.
        ``g.to_undirected()`` gives the lanes without their direction."""
        import networkx as nx  # noqa: PLC0415 (the daemon's events hold route graphs, few walk them)

        g = nx.DiGraph()
        for s in self.storeys:
            for i, v in enumerate(s.vertices):
                g.add_node((s.storey, i), x=v.x, y=v.y, name=v.name, lift=v.lift)
            for lane in s.lanes:
                a, b = s.vertices[lane.a], s.vertices[lane.b]
                ways = ((lane.a, lane.b),) if lane.one_way else ((lane.a, lane.b), (lane.b, lane.a))
                for u, w in ways:
                    g.add_edge((s.storey, u), (s.storey, w), weight=_dist(a, b), door=lane.door)
        for lift in self.lifts:
            stops = [
                (s.storey, i) for s in self.storeys for i, v in enumerate(s.vertices) if v.lift == lift.name
            ]
            for stop, next_stop in itertools.pairwise(stops):
                g.add_edge(stop, next_stop, weight=0.0, lift=lift.name)
                g.add_edge(next_stop, stop, weight=0.0, lift=lift.name)
        return g

    def to_json(self) -> dict[str, Any]:
        """The graph as JSON (what ``twin/<site>/routes/<skill>`` carries)."""
        return {
            "skill": self.skill,
            "fleet": self.fleet,
            "graph_name": self.graph_name,
            "building": self.building,
            "speed_m_s": self.speed_m_s,
            "robot_radius_m": self.robot_radius_m,
            "storeys": [
                {
                    "storey": s.storey,
                    "elevation_m": s.elevation_m,
                    "vertices": [_vertex_json(v) for v in s.vertices],
                    "lanes": [[lane.a, lane.b, lane.door] for lane in s.lanes],
                }
                | _one_way_json(s)
                for s in self.storeys
            ],
            "doors": [
                {
                    "name": d.name,
                    "iri": d.iri,
                    "storey": d.storey,
                    "endpoints": [list(p) for p in d.endpoints],
                    "width_m": d.width_m,
                    "passable": d.passable,
                }
                | ({"operation": d.operation} if d.operation else {})
                | ({"swing": d.swing} if d.swing else {})
                for d in self.doors
            ],
            "lifts": [
                {
                    "name": lift.name,
                    "iri": lift.iri,
                    "position": [lift.x, lift.y, lift.yaw],
                    "dims": [lift.width_m, lift.depth_m],
                    "storeys": list(lift.storeys),
                }
                for lift in self.lifts
            ],
            "notes": list(self.notes),
        }


def _one_way_json(s: StoreyRoutes) -> dict[str, Any]:
    """``one_way``: the indices of the storey's one-way lanes (each from its first vertex to its
    second), only when it has some."""
    one_way = [i for i, lane in enumerate(s.lanes) if lane.one_way]
    return {"one_way": one_way} if one_way else {}


def _vertex_json(v: RouteVertex) -> dict[str, Any]:
    out: dict[str, Any] = {"x": v.x, "y": v.y, "kind": v.kind}
    for key in ("name", "lift", "dock"):
        if getattr(v, key):
            out[key] = getattr(v, key)
    for key in ("charger", "holding_point", "parking_spot"):
        if getattr(v, key):
            out[key] = True
    return out


def _dist(a: RouteVertex, b: RouteVertex) -> float:
    return float(((a.x - b.x) ** 2 + (a.y - b.y) ** 2) ** 0.5)
