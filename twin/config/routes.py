"""A routes skill (``[skills.NAME] kind = "routes"``): one fleet's route graph of the building.

It names the navigation skill whose map it follows (the robot's height and inflation radius, so
fleets of different size get different graphs of the same building) and says what Open-RMF and nav2
need to know about the fleet::

    [skills.cleaners]
    kind = "routes"
    navigation = "lab-navigation"    # its map, robot height and inflation_radius_m
    fleet = "cleaners"               # the fleet name RMF uses (default: the skill's name)
    graph_name = "cleaners"          # the nav2 graph's name (default: the skill's name)
    speed_m_s = 0.5                  # nominal speed: every lane's speed limit
    storeys = ["ground-floor"]       # storeys served (default: every storey)
    keepout = ["keepout"]            # keepout skills whose zones no lane crosses
    max_lane_m = 3.0                 # no lane longer than this
    spacing_m = 0.5                  # vertices this far apart along lanes and in open rooms
    small_region_m2 = 12.0           # free regions under this get a lattice half spacing_m apart
    pocket_m2 = 1.0                  # free regions under this with nothing in them: noted pockets
    lift_types = ["ELEVATOR"]        # IfcTransportElement predefined types that are lifts
    outdoors = false                 # lanes only over the storeys' floors (slabs, spaces, entrances)
    waypoints.charger1 = { storey = "ground-floor", x = 12.0, y = 8.0, charger = true }
    waypoints.desk = { at = "Room A", parking_spot = true }    # an IfcSpace's name
    one_way = [{ x1 = 4.5, y1 = 2.0, x2 = 7.5, y2 = 2.0 }]      # lanes along it: this way only
    one_way = [{ door = "Door A", x2 = 12.0, y2 = 7.0 }]       # through Door A towards (12, 7) only

The core checks the table here (:func:`parse_routes`); :func:`check_routes` then checks its references
against the other skills.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, Literal

from pydantic import Field, ValidationError, model_validator

from twin.config.base import ConfigTable, Flag, Number, Text, list_of
from twin.config.messages import config_error
from twin.errors import ConfigError, RouteError
from twin.selection.skills import SkillProfile

__all__ = [
    "OneWay",
    "OneWayTable",
    "RouteProfile",
    "RoutesTable",
    "Waypoint",
    "WaypointTable",
    "check_routes",
    "parse_routes",
]

_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}$")


class WaypointTable(ConfigTable):
    """A named waypoint: a position on a storey, or ``at`` an IfcSpace's name."""

    storey: Text | None = Field(None, description="The storey key of a waypoint given by position.")
    x: Number | None = Field(None, description="x in the building's (map) frame, metres.")
    y: Number | None = Field(None, description="y in the building's (map) frame, metres.")
    at: Text | None = Field(
        None, description="An IfcSpace's name: the waypoint is at its most interior point."
    )
    charger: Flag = Field(False, description="RMF is_charger.")
    holding_point: Flag = Field(False, description="RMF is_holding_point.")
    parking_spot: Flag = Field(False, description="RMF is_parking_spot.")
    dock: Text = Field("", description="RMF dock_name of the lanes into this waypoint.")

    @model_validator(mode="after")
    def _where(self) -> WaypointTable:
        by_position = self.storey is not None and self.x is not None and self.y is not None
        if by_position == (self.at is not None) or (
            self.at is not None and (self.storey, self.x, self.y) != (None, None, None)
        ):
            msg = "give either storey, x and y, or at (a space's name)"
            raise ValueError(msg)
        return self


class OneWayTable(ConfigTable):
    """A one-way stretch: the lanes along the segment (x1, y1) -> (x2, y2) go that way only; or a
    one-way door: the lane through ``door`` goes towards (x2, y2) only."""

    x1: Number | None = Field(None, description="Start x in the building's (map) frame, metres.")
    y1: Number | None = Field(None, description="Start y, metres.")
    x2: Number = Field(description="End x, metres: lanes along the segment go from start to end.")
    y2: Number = Field(description="End y, metres.")
    door: Text | None = Field(
        None,
        description="A door's name (its RMF name or IFC name): its lane goes only towards (x2, y2), "
        "the end nearer that point; give no x1, y1.",
    )
    storey: Text | None = Field(None, description="The storey key (default: every storey served).")
    within_m: Annotated[Number, Field(gt=0, le=10)] = Field(
        0.5, description="A lane is along the segment when both its ends lie within this of it, metres."
    )

    @model_validator(mode="after")
    def _length(self) -> OneWayTable:
        if self.door is not None:
            if self.x1 is not None or self.y1 is not None:
                msg = f"one-way door {self.door!r}: give x2, y2 (the side it goes to), not x1, y1"
                raise ValueError(msg)
            return self
        if self.x1 is None or self.y1 is None:
            msg = "give x1, y1, x2, y2 (a stretch) or door, x2, y2 (a one-way door)"
            raise ValueError(msg)
        if math.hypot(self.x2 - self.x1, self.y2 - self.y1) < 0.1:
            msg = f"the segment ({self.x1}, {self.y1}) -> ({self.x2}, {self.y2}) is shorter than 0.1 m"
            raise ValueError(msg)
        return self


class RoutesTable(ConfigTable):
    """The keys of a ``kind = "routes"`` skill."""

    kind: Literal["routes"]
    navigation: Text = Field(description="The navigation skill whose map and inflation the graph follows.")
    fleet: Text | None = Field(None, description="The fleet name RMF uses (default: the skill's name).")
    graph_name: Text | None = Field(None, description="The graph's name (default: the skill's name).")
    speed_m_s: Annotated[Number, Field(gt=0, le=20)] = Field(0.5, description="Nominal speed, m/s.")
    storeys: Annotated[tuple[Text, ...], list_of("storey keys")] = Field(
        (), description="Storey keys served (default: every storey)."
    )
    keepout: Annotated[tuple[Text, ...], list_of("keepout skills")] = Field(
        (), description="Keepout skills whose zones no lane crosses."
    )
    max_lane_m: Annotated[Number, Field(ge=0.5, le=100)] = Field(3.0, description="Longest lane, metres.")
    spacing_m: Annotated[Number, Field(ge=0.2, le=5)] = Field(
        0.5,
        description=(
            "Largest gap between vertices along a lane and the spacing of the open-space lattice, metres "
            "(at most max_lane_m): finer gives shorter routes between close points, and more vertices."
        ),
    )
    small_region_m2: Annotated[Number, Field(ge=0, le=10_000)] = Field(
        12.0,
        description=(
            "Free regions under this area (m²; rooms whose doors the robot does not fit) get their "
            "open-space lattice half spacing_m apart when most of a storey's free space is in them; 0: never."
        ),
    )
    pocket_m2: Annotated[Number, Field(ge=0, le=10_000)] = Field(
        1.0,
        description=(
            "Free regions under this area (m²) with no space, lift or waypoint are pockets: kept on the "
            "graph, joined to nothing outside, and listed in one note per storey; 0: none noted."
        ),
    )
    lift_types: Annotated[tuple[Text, ...], list_of("IfcTransportElement predefined types")] = Field(
        ("ELEVATOR",),
        description=(
            "The IfcTransportElement predefined types (IFC2X3: operation types) that are lifts; "
            "NOTDEFINED takes elements whose type the model does not say."
        ),
    )
    open_door_operations: Flag = Field(
        False, description="nav2 GeoJSON: an open_door operation on door edges (the plugin must exist)."
    )
    outdoors: Flag = Field(
        False,
        description="Lanes also where the storey has no floor (slab or space): outside the building.",
    )
    waypoints: dict[str, WaypointTable] = Field(default_factory=dict, description="Named waypoints.")
    one_way: tuple[OneWayTable, ...] = Field(
        (), description="One-way stretches: the lanes along each segment go from (x1, y1) to (x2, y2) only."
    )
    description: Text = ""


class _RoutesFile(ConfigTable):
    skills: dict[str, RoutesTable]


@dataclass(frozen=True, slots=True)
class Waypoint:
    """A configured waypoint: by position (``storey``, ``x``, ``y``) or ``at`` a named space."""

    name: str
    storey: str | None = None
    x: float = 0.0
    y: float = 0.0
    at: str | None = None
    charger: bool = False
    holding_point: bool = False
    parking_spot: bool = False
    dock: str = ""


@dataclass(frozen=True, slots=True)
class OneWay:
    """A one-way stretch (metres, the map frame): lanes within ``within_m`` of the segment go from
    (x1, y1) towards (x2, y2) only; or, with ``door``, the lane through that door goes only towards
    its end nearer (x2, y2). ``storey`` None: every storey served."""

    x1: float
    y1: float
    x2: float
    y2: float
    storey: str | None = None
    within_m: float = 0.5
    door: str | None = None


@dataclass(frozen=True, slots=True)
class RouteProfile:
    """A validated routes skill. Lengths in metres, speeds in m/s."""

    name: str
    navigation: str
    fleet: str
    graph_name: str
    speed_m_s: float = 0.5
    storeys: tuple[str, ...] = ()
    keepout: tuple[str, ...] = ()
    max_lane_m: float = 3.0
    spacing_m: float = 0.5
    small_region_m2: float = 12.0
    pocket_m2: float = 1.0
    lift_types: tuple[str, ...] = ("ELEVATOR",)
    open_door_operations: bool = False
    outdoors: bool = False
    waypoints: tuple[Waypoint, ...] = ()
    one_way: tuple[OneWay, ...] = ()
    description: str = ""


def parse_routes(name: str, data: Mapping[str, Any]) -> RouteProfile:
    """Validate a ``kind = "routes"`` table; a :class:`~twin.errors.ConfigError` names the bad key."""
    try:
        table = _RoutesFile.model_validate({"skills": {name: data}}).skills[name]
    except ValidationError as err:
        raise config_error(err, _RoutesFile) from None
    for wp in table.waypoints:
        if not _NAME.match(wp):
            msg = f"Configuration [skills.{name}] waypoint name {wp!r}: expected 1-64 of [A-Za-z0-9_.-]."
            raise ConfigError(msg)
    return RouteProfile(
        name=name,
        navigation=table.navigation,
        fleet=table.fleet or name,
        graph_name=table.graph_name or name,
        speed_m_s=table.speed_m_s,
        storeys=tuple(dict.fromkeys(table.storeys)),
        keepout=tuple(dict.fromkeys(table.keepout)),
        max_lane_m=table.max_lane_m,
        spacing_m=min(table.spacing_m, table.max_lane_m),
        small_region_m2=table.small_region_m2,
        pocket_m2=table.pocket_m2,
        lift_types=tuple(dict.fromkeys(t.upper() for t in table.lift_types)),
        open_door_operations=table.open_door_operations,
        outdoors=table.outdoors,
        waypoints=tuple(
            Waypoint(
                name=wp,
                storey=t.storey,
                x=t.x or 0.0,
                y=t.y or 0.0,
                at=t.at,
                charger=t.charger,
                holding_point=t.holding_point,
                parking_spot=t.parking_spot,
                dock=t.dock,
            )
            for wp, t in table.waypoints.items()
        ),
        one_way=tuple(
            OneWay(o.x1 or 0.0, o.y1 or 0.0, o.x2, o.y2, o.storey, o.within_m, o.door) for o in table.one_way
        ),
        description=table.description,
    )


def check_routes(routes: RouteProfile, skills: Mapping[str, SkillProfile]) -> None:
    """Refuse a routes skill whose navigation or keepout skills are missing or of another kind."""
    nav = skills.get(routes.navigation)
    if nav is None or nav.kind != "navigation":
        known = ", ".join(sorted(n for n, s in skills.items() if s.kind == "navigation")) or "none"
        what = "is not configured" if nav is None else f"is a {nav.kind} skill"
        msg = (
            f"Routes skill {routes.name!r}: navigation skill {routes.navigation!r} {what}; "
            f"navigation skills: {known}."
        )
        raise RouteError(msg)
    for name in routes.keepout:
        keepout = skills.get(name)
        if keepout is None or keepout.kind != "keepout":
            msg = f"Routes skill {routes.name!r}: keepout {name!r} is not a configured keepout skill."
            raise RouteError(msg)
