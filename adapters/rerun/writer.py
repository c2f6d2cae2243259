"""The recording writer: turns the twin's events into Rerun logs, owns the SDK's recording stream and
the files (rotation). It runs in the recorder process (:mod:`adapters.rerun.child`), so the SDK's work
never competes with the daemon's writer for the GIL. What is recorded (entity paths):

- ``world/<storey>/<class>/<element>``: the building (static), one mesh per element with its placement,
  coloured by class, with its IRI, class and name as properties (shown on hover and selection);
- ``maps/<storey>/<skill>/tiles/r<i>_c<j>``: every map as tiles, exact at every revision
  (:mod:`adapters.rerun.tiles`); ``maps/<storey>/<skill>`` carries its version and revision;
  ``maps/<storey>/<skill>/changed``: the changed rectangle of each update, as a 3D box;
- ``world/observations/<robot>/<element>``: what robots added or changed (cleared when removed), with
  who saw it, when and at which revision;
- ``maps/<storey>/<routes skill>``: a routes skill's graph over its navigation map, at every graph
  version: ``lanes`` (``LineStrips3D``, door lanes orange), ``one_way`` (``Arrows3D``: the way of each
  one-way lane) and ``vertices`` (``Points3D`` labelled with their names), 2 cm above the storey's
  floor, and the graph's version;
- ``events``: one text line per observation (accepted with its revision, or the rejection reason),
  skill change, map removal and robot storey switch.

Timelines: ``revision`` (the twin revision the data reflects) and ``time`` (wall clock of the change).

**Rotation** (``rotate_every_s``, ``max_bytes``): the recording continues in ``<name>-0001.rrd``,
``-0002`` ... each starting with the building, every current map (all tiles), every points skill's
current cloud and what robots observed, at the current revision, so any file replays on its own.
"""

from __future__ import annotations

import datetime
import logging
import time
from collections.abc import Collection
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from adapters.rerun.style import OBSERVED, Rgba, blueprint_of, colour_of, entity_name
from adapters.rerun.tiles import TILE, MapMark, MapTiles, tiles_of, tiles_path
from twin.live.events import (
    ElementShape,
    MapPublished,
    MapRemoved,
    MapUpdated,
    ObservationAccepted,
    ObservationNoted,
    ObservationRejected,
    PointsPublished,
    RobotStoreyChanged,
    RoutesPublished,
    SkillChanged,
    TwinEvent,
    TwinStarted,
)

log = logging.getLogger(__name__)

FILE_FLUSH_S = 10.0
"""How long a file's rows are batched before they are written (per entity)."""

Recordable = TwinEvent | MapMark

ROUTES_LIFT_M = 0.02
"""How far above the storey's floor (and its maps) the route graphs are drawn."""
_LANE: Rgba = (40, 140, 255, 255)
_DOOR_LANE: Rgba = (255, 140, 0, 255)
_ONE_WAY: Rgba = (0, 200, 200, 255)
_VERTEX_COLOURS: dict[str, Rgba] = {
    "lane": (40, 140, 255, 255),
    "door": (255, 140, 0, 255),
    "space": (60, 200, 90, 255),
    "lift": (200, 60, 200, 255),
    "waypoint": (230, 40, 40, 255),
}
Seen = tuple[str, int, int]  # (robot, revision, time ns) of an observation


def _same_mesh(a: ElementShape, b: ElementShape) -> bool:
    return a.mesh is b.mesh or (
        np.array_equal(a.mesh.vertices, b.mesh.vertices) and np.array_equal(a.mesh.faces, b.mesh.faces)
    )


class RecordingWriter:
    """Writes events to an ``.rrd`` file (rotated) and/or a live viewer, in the order they come.

    It keeps its own copy of every map (``_maps``: :class:`~adapters.rerun.tiles.MapTiles`, updates
    applied), a second holder beside the daemon's ``LatestMaps`` for three reasons: it runs in the
    recorder process, which cannot read the daemon's memory; it must hold each map *as of the revision
    it is recording*, which lags the daemon's latest version by its queue; and it needs the cells to
    log only the tiles a full map changes (:meth:`MapTiles.replace`) and to log every tile again at
    the start of a rotated file. It is written by the events alone, so it equals the daemon's holder
    once both have taken the same events.
    """

    def __init__(
        self,
        *,
        path: Path | None = None,
        connect_url: str | None = None,
        application: str = "building-twin",
        rotate_every_s: float = 0.0,
        max_bytes: int = 0,
    ) -> None:
        self.path = path
        self.connect_url = connect_url
        self.application = application
        self.rotate_every_s = rotate_every_s
        self.max_bytes = max_bytes
        self.files: list[Path] = []
        """Every file written so far, in order (the first is ``path``)."""
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
        self.stream = self._open(path)
        self._opened = time.monotonic()
        self._started_event: TwinStarted | None = None
        self._observed: dict[str, tuple[ElementShape, Rgba, Seen]] = {}
        self._now: tuple[int, int] = (0, 0)  # (revision, stamp) of the last recorded event
        self._storeys: dict[str, float] = {}
        self._maps: dict[tuple[str, str], MapTiles] = {}
        self._placed: dict[tuple[str, str], int] = {}
        """Per map, the last generation of tiles this file holds (kept on removal)."""
        self._clouds: dict[tuple[str, str], rr.Points3D] = {}
        """Per points map, its latest cloud as logged (what a new file starts with)."""
        self._routes: dict[str, RoutesPublished] = {}
        """Per routes skill, its latest graph as logged (what a new file starts with)."""

    # --- files -------------------------------------------------------------------------------------
    def _open(self, path: Path | None) -> rr.RecordingStream:
        # Files batch each entity's rows for 10 s: fewer, larger chunks (each carries its own schema,
        # ~1 KB) in which a tile's successive versions compress against each other (Janesville: 7.4
        # -> 5.4 KB per observation against 2 s); a live viewer keeps the SDK's 200 ms. No footer: its
        # manifest grows with every chunk, in the file (~3 KB per chunk) and in memory; the viewer
        # reads the file without it. A daemon that dies still gets its file flushed: the recorder
        # process closes it at the end of its input.
        tick = 0.2 if self.connect_url else FILE_FLUSH_S
        # A batch flushes early at 2 MB: with 8 MB the recorder process's memory grew without bound
        # under a soak's load (+300 MB in 3 minutes); with 2 MB it stays flat, files as small.
        batcher = rr.ChunkBatcherConfig(
            flush_tick=datetime.timedelta(seconds=tick), flush_num_bytes=2 * 2**20, flush_num_rows=2**20
        )
        stream = rr.RecordingStream(application_id=self.application, batcher_config=batcher)
        stream.set_log_time_enabled(False)  # the ``time`` timeline holds when each change happened
        sinks: list[rr.FileSink | rr.GrpcSink] = []
        if path is not None:
            sinks.append(rr.FileSink(str(path), write_footer=False))
            self.files.append(path)
        if self.connect_url:
            sinks.append(rr.GrpcSink(self.connect_url))
        if sinks:
            stream.set_sinks(*sinks)
        return stream

    def _due(self) -> bool:
        if self.path is None or self._started_event is None:
            return False
        if self.rotate_every_s and time.monotonic() - self._opened >= self.rotate_every_s:
            return True
        current = self.files[-1]
        return bool(self.max_bytes) and current.exists() and current.stat().st_size >= self.max_bytes

    def _rotate(self) -> None:
        """Close this file and go on in the next, which starts with the twin as it is now."""
        assert self.path is not None and self._started_event is not None
        self.stream.flush()
        self.stream.disconnect()
        previous = self.files[-1]
        path = self.path.with_name(f"{self.path.stem}-{len(self.files):04d}{self.path.suffix}")
        self.stream = self._open(path)
        self._opened = time.monotonic()
        revision, stamp = self._now
        self._building(self._started_event)
        self._time(revision, stamp)
        self._placed = {}
        for key, tiles in self._maps.items():
            tiles.place(self.stream)
            self._placed[key] = tiles.generation
            tiles.log(self.stream, tiles_of(tiles.frame.full))
        for (storey, skill), cloud in self._clouds.items():
            self.stream.log(f"points/{storey}/{skill}", cloud)
        for entity, (shape, colour, seen) in self._observed.items():
            self._shape(entity, shape, colour, static=False, seen=seen)
        for routes in self._routes.values():
            self._log_routes(routes, ())
        self._text(f"recording continued from {previous.name} at revision {revision}", "INFO")
        log.info("Recording continues in %s (revision %d)", path, revision)

    def write(self, event: Recordable) -> None:
        """Record one event (rotating first when the file is due)."""
        if self._due():
            self._rotate()
        self._record(event)

    def note(self, text: str, level: str = "INFO") -> None:
        """A line in the recording's event log, at the time of the last recorded event."""
        self._text(text, level)

    def close(self) -> None:
        """Flush and close the file (and the viewer connection)."""
        self.stream.flush()
        self.stream.disconnect()

    # --- events ------------------------------------------------------------------------------------
    def _time(self, revision: int, stamp_ns: int) -> None:
        self._now = (revision, stamp_ns)
        self.stream.set_time("revision", sequence=revision)
        self.stream.set_time("time", timestamp=np.datetime64(stamp_ns, "ns"))

    def _record(self, event: Recordable) -> None:
        if isinstance(event, TwinStarted):
            self._started(event)
        elif isinstance(event, MapPublished):
            self._map(event)
        elif isinstance(event, MapMark):
            self._time(event.revision, event.stamp_ns)
            self._version(event.storey, event.skill, event.version, event.revision)
        elif isinstance(event, MapUpdated):
            self._update(event)
        elif isinstance(event, PointsPublished):
            self._points(event)
        elif isinstance(event, MapRemoved):
            self._time(event.revision, event.stamp_ns)
            self._maps.pop((event.storey, event.skill), None)
            self._clouds.pop((event.storey, event.skill), None)
            self.stream.log(f"maps/{event.storey}/{event.skill}", rr.Clear(recursive=True))
            self.stream.log(f"points/{event.storey}/{event.skill}", rr.Clear(recursive=True))
            self._text(f"map {event.storey}/{event.skill} removed", "INFO")
        elif isinstance(event, ObservationAccepted):
            self._accepted(event)
        elif isinstance(event, ObservationNoted):
            self._time(event.revision, event.stamp_ns)
            for note in event.notes:
                self._text(f"{event.robot}: {note}", "INFO")
        elif isinstance(event, ObservationRejected):
            self.stream.set_time("time", timestamp=np.datetime64(event.stamp_ns, "ns"))
            self._text(f"{event.robot}: observation rejected: {event.error}", "WARN")
        elif isinstance(event, SkillChanged):
            self._time(event.revision, event.stamp_ns)
            what = "removed" if event.profile is None else f"set to {event.profile.to_json()}"
            self._text(f"skill {event.name} {what} (revision {event.revision})", "INFO")
        elif isinstance(event, RoutesPublished):
            self._route_graph(event)
        elif isinstance(event, RobotStoreyChanged):
            self._time(event.revision, event.stamp_ns)
            was = f" (was {event.previous})" if event.previous else ""
            self._text(f"{event.robot}: now on storey {event.storey}{was}, via {event.source}", "INFO")

    def _points(self, event: PointsPublished) -> None:
        """A points map's cloud, in world coordinates (z plus the storey's elevation), each version."""
        self._time(event.revision, event.stamp_ns)
        c = event.cloud
        xyz = c.xyz.astype(np.float32)
        xyz[:, 2] += np.float32(c.elevation_m)
        cloud = self._clouds[(c.storey, c.skill)] = rr.Points3D(xyz, radii=np.float32(c.resolution_m / 4))
        self.stream.log(f"points/{c.storey}/{c.skill}", cloud)

    def _route_graph(self, event: RoutesPublished) -> None:
        """A routes skill's graph version, at the current revision (a graph changes no twin data)."""
        self._time(self._now[0], event.stamp_ns)
        g = event.graph
        previous = self._routes.get(g.skill)
        self._routes[g.skill] = event
        if previous is None and self._started_event is not None:  # a new view in each storey's tab
            self._send_blueprint(self._started_event)
        served = {s.storey for s in g.storeys}
        gone = () if previous is None else {s.storey for s in previous.graph.storeys} - served
        self._log_routes(event, gone)
        lanes = sum(len(s.lanes) for s in g.storeys)
        self._text(f"routes {g.skill}: version {event.version}, {lanes} lanes", "INFO")

    def _log_routes(self, event: RoutesPublished, gone: Collection[str]) -> None:
        g = event.graph
        for storey in gone:
            self.stream.log(f"maps/{storey}/{g.skill}", rr.Clear(recursive=True))
        for s in g.storeys:
            path = f"maps/{s.storey}/{g.skill}"
            z = s.elevation_m + ROUTES_LIFT_M
            xy = np.array([(v.x, v.y) for v in s.vertices], dtype=np.float32).reshape(-1, 2)
            xyz = np.column_stack([xy, np.full(len(xy), z, dtype=np.float32)])
            ends = np.array([(lane.a, lane.b) for lane in s.lanes], dtype=np.intp).reshape(-1, 2)
            colours = [_DOOR_LANE if lane.door else _LANE for lane in s.lanes]
            self.stream.log(f"{path}/lanes", rr.LineStrips3D(xyz[ends], colors=colours, radii=0.03))
            one_way = ends[[lane.one_way for lane in s.lanes]] if s.lanes else ends
            self.stream.log(  # the way of each one-way lane (none: an empty batch clears the last)
                f"{path}/one_way",
                rr.Arrows3D(
                    origins=xyz[one_way[:, 0]],
                    vectors=xyz[one_way[:, 1]] - xyz[one_way[:, 0]],
                    colors=[_ONE_WAY] * len(one_way),
                    radii=0.04,
                ),
            )
            self.stream.log(
                f"{path}/vertices",
                rr.Points3D(
                    xyz,
                    labels=[v.name for v in s.vertices],
                    colors=[_VERTEX_COLOURS.get(v.kind, _LANE) for v in s.vertices],
                    radii=0.08,
                ),
            )
            self.stream.log(path, rr.AnyValues(graph_version=event.version, fleet=g.fleet))

    def _text(self, text: str, level: str) -> None:
        self.stream.log("events", rr.TextLog(text, level=level))

    def _shape(
        self,
        path: str,
        shape: ElementShape,
        colour: Rgba,
        *,
        static: bool,
        seen: Seen | None = None,
        mesh: bool = True,
    ) -> None:
        """One element's mesh; ``seen`` for what a robot observed, shown when an operator selects it.
        ``mesh=False``: only its placement and properties (the entity keeps the mesh logged before)."""
        m = shape.placement
        provenance: dict[str, Any] = {}
        if seen is not None:
            robot, revision, stamp_ns = seen
            when = str(np.datetime64(stamp_ns, "ns").astype("datetime64[ms]")) + "Z"
            provenance = {"observed_by": robot, "observed_revision": revision, "observed_at": when}
        self.stream.log(path, rr.Transform3D(translation=m[:3, 3], mat3x3=m[:3, :3]), static=static)
        properties = rr.AnyValues(iri=shape.iri, ifc_class=shape.ifc_class, name=shape.name, **provenance)
        if not mesh:
            self.stream.log(path, properties, static=static)
            return
        self.stream.log(
            path,
            rr.Mesh3D(
                vertex_positions=shape.mesh.vertices.astype(np.float32),
                triangle_indices=shape.mesh.faces.astype(np.uint32),
                albedo_factor=colour,
            ),
            properties,
            static=static,
        )

    def _building(self, event: TwinStarted) -> None:
        """The building (static) and the blueprint: what every file starts with."""
        self.stream.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        for shape in event.elements:
            storey = shape.storey or "building"
            path = f"world/{storey}/{shape.ifc_class}/{entity_name(shape.iri)}"
            self._shape(path, shape, colour_of(shape), static=True)
        self._send_blueprint(event)

    def _send_blueprint(self, event: TwinStarted) -> None:
        routes = {name: r.navigation for name, r in self._routes.items()}
        self.stream.send_blueprint(blueprint_of(event, routes))

    def _started(self, event: TwinStarted) -> None:
        self._storeys = {key: elevation for key, _, elevation in event.storeys}
        self._started_event = event
        self._building(event)
        self._time(event.revision, event.stamp_ns)
        self._text(
            f"twin {event.site} started at revision {event.revision}: {len(event.elements)} elements, "
            f"{len(event.skills)} skills, {len(event.storeys)} storeys",
            "INFO",
        )

    def _version(self, storey: str, skill: str, version: int, revision: int) -> None:
        self.stream.log(
            f"maps/{storey}/{skill}", rr.AnyValues(map_version=version, map_revision=revision, tiles=TILE)
        )

    def _map(self, event: MapPublished) -> None:
        g = event.grid
        self._time(event.revision, event.stamp_ns)
        key = (g.storey, g.skill)
        known = self._maps.get(key)
        if known is None or known.frame != g.frame:
            # A map that (re)appears or changes frame gets new tile entities: the static placements
            # of older revisions are never overwritten (nor hidden by the removal's clear).
            placed = self._placed.get(key)
            generation = 0 if placed is None else placed + 1
            if known is not None:  # a new frame: the old tiles end here
                self.stream.log(tiles_path(g.storey, g.skill, known.generation), rr.Clear(recursive=True))
            known = self._maps[key] = MapTiles(g, generation)
            known.place(self.stream)
            self._placed[key] = generation
            changed = tiles_of(g.frame.full)
        else:  # the full map follows its updates: only tiles that differ (none, normally)
            changed = known.replace(g.data)
        known.log(self.stream, changed)
        self._version(g.storey, g.skill, event.version, event.revision)

    def _update(self, event: MapUpdated) -> None:
        f, w = event.frame, event.window
        res = f.resolution_m
        z = self._storeys.get(event.storey, 0.0)
        self._time(event.revision, event.stamp_ns)
        known = self._maps.get((event.storey, event.skill))
        if known is not None and known.frame == f:
            known.log(self.stream, known.apply(w, event.data))
        self.stream.log(
            f"maps/{event.storey}/{event.skill}/changed",
            rr.Boxes3D(
                mins=[f.origin_x + w.col0 * res, f.origin_y + w.row0 * res, z],
                sizes=[w.shape[1] * res, w.shape[0] * res, 0.05],
                colors=[(255, 200, 0, 255)],
            ),
            rr.AnyValues(version=event.version, x=w.col0, y=w.row0, width=w.shape[1], height=w.shape[0]),
        )

    def _accepted(self, event: ObservationAccepted) -> None:
        self._time(event.revision, event.stamp_ns)
        for shape in event.upserted:
            path = f"world/observations/{entity_name(event.robot)}/{entity_name(shape.iri)}"
            colour = OBSERVED if not shape.is_static else colour_of(shape)
            if shape.is_open:
                colour = (colour[0], colour[1], colour[2], 60)
            seen = (event.robot, event.revision, event.stamp_ns)
            known = self._observed.get(path)  # a moved element keeps its mesh: only its placement
            moved = known is not None and known[1] == colour and _same_mesh(known[0], shape)
            self._shape(path, shape, colour, static=False, seen=seen, mesh=not moved)
            self._observed[path] = (shape, colour, seen)
        for iri in event.removed:
            path = f"world/observations/{entity_name(event.robot)}/{entity_name(iri)}"
            self._observed.pop(path, None)
            self.stream.log(path, rr.Clear(recursive=True))
        changed = ", ".join(f"{m.storey}/{m.skill} v{m.version}" for m in event.maps) or "no map"
        doors = [s.iri for s in event.upserted if s.is_open is not None]
        extra = f"; door(s) {', '.join(doors)}" if doors else ""
        self._text(
            f"{event.robot}: accepted at revision {event.revision}: upserted {len(event.upserted)}, "
            f"removed {len(event.removed)}; maps {changed}{extra}",
            "INFO",
        )
        for note in event.notes:  # what fusion decided: merges, refined poses, removals by absence
            self._text(f"{event.robot}: {note}", "INFO")
