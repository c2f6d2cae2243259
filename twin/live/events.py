"""What the twin service tells the outside world: events, and the sinks that receive them.

The service (:mod:`twin.live`) is the single writer of the twin. After every committed change it
emits events, in order, to each :class:`TwinSink` it was given: the Zenoh publishers, the Rerun
recorder, a test's list. A sink's ``emit`` runs on the service's thread and must return quickly (hand
slow work, such as writing a recording, to a thread of its own); an exception in a sink is logged and
never stops the service or the other sinks.

Events carry plain records (grids as numpy arrays, meshes as :class:`~twin.records.Mesh`) and never a
transport type. Times are integer nanoseconds since the Unix epoch (``stamp_ns``).

Example::

    class Printer:
        def emit(self, event: TwinEvent) -> None:
            if isinstance(event, MapUpdated):
                print(event.storey, event.skill, event.version, event.window)

    service = TwinService(store, config, sinks=[Printer()])
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

from twin.maps.grid import GridData, GridFrame, OccupancyGrid, Window
from twin.maps.points import PointCloud
from twin.records import FloatArray, Mesh
from twin.routes.graph import RouteGraph
from twin.selection.skills import SkillProfile


@dataclass(frozen=True, eq=False, slots=True)
class ElementShape:
    """An element as the twin holds it: its identity, class, and geometry (local mesh + placement).

    Elements that share a representation share one :class:`Mesh` object (``mesh is other.mesh``), so
    a sink can log each distinct mesh once and place it many times.
    """

    iri: str
    ifc_class: str
    name: str
    storey: str | None
    """Storey key, when the element belongs to one."""
    mesh: Mesh
    placement: FloatArray
    is_static: bool = True
    is_open: bool | None = None
    """For doors: True when observed open, False when observed closed, None when never observed."""


@dataclass(frozen=True, eq=False, slots=True)
class TwinStarted:
    """The service has loaded the twin and is about to publish its maps (sent once, first)."""

    site: str
    revision: int
    stamp_ns: int
    storeys: tuple[tuple[str, str, float], ...]
    """``(key, name, elevation_m)`` of every storey, lowest first."""
    elements: tuple[ElementShape, ...]
    skills: Mapping[str, SkillProfile]


@dataclass(frozen=True, eq=False, slots=True)
class MapPublished:
    """A full map version: the first of a (storey, skill), or the latest after changes (latched)."""

    grid: OccupancyGrid
    revision: int
    version: int
    stamp_ns: int


@dataclass(frozen=True, eq=False, slots=True)
class MapUpdated:
    """The changed rectangle of a map (``data`` holds the new values of ``window``, row 0 = lowest y).

    ``version`` is the version of the whole map this update brings a copy to; a client that holds
    ``version - 1`` applies it, one that holds less has missed an update and fetches the full map.
    """

    storey: str
    skill: str
    frame: GridFrame
    window: Window
    data: GridData
    revision: int
    version: int
    stamp_ns: int


@dataclass(frozen=True, slots=True)
class MapRemoved:
    """A map no longer exists (its skill was removed)."""

    storey: str
    skill: str
    revision: int
    stamp_ns: int


@dataclass(frozen=True, slots=True)
class MapChange:
    """What an acknowledgement reports per changed map: its new version and changed cells."""

    storey: str
    skill: str
    version: int
    window: Window

    def as_json(self) -> dict[str, object]:
        return {
            "storey": self.storey,
            "skill": self.skill,
            "version": self.version,
            "x": self.window.col0,
            "y": self.window.row0,
            "width": self.window.shape[1],
            "height": self.window.shape[0],
        }


@dataclass(frozen=True, eq=False, slots=True)
class ObservationAccepted:
    """A robot's observation is committed: the elements it added or changed, and those it removed."""

    robot: str
    revision: int
    stamp_ns: int
    upserted: tuple[ElementShape, ...]
    """The new state of every element the observation created or changed (with its geometry); an
    element whose geometry did not change (a door opened) is here too."""
    removed: tuple[str, ...]
    maps: tuple[MapChange, ...]
    notes: tuple[str, ...] = ()
    """What fusion decided (merges, refined poses, removals by absence, stale parts), one line each."""


@dataclass(frozen=True, slots=True)
class ObservationNoted:
    """An observation changed nothing, but fusion has something to say (a stale sighting refused)."""

    robot: str
    revision: int
    stamp_ns: int
    notes: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class ObservationRejected:
    """A robot's observation was refused; the twin is unchanged. ``error`` says what was wrong."""

    robot: str
    error: str
    stamp_ns: int
    size_bytes: int


@dataclass(frozen=True, slots=True)
class SkillChanged:
    """A skill profile was added or replaced (``profile`` set) or removed (``profile`` None) at run time."""

    name: str
    profile: SkillProfile | None
    revision: int
    stamp_ns: int


@dataclass(frozen=True, slots=True)
class RobotStoreyChanged:
    """A robot's current storey changed at run time (it took the lift): every map topic of the robot
    now carries ``storey``'s maps. ``source`` says who asked: ``"zenoh"`` (a put or get on
    ``robots/<robot>/storey``) or ``"ros"`` (the robot's ``/<ns>/storey`` topic). ``revision`` is the
    twin revision at the switch (a switch changes no twin data, so it commits none)."""

    robot: str
    storey: str
    previous: str | None
    source: str
    revision: int
    stamp_ns: int


@dataclass(frozen=True, eq=False, slots=True)
class PointsPublished:
    """A points map's whole cloud (latched). ``sensor_msgs/PointCloud2`` has no update message: a
    changed cloud is published whole again, at most once per ``interval`` (see
    :class:`twin.live.live_points.PointsPublication`)."""

    cloud: PointCloud
    revision: int
    version: int
    stamp_ns: int


@dataclass(frozen=True, eq=False, slots=True)
class RoutesPublished:
    """A routes skill's graph served as ``version`` (1 at start, then one more per structural change
    that changed it). ``navigation`` is the navigation skill whose maps the graph follows. Not emitted
    by the service: ``twin serve``'s route graphs (:mod:`adapters.cli.route_updates`) send it to the
    recorder."""

    graph: RouteGraph
    navigation: str
    version: int
    stamp_ns: int


TwinEvent = (
    TwinStarted
    | MapPublished
    | PointsPublished
    | MapUpdated
    | MapRemoved
    | ObservationAccepted
    | ObservationNoted
    | ObservationRejected
    | SkillChanged
    | RobotStoreyChanged
    | RoutesPublished
)


class TwinSink(Protocol):
    """Receives the service's events, in order, on the service's thread: return quickly."""

    def emit(self, event: TwinEvent) -> None: ...
