"""Route graphs: the waypoints and lanes fleet managers plan on, generated from the twin.

Open-RMF (fleet adapters, the traffic schedule, door and lift sessions) and nav2's Route Server plan
on a route graph. A ``kind = "routes"`` skill (:mod:`twin.config.routes`) makes one per fleet from
the twin: lanes along the middle of the free space of the fleet's navigation map (its robot's radius
and height), a lane through every door the robot fits through carrying the door's name, a named
vertex per space, lifts joining the storeys (:mod:`twin.routes.build`, :mod:`twin.routes.storey`).
The graph is plain records (:mod:`twin.routes.graph`); ``adapters/ros/routes.py`` writes it for
Open-RMF (nav graph YAML) and nav2 (GeoJSON).

Example::

    graph = build_routes(store, scene, cfg.routes["cleaners"], cfg.skills, margin_m=cfg.margin_m)
"""

from __future__ import annotations

from twin.config.routes import RouteProfile, Waypoint, check_routes, parse_routes
from twin.errors import RouteError

__all__ = ["RouteError", "RouteProfile", "Waypoint", "check_routes", "parse_routes"]
