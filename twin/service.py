"""The twin service: the single writer of the twin, with no transport.

It loads the graph (:func:`~twin.scene.load_scene`), builds every skill map of every storey, and then
applies requests one at a time on its own worker thread: robot observations (parse, check, one store
transaction, re-slice only what changed) and skill profiles added or removed at run time. After each
committed change it bumps the twin's revision and emits events (:mod:`twin.events`) to its sinks:
the changed rectangle of every affected map at once, the full maps coalesced (at most every
``limits.full_map_interval_s`` in a burst). Requests come from any thread (e.g. Zenoh callbacks,
which only enqueue); replies go to the callback given with each request.

Example::

    service = TwinService(store, cfg, sinks=[publisher, recorder])
    service.start()                                   # loads, builds, publishes every map
    service.submit_observation("robot1", turtle, reply=print)
    service.serve_forever(stop_event)                 # or service.process(timeout_s=...) in tests
"""

from __future__ import annotations

import json
import logging
import queue
import re
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from twin import vocab
from twin.changes import (
    ElementState,
    ObservationPlan,
    StoreyFrame,
    TwinContext,
    load_states,
    plan_observation,
)
from twin.config import Config
from twin.engine import GeometryChange, LiveMap, MapEngine, Shape
from twin.errors import QueryError, SkillError, TwinError
from twin.events import (
    ElementShape,
    MapChange,
    MapPublished,
    MapRemoved,
    MapUpdated,
    ObservationAccepted,
    ObservationRejected,
    SkillChanged,
    TwinEvent,
    TwinSink,
    TwinStarted,
)
from twin.grid import OccupancyGrid
from twin.observations import parse_observation
from twin.scene import load_scene
from twin.skills import SkillProfile, parse_skill_json, selection_query
from twin.store import ChangeSet, GraphStore, Literal, Triple

log = logging.getLogger(__name__)

Clock = Callable[[], int]
_PREFIXES = re.compile(r"^\s*((PREFIX|BASE)\s+[^\n]*\n?\s*)*", re.IGNORECASE)
_UPDATE = re.compile(r"^\s*(INSERT|DELETE|LOAD|CLEAR|DROP|CREATE|ADD|MOVE|COPY|WITH)\b", re.IGNORECASE)


@dataclass(frozen=True, slots=True)
class Reply:
    """The answer to a request: ``ok`` with a body, or an error message naming what was wrong."""

    ok: bool
    body: dict[str, object]

    @classmethod
    def error(cls, message: str) -> Reply:
        return cls(False, {"ok": False, "error": message})

    def to_json(self) -> bytes:
        return json.dumps(self.body).encode()


ReplyFn = Callable[[Reply], None]


@dataclass(frozen=True, slots=True)
class _Observe:
    robot: str
    payload: bytes
    reply: ReplyFn | None
    received_ns: int


@dataclass(frozen=True, slots=True)
class _Skill:
    name: str
    payload: bytes | None  # None: remove
    reply: ReplyFn | None


@dataclass(frozen=True, slots=True)
class PublishedMap:
    """The latest full version of a map that was published (what a ``get`` answers)."""

    grid: OccupancyGrid
    revision: int
    version: int
    stamp_ns: int


@dataclass(slots=True)
class _Counters:
    accepted: int = 0
    rejected: int = 0
    started_ns: int = 0
    pending_full: dict[tuple[str, str], int] = field(default_factory=dict)
    """Maps changed since their last full publication -> when the first such change happened (ns)."""


class TwinService:
    """The twin's single writer. Create, :meth:`start`, then run :meth:`serve_forever` on a thread."""

    def __init__(
        self,
        store: GraphStore,
        config: Config,
        *,
        sinks: Sequence[TwinSink] = (),
        clock: Clock = time.time_ns,
        max_batch: int = 64,
    ) -> None:
        """``max_batch``: at most this many queued observations share one map pass (group commit)."""
        self.store = store
        self.max_batch = max(1, max_batch)
        self.config = config
        self.sinks = list(sinks)
        self.clock = clock
        self.revision = 0
        self.skills: dict[str, SkillProfile] = {}
        self._queue: queue.Queue[_Observe | _Skill] = queue.Queue()
        self._published: dict[tuple[str, str], PublishedMap] = {}
        self._engine: MapEngine | None = None
        self._ctx: TwinContext | None = None
        self._states: dict[str, ElementState] = {}
        self._counters = _Counters()
        self._base_iri = ""

    # --- start ----------------------------------------------------------------------------------------
    def start(self) -> None:
        """Load the twin, build every map, and emit TwinStarted then MapPublished for each map."""
        t0 = time.perf_counter()
        self._counters.started_ns = self.clock()
        model = self.store.select(
            "SELECT ?m ?schema ?rev WHERE { ?m a twin:Model . OPTIONAL { ?m twin:ifcSchema ?schema } "
            "OPTIONAL { ?m twin:revision ?rev } }"
        )
        if not model:
            msg = "The store holds no imported model (no twin:Model node): import one first."
            raise TwinError(msg)
        model_iri = model[0]["m"] or ""
        self._base_iri = model_iri.removesuffix("model")
        self.revision = max(int(r["rev"] or 0) for r in model)
        scene = load_scene(self.store)
        self._engine = MapEngine(scene, margin_m=self.config.margin_m)
        self._states = load_states(self.store)
        b = scene.elements.bounds
        b = b[~np.isnan(b).any(axis=1)]
        exts = np.array([s.extent for s in scene.storeys]) if scene.storeys else b[:, [0, 1, 3, 4]]
        m = self.config.limits.site_margin_m
        site_box = (
            float(min(exts[:, 0].min(), b[:, 0].min())) - m,
            float(min(exts[:, 1].min(), b[:, 1].min())) - m,
            float(b[:, 2].min()) - m,
            float(max(exts[:, 2].max(), b[:, 3].max())) + m,
            float(max(exts[:, 3].max(), b[:, 4].max())) + m,
            float(b[:, 5].max()) + m,
        )
        self._ctx = TwinContext(
            states=self._states,
            storeys={s.key: StoreyFrame(s.key, s.iri, s.elevation_m) for s in scene.storeys},
            schema=(model[0]["schema"] or "IFC4"),
            static_types=self.config.import_.static_types,
            site_box=site_box,
            model_iri=model_iri,
        )
        self.skills = dict(self.config.skills)
        self.skills.update(self._stored_skills())
        stamp = self.clock()
        self._emit(
            TwinStarted(
                site=self.config.site,
                revision=self.revision,
                stamp_ns=stamp,
                storeys=tuple((s.key, s.name, s.elevation_m) for s in scene.storeys),
                elements=self.element_shapes(),
                skills=dict(self.skills),
            )
        )
        for skill in self.skills.values():
            self._add_skill_maps(skill, stamp)
        log.info(
            "Twin started at revision %d: %d maps of %d skills on %d storeys in %.2f s",
            self.revision,
            len(self._published),
            len(self.skills),
            len(scene.storeys),
            time.perf_counter() - t0,
        )

    def _stored_skills(self) -> dict[str, SkillProfile]:
        """Skill profiles added (or configured ones removed) at run time, kept in the graph."""
        out: dict[str, SkillProfile] = {}
        rows = self.store.select(
            "SELECT ?name ?json ?gone WHERE { ?s a twin:Skill ; rdfs:label ?name . "
            "OPTIONAL { ?s twin:profileJson ?json } OPTIONAL { ?s twin:removed ?gone } }"
        )
        for r in rows:
            name = r["name"] or ""
            if r["gone"] in ("true", "1"):
                self.skills.pop(name, None)
                continue
            try:
                out[name] = parse_skill_json(name, r["json"] or "")
            except SkillError as err:
                log.warning("Ignoring the stored skill %r: %s", name, err)
        return out

    @property
    def engine(self) -> MapEngine:
        if self._engine is None:
            msg = "The twin service has not been started."
            raise TwinError(msg)
        return self._engine

    def element_shapes(self, iris: Sequence[str] | None = None) -> tuple[ElementShape, ...]:
        """The current shape of the given elements (default: all with geometry)."""
        engine = self.engine
        chosen = iris if iris is not None else sorted(self._states)
        out = []
        for iri in chosen:
            shape = engine.shape_of(iri)
            state = self._states.get(iri)
            if shape is None or state is None:
                continue
            out.append(
                ElementShape(
                    iri=iri,
                    ifc_class=state.ifc_class,
                    name=state.name,
                    storey=state.storey,
                    mesh=shape[0],
                    placement=shape[1],
                    is_static=state.is_static,
                    is_open=state.is_open,
                )
            )
        return tuple(out)

    def _selected(self, skill: SkillProfile, only: Sequence[str] | None = None) -> set[str]:
        return {r["element"] or "" for r in self.store.select(selection_query(skill, only))}

    def _add_skill_maps(self, skill: SkillProfile, stamp: int) -> list[LiveMap]:
        selected = self._selected(skill)
        maps = [self.engine.add_map(skill, s.key, selected) for s in self.engine.scene.storeys]
        for m in maps:
            self._publish_full(m, stamp)
        return maps

    # --- events ---------------------------------------------------------------------------------------
    def _emit(self, event: TwinEvent) -> None:
        for sink in self.sinks:
            try:
                sink.emit(event)
            except Exception:  # a sink must never stop the twin
                log.exception("Sink %s failed on %s", type(sink).__name__, type(event).__name__)

    def _publish_full(self, m: LiveMap, stamp: int) -> None:
        grid = m.grid()
        self._published[m.key] = PublishedMap(grid, self.revision, m.version, stamp)
        self._emit(MapPublished(grid, self.revision, m.version, stamp))

    def flush_full_maps(self, *, due_only: bool = False) -> None:
        """Publish the full version of every map changed since its last full publication; with
        ``due_only``, only of those whose first unpublished change is ``full_map_interval_s`` old."""
        stamp = self.clock()
        interval_ns = int(self.config.limits.full_map_interval_s * 1e9)
        for key, since in sorted(self._counters.pending_full.items()):
            if due_only and stamp - since < interval_ns:
                continue
            del self._counters.pending_full[key]
            m = self.engine.maps.get(key)
            if m is not None:
                self._publish_full(m, stamp)

    # --- requests (any thread) ------------------------------------------------------------------------
    def submit_observation(self, robot: str, payload: bytes, reply: ReplyFn | None = None) -> None:
        """Queue an observation by ``robot``; ``reply`` gets the ack (or error) once it is durable."""
        self._queue.put(_Observe(robot, bytes(payload), reply, self.clock()))

    def submit_skill(self, name: str, payload: bytes | None, reply: ReplyFn | None = None) -> None:
        """Queue a skill profile (JSON) to add or replace ``name``, or its removal (``payload`` None)."""
        self._queue.put(_Skill(name, None if payload is None else bytes(payload), reply))

    @property
    def queue_depth(self) -> int:
        return self._queue.qsize()

    # --- the worker -----------------------------------------------------------------------------------
    def process(self, *, timeout_s: float = 0.0) -> int:
        """Handle queued requests until the queue is empty (waiting up to ``timeout_s`` for the first),
        publishing the full maps that are due. Returns the number handled.

        Updates go out at once; a changed map's full version follows ``full_map_interval_s`` after its
        first unpublished change (so it comes after its updates, and a burst is coalesced).
        """
        handled = 0
        try:
            request = self._queue.get(timeout=timeout_s) if timeout_s > 0 else self._queue.get_nowait()
        except queue.Empty:
            request = None
        while request is not None:
            if isinstance(request, _Observe):  # with the observations queued behind it, as one batch
                batch, request = [request], None
                while len(batch) < self.max_batch:
                    try:
                        nxt = self._queue.get_nowait()
                    except queue.Empty:
                        break
                    if not isinstance(nxt, _Observe):
                        request = nxt
                        break
                    batch.append(nxt)
                self._handle_batch(batch)
                handled += len(batch)
            else:
                self._handle_skill(request)
                handled += 1
                request = None
            self.flush_full_maps(due_only=True)
            if request is None:
                try:
                    request = self._queue.get_nowait()
                except queue.Empty:
                    request = None
        self.flush_full_maps(due_only=True)
        return handled

    def serve_forever(self, stop: threading.Event, *, poll_s: float = 0.05) -> None:
        """Handle requests until ``stop`` is set, then finish what is queued and publish every map."""
        while not stop.is_set():
            self.process(timeout_s=poll_s)
        self.process()
        self.flush_full_maps()

    def _handle_skill(self, request: _Skill) -> None:
        try:
            reply = self._skill(request)
        except Exception as err:  # a bug must cost one request, never the daemon
            log.exception("Internal error while handling a skill")
            reply = Reply.error(f"Internal error ({type(err).__name__}): {err}")
        self._send(request, reply)

    def _handle_batch(self, batch: Sequence[_Observe]) -> None:
        try:
            replies = self._observe_batch(batch)
        except Exception as err:  # a bug must cost these requests, never the daemon
            log.exception("Internal error while handling %d observations", len(batch))
            replies = [Reply.error(f"Internal error ({type(err).__name__}): {err}")] * len(batch)
        for request, reply in zip(batch, replies, strict=True):
            self._send(request, reply)

    def _send(self, request: _Observe | _Skill, reply: Reply) -> None:
        if request.reply is not None:
            try:
                request.reply(reply)
            except Exception:
                log.exception("Could not send a reply")

    def _plan(
        self, req: _Observe, pending: Mapping[str, Shape | None]
    ) -> tuple[ObservationPlan, list[str]] | Reply:
        """Check one observation against the twin and commit it (durable on return), or refuse it."""
        try:
            if self._ctx is None:
                msg = "The twin service has not been started."
                raise TwinError(msg)
            reports = parse_observation(req.payload, limits=self.config.limits)
            plan = plan_observation(
                reports,
                robot=req.robot,
                rights=self.config.rights_of(req.robot),
                ctx=self._ctx,
                shapes={
                    r.iri: pending[r.iri] if r.iri in pending else self.engine.shape_of(r.iri)
                    for r in reports
                },
                revision=self.revision + 1,
                stamp_ns=req.received_ns,
            )
            self.store.apply(plan.changes)  # durable from here on
        except TwinError as err:  # ObservationError included
            self._counters.rejected += 1
            log.warning("Rejected an observation by %s: %s", req.robot, err)
            self._emit(ObservationRejected(req.robot, str(err), self.clock(), len(req.payload)))
            return Reply.error(str(err))
        self.revision += 1
        self._counters.accepted += 1
        self._states.update(plan.states)
        return plan, [r.iri for r in reports]

    def _observe_batch(self, batch: Sequence[_Observe]) -> list[Reply]:
        """Commit each observation in its own transaction (in order, each seeing the ones before), then
        bring the maps up to date once for all of them; the acks follow the updates.

        Under load this is group commit: one map pass (and one selection query per skill) for a whole
        queue of observations, so throughput grows with the queue instead of latency.
        """
        stamp = self.clock()
        pending: dict[str, Shape | None] = {}  # the shapes this batch gave, not yet in the engine
        results: list[tuple[ObservationPlan, int, str] | Reply] = []
        geometry: list[GeometryChange] = []
        touched: dict[str, None] = {}
        for req in batch:
            planned = self._plan(req, pending)
            if isinstance(planned, Reply):
                results.append(planned)
                continue
            plan, iris = planned
            results.append((plan, self.revision, req.robot))
            for g in plan.geometry:
                pending[g.iri] = g.new
            geometry += plan.geometry
            touched |= dict.fromkeys(iris)
        if not geometry and not touched:
            return [r for r in results if isinstance(r, Reply)]
        membership = {
            name: dict.fromkeys(touched, False) | dict.fromkeys(self._selected(skill, list(touched)), True)
            for name, skill in self.skills.items()
        }
        changes = self._apply_maps(geometry, membership, stamp)
        replies = []
        for result in results:
            if isinstance(result, Reply):
                replies.append(result)
                continue
            plan, revision, robot = result
            self._emit(
                ObservationAccepted(
                    robot=robot,
                    revision=revision,
                    stamp_ns=stamp,
                    upserted=self.element_shapes(plan.upserted),
                    removed=plan.removed,
                    maps=changes,
                )
            )
            replies.append(
                Reply(
                    True,
                    {
                        "ok": True,
                        "revision": revision,
                        "upserted": list(plan.upserted),
                        "removed": list(plan.removed),
                        "maps": [c.as_json() for c in changes],
                    },
                )
            )
        return replies

    def _apply_maps(
        self, geometry: Sequence[GeometryChange], membership: Mapping[str, Mapping[str, bool]], stamp: int
    ) -> tuple[MapChange, ...]:
        updates = self.engine.apply(geometry, membership)
        changes = []
        for u in updates:
            m = self.engine.maps[(u.storey, u.skill)]
            self._emit(
                MapUpdated(u.storey, u.skill, m.plan.frame, u.window, u.data, self.revision, u.version, stamp)
            )
            self._counters.pending_full.setdefault((u.storey, u.skill), stamp)
            changes.append(MapChange(u.storey, u.skill, u.version, u.window))
        return tuple(changes)

    def _skill(self, req: _Skill) -> Reply:
        stamp = self.clock()
        node = vocab.skill_iri(self._base_iri, req.name)
        try:
            if req.payload is None:
                if req.name not in self.skills:
                    known = ", ".join(sorted(self.skills)) or "none"
                    msg = f"Unknown skill {req.name!r}; skills: {known}."
                    raise SkillError(msg)
                changes = ChangeSet(
                    remove=((node, None),),
                    add=(
                        Triple(node, vocab.RDF_TYPE, vocab.TWIN_SKILL),
                        Triple(node, vocab.RDFS_LABEL, Literal(req.name)),
                        Triple(node, vocab.TWIN_REMOVED, Literal("true", vocab.XSD_BOOLEAN)),
                    ),
                )
                profile = None
            else:
                profile = parse_skill_json(req.name, req.payload)
                changes = ChangeSet(
                    remove=((node, None),),
                    add=(
                        Triple(node, vocab.RDF_TYPE, vocab.TWIN_SKILL),
                        Triple(node, vocab.RDFS_LABEL, Literal(req.name)),
                        Triple(node, vocab.TWIN_PROFILE_JSON, Literal(json.dumps(profile.to_json()))),
                    ),
                )
            self.store.apply(changes)
        except TwinError as err:
            log.info("Refused a skill change for %r: %s", req.name, err)
            return Reply.error(str(err))
        self.revision += 1
        for storey, skill in self.engine.remove_skill(req.name):
            self._published.pop((storey, skill), None)
            self._counters.pending_full.pop((storey, skill), None)
            self._emit(MapRemoved(storey, skill, self.revision, stamp))
        if profile is None:
            del self.skills[req.name]
        else:
            self.skills[req.name] = profile
        self._emit(SkillChanged(req.name, profile, self.revision, stamp))
        maps = self._add_skill_maps(profile, stamp) if profile is not None else []
        return Reply(
            True,
            {
                "ok": True,
                "revision": self.revision,
                "skill": req.name,
                "removed": profile is None,
                "maps": [
                    {"storey": m.plan.storey.key, "skill": req.name, "version": m.version} for m in maps
                ],
            },
        )

    # --- read-only views (any thread) -----------------------------------------------------------------
    def published(self, storey: str, skill: str) -> PublishedMap | None:
        """The latest full map published for (storey, skill), or None."""
        return self._published.get((storey, skill))

    def published_maps(self) -> list[PublishedMap]:
        return list(self._published.values())

    def status(self) -> dict[str, object]:
        now = self.clock()
        return {
            "site": self.config.site,
            "revision": self.revision,
            "elements": sum(1 for s in self._states.values() if not s.removed),
            "triples": len(self.store),
            "skills": sorted(self.skills),
            "storeys": [s.key for s in self.engine.scene.storeys],
            "maps": [
                {"storey": p.grid.storey, "skill": p.grid.skill, "version": p.version, "revision": p.revision}
                for p in sorted(self._published.values(), key=lambda p: (p.grid.storey, p.grid.skill))
            ],
            "observations": {"accepted": self._counters.accepted, "rejected": self._counters.rejected},
            "queue_depth": self.queue_depth,
            "uptime_s": round((now - self._counters.started_ns) / 1e9, 3),
        }

    def query(self, sparql: str) -> tuple[str, bytes]:
        """A read-only SPARQL query, bounded in time and result size; QueryError names the problem."""
        limits = self.config.limits
        if _UPDATE.search(_PREFIXES.sub("", sparql)):
            msg = "This SPARQL endpoint is read-only: updates (INSERT, DELETE, LOAD, CLEAR, ...) are refused."
            raise QueryError(msg)
        result: list[tuple[str, bytes] | BaseException] = []

        def run() -> None:
            try:
                result.append(self.store.query_serialized(sparql))
            except BaseException as err:
                result.append(err)

        worker = threading.Thread(target=run, name="twin-sparql", daemon=True)
        worker.start()
        worker.join(limits.sparql_timeout_s)
        if not result:
            msg = f"The SPARQL query took longer than {limits.sparql_timeout_s} s and was abandoned."
            raise QueryError(msg)
        out = result[0]
        if isinstance(out, BaseException):
            if isinstance(out, TwinError):
                raise out
            msg = f"SPARQL query failed: {out}"
            raise QueryError(msg) from out
        if len(out[1]) > limits.sparql_result_bytes:
            msg = (
                f"The SPARQL result is {len(out[1]):,} bytes, more than the "
                f"{limits.sparql_result_bytes:,} allowed: add a LIMIT."
            )
            raise QueryError(msg)
        return out
