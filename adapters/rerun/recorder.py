"""The Rerun recorder: a sink of the twin service that records the twin's history for operators.

Every event goes through a bounded queue to the recorder's own thread, so recording never delays the
service; a failure is logged, counted, and after repeated failures the recorder disables itself (the
daemon keeps running). What is recorded (entity paths):

- ``world/<storey>/<class>/<element>``: the building at start-up (static), one mesh per element with its
  placement, coloured by class (walls, glass, doors, furniture, openings ...), with its IRI, class and
  name as properties (shown on hover and selection);
- ``maps/<storey>/<skill>/tiles/r<i>_c<j>``: every map, cut in tiles of ``TILE`` x ``TILE`` cells, each
  an ``rr.GridMap`` (RViz map colours; cell size and origin in the building's frame, at the storey's
  elevation). A tile is logged when the map first appears and again at every revision that changes
  one of its cells, so at any point of the ``revision`` timeline the tiles show exactly the map the
  daemon served at that revision, at a cost proportional to the changed tiles, not to the map
  (:func:`map_at` reads a map back at a revision); ``maps/<storey>/<skill>`` carries its version and
  revision; ``maps/<storey>/<skill>/changed``: the changed rectangle of each update, as a 3D box;
- ``world/observations/<robot>/<element>``: what robots added or changed (cleared when removed);
- ``events``: one text line per observation (accepted with its revision, or the rejection reason),
  skill change, map removal and robot storey switch.

**Rotation** (``rotate_every_s``, ``max_bytes``): the recording continues in ``<name>-0001.rrd``,
``-0002`` ... each starting with the building, every current map (all tiles) and what robots
observed, at the current revision, so any file replays on its own (:attr:`RerunRecorder.files`).

Timelines: ``revision`` (a sequence: the twin revision the data reflects) and ``time`` (wall clock of
the change). A blueprint opens on the 3D building, one tab per storey with one view per skill map
(named by its skill, not stacked), and the event log.

Example::

    recorder = RerunRecorder(path=Path("var/recordings/lab.rrd"))
    service.sinks.append(recorder)
    ...
    recorder.close()                 # flushes the file
"""

from __future__ import annotations

import datetime
import logging
import queue
import re
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from twin.events import (
    ElementShape,
    MapPublished,
    MapRemoved,
    MapUpdated,
    ObservationAccepted,
    ObservationRejected,
    RobotStoreyChanged,
    SkillChanged,
    TwinEvent,
    TwinStarted,
)
from twin.grid import OccupancyGrid, Window

log = logging.getLogger(__name__)

_STOP = object()
TILE = 128
"""Cells per side of a recorded map tile."""
_SAFE = re.compile(r"[^A-Za-z0-9_-]+")

# Colours (RGBA) by IFC class family: what an operator tells apart at a glance.
_COLOURS: tuple[tuple[str, tuple[int, int, int, int]], ...] = (
    ("IfcOpeningElement", (255, 80, 80, 60)),
    ("IfcDoor", (200, 120, 40, 255)),
    ("IfcWindow", (120, 200, 255, 120)),
    ("IfcCurtainWall", (120, 200, 255, 120)),
    ("IfcFurnishingElement", (90, 170, 90, 255)),
    ("IfcFurniture", (90, 170, 90, 255)),
    ("IfcSlab", (170, 170, 170, 110)),
    ("IfcWall", (225, 215, 195, 110)),  # translucent: what robots observed inside stands out
    ("IfcColumn", (160, 160, 200, 255)),
    ("IfcBeam", (160, 160, 200, 255)),
)
_GLASS = (120, 200, 255, 120)
_OBSERVED = (240, 60, 200, 255)
_DEFAULT = (200, 200, 200, 255)


def colour_of(shape: ElementShape) -> tuple[int, int, int, int]:
    """The display colour of an element: glass by name, else by class (subtypes by prefix)."""
    if "glass" in shape.name.lower():
        return _GLASS
    for prefix, colour in _COLOURS:
        if shape.ifc_class.startswith(prefix):
            return colour
    return _DEFAULT


def _top_down(
    elements: Sequence[ElementShape], storey: str, elevation: float
) -> rrb.archetypes.EyeControls3D | None:
    """A camera looking straight down on the storey's elements (None if it has none)."""
    points = [
        s.mesh.vertices @ s.placement[:3, :3].T + s.placement[:3, 3]
        for s in elements
        if s.storey == storey and len(s.mesh.vertices)
    ]
    if not points:
        return None
    xyz = np.concatenate(points)
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    cx, cy = float(lo[0] + hi[0]) / 2, float(lo[1] + hi[1]) / 2
    span = float(max(hi[0] - lo[0], hi[1] - lo[1], 1.0))
    return rrb.archetypes.EyeControls3D(
        position=[cx, cy - 0.01 * span, elevation + 1.1 * span],
        look_target=[cx, cy, elevation],
        eye_up=[0.0, 0.0, 1.0],
    )


def entity_name(iri: str) -> str:
    """A short, path-safe entity name for an element IRI."""
    tail = iri.rstrip("/#").rsplit("#", 1)[-1].rsplit("/", 1)[-1]
    return _SAFE.sub("_", tail)[:80] or "element"


class _Recorded:
    """The recorder's copy of one map (updates applied): what its tiles show."""

    def __init__(self, grid: OccupancyGrid) -> None:
        self.grid = OccupancyGrid(grid.frame, grid.data.copy(), grid.storey, grid.skill, grid.elevation_m)


def tiles_of(window: Window) -> list[tuple[int, int]]:
    """``(i, j)`` of every tile ``window`` touches."""
    return [
        (i, j)
        for i in range(window.row0 // TILE, (window.row1 - 1) // TILE + 1)
        for j in range(window.col0 // TILE, (window.col1 - 1) // TILE + 1)
    ]


class RerunRecorder:
    """Records service events to an ``.rrd`` file and/or a live viewer, off the service's thread."""

    def __init__(
        self,
        *,
        path: Path | None = None,
        connect_url: str | None = None,
        application: str = "building-twin",
        max_queue: int = 10_000,
        max_failures: int = 20,
        rotate_every_s: float = 0.0,
        max_bytes: int = 0,
    ) -> None:
        self.path = path
        self.application = application
        self.connect_url = connect_url
        self.rotate_every_s = rotate_every_s
        self.max_bytes = max_bytes
        self.files: list[Path] = []
        """Every file written so far, in order (the first is ``path``)."""
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
        self.stream = self._open(path)
        self._opened = time.monotonic()
        self._started_event: TwinStarted | None = None
        self._observed: dict[str, tuple[ElementShape, tuple[int, int, int, int], tuple[str, int, int]]] = {}
        self._now: tuple[int, int] = (0, 0)  # (revision, stamp) of the last recorded event
        self.dropped = 0
        self.failures = 0
        self.max_failures = max_failures
        self.disabled = False
        self._storeys: dict[str, float] = {}
        self._maps: dict[tuple[str, str], _Recorded] = {}
        self._queue: queue.Queue[object] = queue.Queue(maxsize=max_queue)
        self._thread = threading.Thread(target=self._run, name="rerun-recorder", daemon=True)
        self._thread.start()

    # --- the sink (service thread: never blocks, never raises) ---------------------------------------
    def emit(self, event: TwinEvent) -> None:
        if self.disabled:
            return
        try:
            self._queue.put_nowait(event)
        except queue.Full:
            self.dropped += 1
            if self.dropped in (1, 100, 10_000):
                log.warning("The Rerun recorder is behind: %d event(s) dropped", self.dropped)

    # --- files -------------------------------------------------------------------------------------
    def _open(self, path: Path | None) -> rr.RecordingStream:
        # Files batch rows for 2 s (fewer, larger chunks: a chunk per entity per tick costs about a
        # kilobyte of schema); a live viewer keeps the SDK's 200 ms.
        tick = 0.2 if self.connect_url else 2.0
        batcher = rr.ChunkBatcherConfig(
            flush_tick=datetime.timedelta(seconds=tick), flush_num_bytes=8 * 2**20, flush_num_rows=2**20
        )
        stream = rr.RecordingStream(application_id=self.application, batcher_config=batcher)
        sinks: list[rr.FileSink | rr.GrpcSink] = []
        if path is not None:
            sinks.append(rr.FileSink(str(path)))
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
        for recorded in self._maps.values():
            for i, j in tiles_of(recorded.grid.frame.full):
                self._tile(recorded.grid, i, j)
        for entity, (shape, colour, seen) in self._observed.items():
            self._shape(entity, shape, colour, static=False, seen=seen)
        self._text(f"recording continued from {previous.name} at revision {revision}", "INFO")
        log.info("Recording continues in %s (revision %d)", path, revision)

    # --- the worker ---------------------------------------------------------------------------------
    def _run(self) -> None:
        while True:
            event = self._queue.get()
            try:
                if event is _STOP:
                    return
                self._handle(event)
            finally:
                self._queue.task_done()

    def wait_idle(self) -> None:
        """Return once every event emitted so far is recorded (or dropped)."""
        self._queue.join()

    def _handle(self, event: object) -> None:
        if not self.disabled:
            try:
                if self._due():
                    self._rotate()
                self._record(event)  # type: ignore[arg-type]
            except Exception:
                self.failures += 1
                log.exception("Recording %s failed", type(event).__name__)
                if self.failures >= self.max_failures:
                    self.disabled = True
                    log.error("The Rerun recorder is disabled after %d failures", self.failures)

    def _time(self, revision: int, stamp_ns: int) -> None:
        self._now = (revision, stamp_ns)
        self.stream.set_time("revision", sequence=revision)
        self.stream.set_time("time", timestamp=np.datetime64(stamp_ns, "ns"))

    def _record(self, event: TwinEvent) -> None:
        if isinstance(event, TwinStarted):
            self._started(event)
        elif isinstance(event, MapPublished):
            self._map(event)
        elif isinstance(event, MapUpdated):
            self._update(event)
        elif isinstance(event, MapRemoved):
            self._time(event.revision, event.stamp_ns)
            self._maps.pop((event.storey, event.skill), None)
            self.stream.log(f"maps/{event.storey}/{event.skill}", rr.Clear(recursive=True))
            self._text(f"map {event.storey}/{event.skill} removed", "INFO")
        elif isinstance(event, ObservationAccepted):
            self._accepted(event)
        elif isinstance(event, ObservationRejected):
            self.stream.set_time("time", timestamp=np.datetime64(event.stamp_ns, "ns"))
            self._text(f"{event.robot}: observation rejected: {event.error}", "WARN")
        elif isinstance(event, SkillChanged):
            self._time(event.revision, event.stamp_ns)
            what = "removed" if event.profile is None else f"set to {event.profile.to_json()}"
            self._text(f"skill {event.name} {what} (revision {event.revision})", "INFO")
        elif isinstance(event, RobotStoreyChanged):
            self._time(event.revision, event.stamp_ns)
            was = f" (was {event.previous})" if event.previous else ""
            self._text(f"{event.robot}: now on storey {event.storey}{was}, via {event.source}", "INFO")

    def _text(self, text: str, level: str) -> None:
        self.stream.log("events", rr.TextLog(text, level=level))

    def _shape(
        self,
        path: str,
        shape: ElementShape,
        colour: tuple[int, int, int, int],
        *,
        static: bool,
        seen: tuple[str, int, int] | None = None,
    ) -> None:
        """One element's mesh; ``seen`` (robot, revision, time ns) for what a robot observed, shown when
        an operator selects it."""
        m = shape.placement
        provenance: dict[str, Any] = {}
        if seen is not None:
            robot, revision, stamp_ns = seen
            when = str(np.datetime64(stamp_ns, "ns").astype("datetime64[ms]")) + "Z"
            provenance = {"observed_by": robot, "observed_revision": revision, "observed_at": when}
        self.stream.log(path, rr.Transform3D(translation=m[:3, 3], mat3x3=m[:3, :3]), static=static)
        self.stream.log(
            path,
            rr.Mesh3D(
                vertex_positions=shape.mesh.vertices.astype(np.float32),
                triangle_indices=shape.mesh.faces.astype(np.uint32),
                albedo_factor=colour,
            ),
            rr.AnyValues(iri=shape.iri, ifc_class=shape.ifc_class, name=shape.name, **provenance),
            static=static,
        )

    def _building(self, event: TwinStarted) -> None:
        """The building (static) and the blueprint: what every file starts with."""
        self.stream.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        for shape in event.elements:
            storey = shape.storey or "building"
            path = f"world/{storey}/{shape.ifc_class}/{entity_name(shape.iri)}"
            self._shape(path, shape, colour_of(shape), static=True)
        self._blueprint(event)

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

    def _blueprint(self, event: TwinStarted) -> None:
        maps = [
            rrb.Grid(
                *(
                    rrb.Spatial3DView(
                        name=skill,
                        origin=f"maps/{storey}/{skill}",
                        contents=[f"maps/{storey}/{skill}/**"],
                        eye_controls=_top_down(event.elements, storey, elevation),
                    )
                    for skill in event.skills
                ),
                name=storey,
            )
            for storey, _, elevation in event.storeys
        ]
        blueprint = rrb.Blueprint(
            rrb.Horizontal(
                rrb.Vertical(
                    rrb.Spatial3DView(name="building", origin="world", contents=["world/**", "maps/**"]),
                    rrb.TextLogView(name="events", origin="events"),
                    row_shares=[3, 1],
                ),
                rrb.Tabs(*maps) if maps else rrb.TextLogView(origin="events"),
                column_shares=[3, 2],
            ),
            rrb.TimePanel(state="expanded", timeline="revision"),
        )
        self.stream.send_blueprint(blueprint)

    def _tile(self, g: OccupancyGrid, i: int, j: int) -> None:
        """Log tile ``(i, j)`` of ``g`` as it is now (at the current revision)."""
        f = g.frame
        r0, c0 = i * TILE, j * TILE
        cells = g.data[r0 : r0 + TILE, c0 : c0 + TILE]
        h, w = cells.shape
        self.stream.log(
            f"maps/{g.storey}/{g.skill}/tiles/r{i}_c{j}",
            rr.GridMap(
                data=np.ascontiguousarray(cells).view(np.uint8).tobytes(),  # -1 (unknown) is 255
                format=rr.components.ImageFormat(width=w, height=h, color_model="L", channel_datatype="U8"),
                cell_size=f.resolution_m,
                # Rerun draws an image's row 0 at the far (+y) edge, the twin's row 0 is the lowest y:
                # a half turn about x puts every cell on its world cell without touching the data.
                translation=[
                    f.origin_x + c0 * f.resolution_m,
                    f.origin_y + (r0 + h) * f.resolution_m,
                    g.elevation_m,
                ],
                rotation_axis_angle=rr.RotationAxisAngle(axis=[1.0, 0.0, 0.0], degrees=180.0),
                colormap=rr.components.Colormap.RvizMap,
            ),
        )

    def _map(self, event: MapPublished) -> None:
        g = event.grid
        self._time(event.revision, event.stamp_ns)
        key = (g.storey, g.skill)
        known = self._maps.get(key)
        if known is None or known.grid.frame != g.frame:
            known = self._maps[key] = _Recorded(g)
            changed = tiles_of(g.frame.full)
        else:  # the full map follows its updates: only tiles that differ (none, normally)
            diff = np.argwhere(known.grid.data != g.data)
            changed = sorted({(int(r) // TILE, int(c) // TILE) for r, c in diff})
            known.grid.data[...] = g.data
        for i, j in changed:
            self._tile(known.grid, i, j)
        self.stream.log(
            f"maps/{g.storey}/{g.skill}",
            rr.AnyValues(map_version=event.version, map_revision=event.revision, tiles=TILE),
        )

    def _update(self, event: MapUpdated) -> None:
        f, w = event.frame, event.window
        res = f.resolution_m
        z = self._storeys.get(event.storey, 0.0)
        self._time(event.revision, event.stamp_ns)
        known = self._maps.get((event.storey, event.skill))
        if known is not None and known.grid.frame == f:
            known.grid.data[w.row0 : w.row1, w.col0 : w.col1] = event.data
            for i, j in tiles_of(w):
                self._tile(known.grid, i, j)
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
            colour = _OBSERVED if not shape.is_static else colour_of(shape)
            if shape.is_open:
                colour = (colour[0], colour[1], colour[2], 60)
            seen = (event.robot, event.revision, event.stamp_ns)
            self._shape(path, shape, colour, static=False, seen=seen)
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

    # --- lifecycle ----------------------------------------------------------------------------------
    def close(self, timeout_s: float = 10.0) -> None:
        """Record what is queued, then flush and close the file (and the viewer connection)."""
        try:
            self._queue.put(_STOP, timeout=timeout_s)
        except queue.Full:
            log.warning("The Rerun recorder could not finish its queue in %s s", timeout_s)
        self._thread.join(timeout_s)
        try:
            self.stream.flush()
            self.stream.disconnect()
        except Exception:
            log.exception("Closing the Rerun recording failed")
