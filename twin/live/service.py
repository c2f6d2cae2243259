"""The twin service: the single writer of the twin, with no transport.

It loads the graph (:func:`~twin.maps.scene.load_scene`), builds every skill map of every storey, and then
handles requests one at a time on its own worker thread: robot observations (:mod:`twin.live.observe`:
the hot path) and skill profiles added or removed at run time (:mod:`twin.live.skill_changes`). After
each committed change it bumps the twin's revision and emits events (:mod:`twin.live.events`) to its sinks:
the changed rectangle of every affected map at once, and a changed map in full only as a keyframe (at
most every ``limits.keyframe_interval_s``; see :mod:`twin.live.publication`). Requests come from any
thread (e.g. Zenoh callbacks, which only enqueue); replies go to the callback given with each request.
Every ``flush_every_s`` it flushes the store's buffers so that memory and the store's log stay flat
all day.

Example::

    service = TwinService(store, cfg, sinks=[publisher, recorder])
    service.start()                                   # loads, builds, publishes every map
    service.submit_observation("robot1", turtle, reply=print)
    service.serve_forever(stop_event)                 # or service.process(timeout_s=...) in tests
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence

from twin.config import Config
from twin.errors import TwinError
from twin.fusion.poses import build_poses
from twin.graph.store import GraphStore
from twin.live.events import ElementShape, RobotStoreyChanged, TwinEvent, TwinSink, TwinStarted
from twin.live.explain import explain_cell
from twin.live.live_maps import LiveMaps
from twin.live.live_points import PointsPublication
from twin.live.loading import catch_up, load_live_or_restore
from twin.live.observe import Observer, element_shapes
from twin.live.publication import Publication, PublishedVersion
from twin.live.query import QueryWorkers, run_query
from twin.live.requests import (
    ExplainRequest,
    ObserveRequest,
    Reply,
    ReplyFn,
    Request,
    RequestQueue,
    SkillRequest,
    StoreyRequest,
)
from twin.live.skill_changes import apply_skill, publish_all_maps
from twin.live.snapshots import Restored, Snapshots
from twin.live.state import ElementState, LiveState
from twin.live.status import service_status
from twin.live.store_health import WatchedStore
from twin.live.tombstones import FORGET_BATCH, forget_restored
from twin.live.validate import Checked
from twin.records import Observation
from twin.selection.skills import SkillProfile

log = logging.getLogger(__name__)

Clock = Callable[[], int]
_ALIAS_CHECK_S = 10.0
"""How often the writer looks for aliases unused for ``[fusion] alias_ttl_s`` and for tombstones older
than ``[fusion] tombstone_ttl_s``."""
_HOUSEKEEPING_S = 1.0
"""How long the writer works through its queue before it looks at its flushes, expiries and snapshot
(a queue that never runs dry, at saturation, would hold them back for good: memory and the store's log
would grow with every change)."""
STORE_RETRY_S = 2.0
"""How often the writer tries to make a failed store work again (reopen and probe, or ask)."""


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
        batch_wait_s: float = 0.0,
        flush_every_s: float | None = None,
        housekeeping: Sequence[Callable[[], None]] = (),
        snapshot: Snapshots | None = None,
        warm_ups: Sequence[tuple[str, Callable[[LiveState], None]]] = (),
    ) -> None:
        """``max_batch``: at most this many queued observations share one commit and one map pass
        (group commit); ``batch_wait_s``: how long the writer waits, once it has taken an observation,
        for more to join its batch (robots that report at the same instants share one commit, one map
        pass and one send of their acks; the first waits that much longer for its ack).
        ``flush_every_s``: flush the store's buffers this often (if anything changed;
        default ``[store] flush_every_s``), then run each of ``housekeeping`` (e.g. give freed memory
        back to the system). ``snapshot``: where the derived state is kept between runs (read by
        :meth:`start`, written on a clean stop and in the background; see :mod:`twin.live.snapshots`).
        ``warm_ups``: named steps :meth:`start` runs last, after the maps (see :meth:`warm_up`)."""
        self.store = store if isinstance(store, WatchedStore) else WatchedStore(store)
        """The store, watched: :attr:`store_health` says what it can do (:mod:`twin.live.store_health`)."""
        self.store_health = self.store.health
        self._store_tried = 0.0  # monotonic time of the last attempt to make a failed store work again
        self.config = config
        self.sinks = list(sinks)
        self.clock = clock
        self.flush_every_s = config.store_flush_every_s if flush_every_s is None else flush_every_s
        self.housekeeping = list(housekeeping)
        self.snapshot = snapshot
        self.restored_from: int | None = None
        """The revision of the snapshot :meth:`start` restored the maps from (None: built from the store)."""
        self._completing: Restored | None = None
        self._queue = RequestQueue(max_batch, wait_s=batch_wait_s)
        self.publication = Publication(
            emit=self._emit, clock=clock, keyframe_s=config.limits.keyframe_interval_s
        )
        self.points_publication = PointsPublication(emit=self._emit, clock=clock)
        """The points skills' clouds (whole, at a bounded rate: see :mod:`twin.live.live_points`)."""
        self._live: LiveState | None = None
        self._observer: Observer | None = None
        self.started_ns = 0
        self._flushed_at = (0.0, 0)  # (monotonic time, revision) of the last flush
        self._base_iri = ""
        self.warm_ups = list(warm_ups)
        """What the first request would otherwise build lazily, as (name, step): :meth:`warm_up`."""
        self.queries = QueryWorkers()
        """The SPARQL queries' worker threads: a stop closes it (no new query) and waits for them."""

    # --- start ----------------------------------------------------------------------------------------
    def start(self) -> None:
        """Load the twin, build every map, and emit TwinStarted then MapPublished for each map."""
        t0 = time.perf_counter()
        self.started_ns = self.clock()
        live, self._base_iri, restored = load_live_or_restore(self.store, self.config, self.snapshot)
        self.restored_from = None if restored is None else restored.revision
        scene = live.maps.scene
        self._live = live
        forgotten: list[str] = []
        if restored is not None:
            catch_up(self.store, live, restored)
            forgotten = forget_restored(self.store, live, self._base_iri)
            if forgotten:
                log.info("Forgot %d removed elements the snapshot still held", len(forgotten))
        if self.config.fusion.enabled:  # before serving: the first observation waits for nothing
            t_poses = time.perf_counter()
            build_poses(live)
            log.info("Indexed the poses of dynamic elements in %.2f s", time.perf_counter() - t_poses)
        self._observer = Observer(
            self.store,
            self.config,
            live,
            emit=self._emit,
            send=_send,
            clock=self.clock,
            publication=self.publication,
            base_iri=self._base_iri,
        )
        self._flushed_at = (time.monotonic(), live.revision)
        stamp = self.clock()
        self._emit(
            TwinStarted(
                site=self.config.site,
                revision=live.revision,
                stamp_ns=stamp,
                storeys=tuple((s.key, s.name, s.elevation_m) for s in scene.storeys),
                elements=self.element_shapes(),
                skills=dict(live.skills),
            )
        )
        self._completing = publish_all_maps(self.store, live, self.publication, restored, stamp)
        self.warm_up()
        log.info(
            "Twin started at revision %d: %d maps of %d skills on %d storeys in %.2f s",
            live.revision,
            len(self.publication.latest),
            len(live.skills),
            len(scene.storeys),
            time.perf_counter() - t0,
        )
        if self.snapshot is not None and (
            restored is None
            or restored.skills != frozenset(live.skills)
            or restored.revision < live.revision
            or forgotten
        ):
            self.snapshot.save_in_background(live)  # rebuilt, replayed or pruned: keep the result

    def warm_up(self) -> None:
        """Build now what the first request would otherwise wait for, so that a started service is
        ready (``twin serve`` says ``serving`` after this): the world triangles of a scene restored
        from the snapshot (1.2-1.5 s on Janesville, else paid by the first observation), then each of
        :attr:`warm_ups` in turn (the place for any other state built on first use, e.g. fusion's
        per-storey poses). Called by :meth:`start`; each step runs once per start."""
        self.complete_scene()
        for name, step in self.warm_ups:
            t = time.perf_counter()
            step(self.live)
            log.info("Start-up step %r done in %.2f s", name, time.perf_counter() - t)

    def save_snapshot(self) -> None:
        """Write the snapshot now (a clean stop); a failure is logged, never raised."""
        if self.snapshot is not None and self._live is not None:
            try:
                self.snapshot.save(self._live)
            except Exception:  # an optimisation: never worth a failed stop
                log.exception("Could not save the snapshot %s", self.snapshot.path)

    @property
    def live(self) -> LiveState:
        if self._live is None:
            msg = "The twin service has not been started."
            raise TwinError(msg)
        return self._live

    @property
    def observer(self) -> Observer:
        if self._observer is None:
            msg = "The twin service has not been started."
            raise TwinError(msg)
        return self._observer

    @property
    def live_maps(self) -> LiveMaps:
        """The live maps (every (storey, skill) map and the geometry they are drawn from)."""
        self.complete_scene()
        return self.live.maps

    @property
    def revision(self) -> int:
        return self._live.revision if self._live is not None else 0

    @property
    def skills(self) -> dict[str, SkillProfile]:
        return dict(self._live.skills) if self._live is not None else dict(self.config.skills)

    @property
    def states(self) -> dict[str, ElementState]:
        """Every element's state (read it, never change it)."""
        return self.live.states

    def element_shapes(self, iris: Sequence[str] | None = None) -> tuple[ElementShape, ...]:
        """The current shape of the given elements (default: all with geometry)."""
        return element_shapes(self.live, iris if iris is not None else sorted(self.live.states))

    # --- events ---------------------------------------------------------------------------------------
    def _emit(self, event: TwinEvent) -> None:
        for sink in self.sinks:
            try:
                sink.emit(event)
            except Exception:  # a sink must never stop the twin
                log.exception("Sink %s failed on %s", type(sink).__name__, type(event).__name__)

    def flush_full_maps(self, *, due_only: bool = False) -> None:
        """Publish the full version of every map changed since its last full publication; with
        ``due_only``, only the keyframes that are due (``keyframe_interval_s`` since the last one)."""
        if self._live is not None:
            self.publication.flush(self._live.maps.skill_maps, self._live.revision, due_only=due_only)
            self.points_publication.flush(self._live.maps.points, self._live.revision, due_only=due_only)

    def recover_store(self, *, due_only: bool = False) -> bool:
        """If the store has failed (read-only: a full disk; unreachable), try to make it work again (at
        most every :data:`STORE_RETRY_S` with ``due_only``); True if it is ok. On the writer's thread:
        an embedded store is reopened, which no write may overlap."""
        if self.store_health.ok:
            return True
        if due_only and time.monotonic() - self._store_tried < STORE_RETRY_S:
            return False
        self._store_tried = time.monotonic()
        return self.store.recover()

    def flush_store(self, *, due_only: bool = False) -> None:
        """Flush the store's buffers if anything was committed since the last flush (with ``due_only``:
        and ``flush_every_s`` has passed)."""
        at, revision = self._flushed_at
        if self.revision == revision or (due_only and time.monotonic() - at < self.flush_every_s):
            return
        if not self.store_health.ok:  # nothing was committed since it failed; a flush would fail too
            return
        try:
            self.store.flush()
        except Exception:  # a failed flush costs nothing yet: the commits are in the log
            log.exception("Could not flush the store")
        for job in self.housekeeping:
            try:
                job()
            except Exception:
                log.exception("Housekeeping %r failed", job)
        self._flushed_at = (time.monotonic(), self.revision)

    # --- requests (any thread) ------------------------------------------------------------------------
    def submit_observation(
        self,
        robot: str,
        payload: bytes | Observation | Checked,
        reply: ReplyFn | None = None,
        *,
        received_ns: int | None = None,
    ) -> None:
        """Queue an observation by ``robot``: a Turtle document, or the typed records an adapter in this
        process made (validated by the same checks as a parsed document: :mod:`twin.live.validate`;
        :class:`~twin.live.validate.Checked` records, checked where they were made under the same
        limits, are not checked again); ``reply`` gets the ack (or error) once it is durable.
        ``received_ns``: when it arrived, if it was taken where it arrived (default: now)."""
        now = self.clock() if received_ns is None else received_ns
        if isinstance(payload, Observation):
            self._queue.put(ObserveRequest(robot, b"", reply, now, observation=payload))
        elif isinstance(payload, Checked):
            passed = payload.passed(self.config.limits)
            self._queue.put(ObserveRequest(robot, b"", reply, now, payload.observation, checked=passed))
        else:
            self._queue.put(ObserveRequest(robot, bytes(payload), reply, now))

    def submit_explain(self, storey: str, skill: str, x: float, y: float, reply: ReplyFn) -> None:
        """Queue the question why the cell at world ``(x, y)`` of map (``storey``, ``skill``) is what it
        is; ``reply`` gets the answer (see :mod:`twin.live.explain`)."""
        self._queue.put(ExplainRequest(storey, skill, x, y, reply))

    def submit_storey(
        self, robot: str, storey: str, *, source: str = "zenoh", reply: ReplyFn | None = None
    ) -> None:
        """Queue a robot's storey switch (the lift): the writer checks the robot and the storey, keeps the
        robot's storey and emits :class:`~twin.live.events.RobotStoreyChanged` to the sinks (the ROS 2
        publisher republishes that robot's topics on it); ``reply`` gets ``{"storey", "previous",
        "changed"}`` or the refusal naming the unknown robot or storey."""
        self._queue.put(StoreyRequest(robot, storey, source, reply))

    def robot_storey(self, robot: str) -> str | None:
        """The storey the writer last put ``robot`` on (its configured one at start)."""
        return self.live.robot_storeys.get(robot)

    def submit_skill(self, name: str, payload: bytes | None, reply: ReplyFn | None = None) -> None:
        """Queue a skill profile (JSON) to add or replace ``name``, or its removal (``payload`` None)."""
        self._queue.put(SkillRequest(name, None if payload is None else bytes(payload), reply))

    @property
    def queue_depth(self) -> int:
        return self._queue.depth

    # --- the worker -----------------------------------------------------------------------------------
    def complete_scene(self) -> None:
        """Compute the world triangles a start from the snapshot left for later (once)."""
        if self._completing is not None:
            t = time.perf_counter()
            self._completing.complete()
            self._completing = None
            log.info("The restored scene's triangles computed in %.2f s", time.perf_counter() - t)

    def process(self, *, timeout_s: float = 0.0, budget_s: float | None = None) -> int:
        """Handle queued requests until the queue is empty (waiting up to ``timeout_s`` for the first),
        publishing the full maps that are due; with ``budget_s``, take no new work once that long has
        passed (a queue that never runs dry must not hold back :meth:`serve_forever`'s flushes and
        expiries). Returns the number handled.

        Updates go out at once; a changed map goes out in full only as a keyframe, at most every
        ``keyframe_interval_s`` (see :mod:`twin.live.publication`).
        """
        self.complete_scene()
        handled = 0
        work = self._queue.take(timeout_s)
        until = None if budget_s is None else time.monotonic() + budget_s
        while work is not None:
            if isinstance(work, list):  # observations queued one behind the other: one batch
                self._observe(work)
                handled += len(work)
            elif isinstance(work, ExplainRequest):
                self._explain(work)
                handled += 1
            elif isinstance(work, StoreyRequest):
                self._switch_storey(work)
                handled += 1
            else:
                self._change_skill(work)
                handled += 1
            self.flush_full_maps(due_only=True)
            work = None if until is not None and time.monotonic() >= until else self._queue.take()
        self.flush_full_maps(due_only=True)
        return handled

    def serve_forever(
        self, stop: threading.Event, *, poll_s: float = 0.05, on_stop: Callable[[], None] | None = None
    ) -> None:
        """Handle requests until ``stop`` is set, then finish what is queued and publish every map.
        ``on_stop`` runs first when the stop is seen (e.g. let no new request in)."""
        aliases_checked = time.monotonic()
        backlog = False  # the last pass forgot a full batch of tombstones: more are due
        while not stop.is_set():
            self.process(timeout_s=poll_s, budget_s=_HOUSEKEEPING_S)
            self.recover_store(due_only=True)
            self.flush_store(due_only=True)
            if time.monotonic() - aliases_checked > _ALIAS_CHECK_S:
                aliases_checked = time.monotonic()
                self.observer.expire_aliases()
                self.observer.expire_unconfirmed()
                backlog = True
            if backlog:  # a batch a turn, the queue served in between (see twin.live.tombstones)
                backlog = self.observer.forget_tombstones() == FORGET_BATCH
            if self.snapshot is not None and self.snapshot.due(self.revision):
                self.snapshot.save_in_background(self.live)
        if on_stop is not None:
            on_stop()
        self.process()
        self.flush_full_maps()
        self.flush_store()
        self.save_snapshot()

    def _observe(self, batch: Sequence[ObserveRequest]) -> None:
        try:
            self.observer.observe_batch(batch)
        except Exception as err:  # a bug must cost these requests, never the daemon
            log.exception("Internal error while handling %d observations", len(batch))
            for request in batch:
                _send(request, Reply.error(f"Internal error ({type(err).__name__}): {err}"))

    def _explain(self, req: ExplainRequest) -> None:
        try:
            body = explain_cell(self.live, self.store, req.storey, req.skill, x=req.x, y=req.y)
            reply = Reply(True, {"ok": True, **body})
        except TwinError as err:
            reply = Reply.error(str(err))
        except Exception as err:  # a bug must cost one request, never the daemon
            log.exception("Internal error while explaining a cell")
            reply = Reply.error(f"Internal error ({type(err).__name__}): {err}")
        _send(req, reply)

    def _switch_storey(self, req: StoreyRequest) -> None:
        live = self.live
        if req.robot not in self.config.robots:
            known = ", ".join(sorted(self.config.robots)) or "none"
            _send(
                req,
                Reply.error(f"Unknown robot {req.robot!r}: configured robots ([robots.NAME]) are {known}."),
            )
            return
        if req.storey not in live.site.storeys:
            known = ", ".join(s.key for s in live.maps.scene.storeys) or "none"
            _send(
                req,
                Reply.error(
                    f"Unknown storey {req.storey!r} for robot {req.robot!r}: the twin's storeys are {known}."
                ),
            )
            return
        previous = live.robot_storeys.get(req.robot)
        changed = previous != req.storey
        if changed:
            live.robot_storeys[req.robot] = req.storey
            self._emit(
                RobotStoreyChanged(req.robot, req.storey, previous, req.source, live.revision, self.clock())
            )
        body: dict[str, object] = {"ok": True, "robot": req.robot, "storey": req.storey, "previous": previous}
        _send(req, Reply(True, body | {"changed": changed}))

    def _change_skill(self, req: SkillRequest) -> None:
        try:
            reply = apply_skill(
                self.store,
                self.live,
                req,
                base_iri=self._base_iri,
                publication=self.publication,
                emit=self._emit,
                stamp=self.clock(),
            )
        except Exception as err:  # a bug must cost one request, never the daemon
            log.exception("Internal error while handling a skill")
            reply = Reply.error(f"Internal error ({type(err).__name__}): {err}")
        _send(req, reply)

    # --- read-only views (any thread) -----------------------------------------------------------------
    def published(self, storey: str, skill: str) -> PublishedVersion | None:
        """The latest full map published for (storey, skill), or None."""
        return self.publication.latest.get((storey, skill))

    def published_maps(self) -> list[PublishedVersion]:
        return list(self.publication.latest.values())

    def status(self) -> dict[str, object]:
        """What ``twin status`` shows: revision, elements, maps, observation counts, queue, uptime."""
        return service_status(self)

    def query(self, sparql: str) -> tuple[str, bytes]:
        """A read-only SPARQL query, bounded in time and result size; QueryError names the problem."""
        return run_query(self.store, sparql, limits=self.config.limits, workers=self.queries)


def _send(request: Request, reply: Reply) -> None:
    if request.reply is not None:
        try:
            request.reply(reply)
        except Exception:
            log.exception("Could not send a reply")
