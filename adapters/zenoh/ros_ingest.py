"""ROS 2 robots and the building's Open-RMF systems report to the twin in the messages they already
publish: subscribed in their layouts, translated into observations, submitted on the core's path.

- per robot with ``[robots.NAME.detections]``: ``/<ns>/<topic>`` (``vision_msgs/msg/Detection3DArray``),
  ``/<ns>/tf`` and ``/<ns>/tf_static`` (``tf2_msgs/msg/TFMessage``, the latter latched), and with
  ``camera_info`` its ``sensor_msgs/msg/CameraInfo`` (latched: its fields of view for the views);
- per ``[sources.NAME]``: ``/<ns>/door_states`` (``rmf_door_msgs/msg/DoorState``) or
  ``/<ns>/rmf_obstacles`` (``rmf_obstacle_msgs/msg/Obstacles``).

Layouts as :mod:`adapters.zenoh.ros_maps` serves maps: ``bridge`` (zenoh-bridge-ros2dds: key ``<ns>/<topic>``,
payload the CDR bytes) and ``rmw_zenoh`` (``<domain>/<ns>/<topic>/<dds type>/<RIHS01 hash>``, with a
subscriber liveliness token in the ROS graph). On rmw_zenoh the subscription covers every type on the
topic, so a publisher of another type (or hash) is refused and counted as ``wrong_type``.

A robot's messages (TF, camera info, detection arrays) go to its ingest worker process
(:mod:`adapters.zenoh.ros_workers`; ``[ros] ingest_workers``, 0: this process's ingest thread), the
sources' (doors, obstacles) to the ingest thread; Zenoh's callbacks only queue them, with their arrival
time (a full queue drops the message and counts ``overflow``, by kind: ROS topics carry no ack, and a
slow twin must not stall Zenoh). Each resulting observation is submitted with
``TwinService.submit_observation(owner, records)``: the core's typed records for detection arrays (no
Turtle written and parsed again), Turtle for the rest; the same validation, rights, limits, fusion,
durability and map updates as any observation; its ack is counted per robot or source (accepted,
unchanged, refused by cause, last refusal) in the daemon's status (``ros_ingest``). Every cause of
refusal is logged once per robot or source, then counted silently.

The view of a detection array is cut by the structure in the ``view_skill`` map of the robot's storey,
which this object keeps as a sink of the service (``MapPublished``/``MapUpdated``) and feeds to the
robots' translator (each worker), with the storeys' elevations and every storey switch. Whether the core
reads the fusion terms (views, sense times) is probed once: until it does, documents carry the
elements alone.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import zenoh

from adapters.ros.detections import DetectionSettings
from adapters.ros.diagnostics import Counts, encode_diagnostics
from adapters.ros.interfaces import (
    CAMERA_INFO,
    DETECTION_3D_ARRAY,
    DIAGNOSTIC_ARRAY,
    DOOR_STATE,
    OBSTACLES,
    TF_MESSAGE,
)
from adapters.ros.observation_doc import BoxReport, RosInputError, Translation, ViewReport, observation_turtle
from adapters.ros.rmf import (
    HELD_OBSTACLES,
    DoorIndex,
    DoorSettings,
    Level,
    ObstacleSettings,
    ObstacleTracker,
    held_obstacles,
    translate_door_state,
)
from adapters.ros.rmw_zenoh import (
    DEFAULT_QOS,
    STATE_QOS,
    RosNode,
    RosTopic,
    attachment,
    dds_type_name,
    gid_of,
    resolve_name,
    type_hash,
)
from adapters.ros.sessions import TrackerSession
from adapters.ros.settings import RosSettings, ros_robots, ros_sources
from adapters.zenoh.latched import CDR, declare_latched_subscriber
from adapters.zenoh.ros_workers import (
    ROBOT_KINDS,
    Outcome,
    Refused,
    RobotSpec,
    RobotTranslator,
    Translated,
    Waited,
    WorkerPool,
)
from twin.config import Config, Limits
from twin.errors import ObservationError
from twin.graph.rdf import Row
from twin.live.events import MapPublished, MapUpdated, RobotStoreyChanged, TwinEvent, TwinStarted
from twin.live.parse import parse_observation
from twin.live.requests import Reply, ReplyFn
from twin.live.validate import Checked
from twin.maps.grid import OccupancyGrid
from twin.records import Observation

__all__ = ["INGEST_NODE", "RosIngest", "core_reads_fusion_terms", "source_node"]

log = logging.getLogger(__name__)

INGEST_NODE = "twin_ingest"


def source_node(source: str) -> str:
    """The ingest node's name for a source (``twin_ingest_building_doors``): sources share a namespace (the
    root, by default), so each needs a name of its own (ROS warns of duplicate node names); a robot's is
    :data:`INGEST_NODE` in its own namespace."""
    return f"{INGEST_NODE}_{source.replace('-', '_')}"


_NODE_ID_BASE = 10_000  # node ids of this session's ingest nodes (the map server's count from 0)
DIAGNOSTICS_TOPIC = "diagnostics"
DIAGNOSTICS_S = 1.0
"""How often the DiagnosticArray of a robot or source that asked for it is published."""
MAX_WAITING = 64
"""Arrays per robot waiting for TF at most; more are translated at once (and refused if still unresolved)."""
MAX_STATIC = 32
"""``tf_static`` messages kept per robot, to feed a restarted worker again."""


class Submit(Protocol):
    """``TwinService.submit_observation``: a document or typed records, the ack to ``reply``,
    ``received_ns`` the arrival time (taken where the message arrived)."""

    def __call__(
        self,
        robot: str,
        payload: bytes | Observation | Checked,
        reply: ReplyFn | None = None,
        *,
        received_ns: int | None = None,
    ) -> None: ...


def core_reads_fusion_terms(limits: Limits) -> bool:
    """Whether the core's observation parser accepts a view and a sense time (issue 28's terms)."""
    doc = observation_turtle(
        boxes=[BoxReport("urn:twin-ros:probe:det:1", "IfcFurniture", "s", (0, 0, 0.5, 1, 1, 1, 0))],
        view=ViewReport("s", (((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)),), ("IfcFurniture",), origin=(0, 0, 1)),
        sense_ns=1_700_000_000_000_000_000,
    )
    assert doc is not None
    try:
        parse_observation(doc, limits=limits)
    except ObservationError:
        return False
    except Exception:  # a parser of another shape: do not guess
        log.debug("Probing the core's fusion terms failed", exc_info=True)
        return False
    return True


@dataclass(eq=False, slots=True)
class _Out:
    """A publisher; on rmw_zenoh with its gid and sequence number for the attachment."""

    publisher: Any
    gid: bytes | None = None
    sequence: int = 0

    def put(self, payload: bytes, stamp_ns: int) -> None:
        if self.gid is None:
            self.publisher.put(payload)
            return
        self.sequence += 1
        self.publisher.put(payload, attachment=attachment(self.sequence, stamp_ns, self.gid))


@dataclass(frozen=True, slots=True)
class _Message:
    owner: str
    kind: str  # "detections", "tf", "tf_static", "camera_info", "doors", "obstacles", "wrong_type"
    payload: bytes
    note: str = ""
    received_ns: int = 0


class RosIngest:
    """Subscribes to the configured robots' detections and TF and the sources' RMF topics; a TwinSink.

    ``submit`` is ``TwinService.submit_observation``; ``storey_of(robot)`` the robot's current storey
    (``RosMapPublisher.storey_of``). Add it to the service's sinks before the service starts (it learns
    the storeys, the doors and the maps that occlude views from the events), and ``close`` it.

    It keeps its own copy of the ``view_skill`` maps (``_grids``), beside the daemon's ``LatestMaps``:
    its worker cuts views with a grid it reads without a lock, so each version is a new array (copy on
    write), where the holder applies updates in place under its lock; and only the view skills.
    """

    def __init__(
        self,
        session: zenoh.Session,
        config: Config,
        submit: Submit,
        *,
        storey_of: Callable[[str], str | None],
        clock: Callable[[], int] = time.time_ns,
        fusion_terms: bool | None = None,
        queue_depth: int | None = None,
        select: Callable[[str], list[Row]] | None = None,
        typed: bool = True,
        workers: int | None = None,
        sessions: Mapping[str, TrackerSession] | None = None,
    ) -> None:
        """``select``: a read-only SPARQL SELECT on the twin's store (the daemon's): with it, the
        obstacle trackers take back at start-up (on TwinStarted, before any message is handled) the
        obstacles a previous run added, with their lifetimes (:func:`~adapters.ros.rmf.held_obstacles`).
        ``typed``: detection arrays go to ``submit`` as the core's typed records (an
        :class:`~twin.records.Observation`, checked by the same validator as a parsed document) rather
        than as Turtle text that the core would parse again; False: Turtle (a ``submit`` that only takes
        documents). ``workers`` and ``queue_depth``: ``[ros] ingest_workers`` and ``ingest_queue`` unless
        given (0 workers: the robots' messages are translated in this process's ingest thread)."""
        ros = config.section(RosSettings)
        self.submit = submit
        self.typed = typed
        self.queue_depth = ros.ingest_queue if queue_depth is None else queue_depth
        self.tf_wait_s = ros.tf_wait_s
        self.hold_steady_s = ros.hold_steady_ms / 1e3
        worker_count = ros.workers() if workers is None else max(0, workers)
        self.select = select
        self._held: list[tuple[str, int | None]] = []
        self._restored = threading.Event()
        """Set once the obstacles of a previous run are known (at once without ``select``)."""
        self.storey_of = storey_of
        self.clock = clock
        self.fusion_terms = core_reads_fusion_terms(config.limits) if fusion_terms is None else fusion_terms
        self._lock = threading.Lock()
        self._queue: queue.Queue[_Message | None] = queue.Queue(maxsize=self.queue_depth)
        self._counts: dict[str, Counts] = {}
        self._robots: dict[str, RobotSpec] = {}
        self._static: dict[str, list[bytes]] = {}
        """Each robot's latest ``tf_static`` messages and camera info, to feed a restarted worker."""
        self._camera: dict[str, bytes] = {}
        self._lost: dict[str, int] = {}
        self._sessions: dict[str, TrackerSession] = {}
        """Each robot's tracker session as its translator last told (the status; a restarted worker)."""
        self._doors: dict[str, DoorSettings] = {}
        self._obstacles: dict[str, ObstacleTracker] = {}
        self._door_index = DoorIndex(())
        self._elevations: dict[str, float] = {}
        self._grids: dict[tuple[str, str], OccupancyGrid] = {}
        self._entities: list[Any] = []
        self._diagnostics: dict[str, list[_Out]] = {}
        self._refused_before: dict[str, int] = {}
        self._next_diagnostics = time.monotonic() + DIAGNOSTICS_S
        zid = str(session.zid())
        node_id = _NODE_ID_BASE
        entity = 0
        for robot in sorted(ros_robots(config).values(), key=lambda r: r.name):
            d = robot.detections
            if d is None or robot.namespace is None:
                continue
            settings = DetectionSettings.from_config(robot.name, d, config.limits)
            resumed = (sessions or {}).get(robot.name) or TrackerSession()
            self._robots[robot.name] = RobotSpec(robot.name, settings, d.view_skill, session=resumed)
            self._sessions[robot.name] = resumed
            self._counts[robot.name] = Counts()
            node = RosNode(robot.domain_id, robot.namespace, INGEST_NODE, zid, node_id)
            node_id += 1
            topics = [
                (d.topic, DETECTION_3D_ARRAY, "detections", False),
                (d.tf, TF_MESSAGE, "tf", False),
                (d.tf_static, TF_MESSAGE, "tf_static", True),
            ]
            if d.camera_info is not None:
                topics.append((d.camera_info, CAMERA_INFO, "camera_info", True))
            entity = self._subscribe(
                session, owner=robot.name, node=node, layouts=robot.ros, topics=topics, entity=entity
            )
            if d.diagnostics:
                entity = self._declare_diagnostics(session, robot.name, node, robot.ros, entity)
        for source in sorted(ros_sources(config).values(), key=lambda s: s.name):
            self._counts[source.name] = Counts()
            if source.kind == "rmf_doors":
                self._doors[source.name] = DoorSettings(source.name, dict(source.doors))
                kind, type_name = "doors", DOOR_STATE
            else:
                levels = {n: Level(lv.storey, lv.x, lv.y, lv.yaw_rad) for n, lv in source.levels}
                self._obstacles[source.name] = ObstacleTracker(
                    ObstacleSettings(source.name, dict(source.classes), levels, max_size_m=source.max_size_m)
                )
                kind, type_name = "obstacles", OBSTACLES
            node = RosNode(source.domain_id, source.namespace, source_node(source.name), zid, node_id)
            node_id += 1
            entity = self._subscribe(
                session,
                owner=source.name,
                node=node,
                layouts=source.ros,
                topics=[(source.topic, type_name, kind, False)],
                entity=entity,
            )
            if source.diagnostics:
                entity = self._declare_diagnostics(session, source.name, node, source.ros, entity)
        if self.select is None or not self._obstacles:
            self._restored.set()
        specs = list(self._robots.values())
        self._translator: RobotTranslator | None = None
        self._pool: WorkerPool | None = None
        if worker_count == 0 or not specs:
            self._translator = RobotTranslator(
                specs, fusion_terms=self.fusion_terms, typed=typed, clock=clock, tf_wait_s=self.tf_wait_s,
                max_waiting=MAX_WAITING, storey_of=storey_of, limits=config.limits,
            )  # fmt: skip
        else:
            self._pool = WorkerPool(
                specs, worker_count, deliver=self._outcomes, replay=self._replay, on_restart=self._restarted,
                fusion_terms=self.fusion_terms, typed=typed, tf_wait_s=self.tf_wait_s,
                queue_depth=self.queue_depth, limits=config.limits, hold_steady_s=self.hold_steady_s,
            )  # fmt: skip
            for name in self._robots:
                self._pool.feed(("storey", name, storey_of(name)), robot=name)
        self._worker = threading.Thread(target=self._run, name="ros-ingest", daemon=True)
        self._worker.start()
        log.info(
            "ROS 2 ingestion: %d robot(s) with detections in %s, %d source(s); views and sense times %s",
            len(self._robots),
            f"{len(self._pool.workers)} worker process(es)" if self._pool else "the ingest thread",
            len(self._doors) + len(self._obstacles),
            "on" if self.fusion_terms else "off (the core does not read them yet)",
        )  # fmt: skip

    # --- subscriptions (Zenoh threads) --------------------------------------------------------------
    def _subscribe(
        self,
        session: zenoh.Session,
        *,
        owner: str,
        node: RosNode,
        layouts: tuple[str, ...],
        topics: list[tuple[str, str, str, bool]],
        entity: int,
    ) -> int:
        if "rmw_zenoh" in layouts:
            self._entities.append(session.liveliness().declare_token(node.node_token()))
        for name, type_name, kind, latched in topics:
            topic = RosTopic(node.domain_id, *resolve_name(node.namespace, name), type_name)
            if "bridge" in layouts:
                handler = self._handler(owner, kind, None)
                self._entities.append(
                    declare_latched_subscriber(session, topic.bridge_key, handler, max_samples=None)
                    if latched
                    else session.declare_subscriber(topic.bridge_key, handler)
                )
            if "rmw_zenoh" in layouts:
                expected = f"{dds_type_name(type_name)}/{type_hash(type_name)}"
                any_type = f"{node.domain_id}/{topic.fqn.strip('/')}/*/*"
                handler = self._handler(owner, kind, expected)
                self._entities.append(
                    declare_latched_subscriber(session, any_type, handler, max_samples=None)
                    if latched
                    else session.declare_subscriber(any_type, handler)
                )
                token = node.subscriber_token(topic, entity, STATE_QOS if latched else DEFAULT_QOS)
                entity += 1
                self._entities.append(session.liveliness().declare_token(token))
        return entity

    def _declare_diagnostics(
        self, session: zenoh.Session, owner: str, node: RosNode, layouts: tuple[str, ...], entity: int
    ) -> int:
        """Publishers of ``<ns>/diagnostics`` (DiagnosticArray) in ``layouts``."""
        topic = RosTopic(node.domain_id, node.namespace, DIAGNOSTICS_TOPIC, DIAGNOSTIC_ARRAY)
        outs = self._diagnostics.setdefault(owner, [])
        if "bridge" in layouts:
            outs.append(_Out(session.declare_publisher(topic.bridge_key, encoding=CDR)))
        if "rmw_zenoh" in layouts:
            token = node.publisher_token(topic, entity, DEFAULT_QOS)
            entity += 1
            self._entities.append(session.liveliness().declare_token(token))
            pub = session.declare_publisher(
                topic.data_key, encoding=CDR, reliability=zenoh.Reliability.RELIABLE
            )
            outs.append(_Out(pub, gid=gid_of(token)))
        return entity

    def _publish_diagnostics(self) -> None:
        """One DiagnosticArray per owner that asked for it: WARN if it had refusals since the last one."""
        now = time.monotonic()
        if not self._diagnostics or now < self._next_diagnostics:
            return
        self._next_diagnostics = now + DIAGNOSTICS_S
        stamp = self.clock()
        for owner, outs in self._diagnostics.items():
            with self._lock:
                c = self._counts[owner]
                report = c.diagnostic(owner, refused_before=self._refused_before.get(owner, 0))
                self._refused_before[owner] = sum(c.refused.values())
            payload = encode_diagnostics([report], stamp_ns=stamp)
            for out in outs:
                out.put(payload, stamp)

    def _handler(self, owner: str, kind: str, expected: str | None) -> Callable[[zenoh.Sample], None]:
        put = zenoh.SampleKind.PUT
        suffix = f"/{expected}"  # the key is <topic>/<type>/<hash> (the subscription: <topic>/*/*)
        kept = kind in ("tf_static", "camera_info")  # (looked at for every sample)

        def on_sample(sample: zenoh.Sample) -> None:
            if sample.kind != put:
                return
            note = ""
            got_kind = kind
            if expected is not None:
                key = str(sample.key_expr)
                if not key.endswith(suffix):
                    got = "/".join(key.split("/")[-2:])
                    got_kind, note = "wrong_type", f"{key} carries {got}, not {expected}"
            arrived = self.clock()
            payload = sample.payload.to_bytes()
            try:
                if self._pool is not None and got_kind in ROBOT_KINDS and owner in self._robots:
                    self._pool.put(owner, got_kind, payload, arrived)
                    if kept:
                        self._keep(owner, got_kind, payload)
                    with self._lock:
                        c = self._counts[owner]
                        c.received += 1
                        c.messages[got_kind] += 1
                else:
                    self._queue.put_nowait(_Message(owner, got_kind, payload, note, arrived))
            except queue.Full:
                with self._lock:
                    c = self._counts[owner]
                    c.received += 1
                    c.overflow[got_kind] += 1
                    self._refuse(c, owner, "overflow", f"The ingestion queue is full ({self.queue_depth}).")

        return on_sample

    # --- the worker --------------------------------------------------------------------------------
    def _run(self) -> None:
        self._restored.wait()  # the obstacles of a previous run first: a DELETE may name one
        for name, tracker in self._obstacles.items():
            if n := tracker.restore(self._held):
                log.info("RMF source %s: %d obstacle(s) of a previous run held again", name, n)
        while True:
            waiting = self._translator is not None and self._translator.waiting
            timeout = 0.05 if waiting else self._next_expiry_s()
            if self._diagnostics:
                timeout = min(timeout, max(0.0, self._next_diagnostics - time.monotonic()))
            try:
                message = self._queue.get(timeout=timeout)
            except queue.Empty:
                message = None
            else:
                if message is None:
                    return
            try:
                if message is not None:
                    self._handle(message)
                self._expire()
                if self._translator is not None:
                    self._outcomes(self._translator.give_up_waiting())
                self._publish_diagnostics()
            except Exception:  # a bad message must never stop ingestion
                log.exception("ROS 2 ingestion failed on a %s message", message.kind if message else "timer")

    def _next_expiry_s(self) -> float:
        times = [t for tr in self._obstacles.values() if (t := tr.next_expiry()) is not None]
        if not times:
            return 0.5
        return min(0.5, max(0.0, (min(times) - self.clock()) / 1e9))

    def _expire(self) -> None:
        now = self.clock()
        for name, tracker in self._obstacles.items():
            nxt = tracker.next_expiry()
            if nxt is not None and nxt <= now:
                self._deliver(name, tracker.expire(now_ns=now))

    def _handle(self, m: _Message) -> None:
        with self._lock:
            c = self._counts[m.owner]
            c.received += 1
            c.messages[m.kind] += 1
            if m.kind == "wrong_type":
                self._refuse(c, m.owner, "wrong_type", m.note)
                return
        if m.kind in ROBOT_KINDS and self._translator is not None:
            self._outcomes(self._translator.handle(m.owner, m.kind, m.payload, m.received_ns))
            return
        self._translate(m)

    def _translate(self, m: _Message) -> None:
        try:
            if m.kind == "doors":
                with self._lock:
                    index = self._door_index
                translation = translate_door_state(
                    m.payload, self._doors[m.owner], index, fusion_terms=self.fusion_terms
                )
            else:
                translation = self._obstacles[m.owner].translate(
                    m.payload, now_ns=self.clock(), fusion_terms=self.fusion_terms
                )
        except RosInputError as err:
            with self._lock:
                self._refuse(self._counts[m.owner], m.owner, err.cause, str(err))
            return
        self._deliver(m.owner, translation, m.received_ns)

    def _outcomes(self, outcomes: list[Outcome]) -> None:
        """What the robots' translator (here or in a worker) made of their messages."""
        for o in outcomes:
            if isinstance(o, Translated):
                if o.session is not None:
                    with self._lock:
                        self._sessions[o.owner] = o.session
                self._deliver(o.owner, o.translation, o.received_ns)
            elif isinstance(o, Refused):
                with self._lock:
                    self._refuse(self._counts[o.owner], o.owner, o.cause, o.message)
            elif isinstance(o, Waited):
                with self._lock:
                    self._counts[o.owner].waited += 1

    def _keep(self, owner: str, kind: str, payload: bytes) -> None:
        """The latched messages a restarted worker needs again (Zenoh threads)."""
        if kind == "tf_static":
            with self._lock:
                kept = self._static.setdefault(owner, [])
                kept.append(payload)
                del kept[:-MAX_STATIC]
        elif kind == "camera_info":
            with self._lock:
                self._camera[owner] = payload

    def _replay(self, robots: list[str]) -> list[tuple[Any, ...]]:
        """What a restarted worker of ``robots`` is fed again, in order (the pool's thread)."""
        with self._lock:
            grids = list(self._grids.values())
            items: list[tuple[Any, ...]] = [("elevations", dict(self._elevations))]
            items += [("grid", g) for g in grids]
            items += [("storey", r, self.storey_of(r)) for r in robots]
            items += [("session", r, self._sessions[r]) for r in robots if r in self._sessions]
            for r in robots:
                items += [("msg", r, "tf_static", p, self.clock()) for p in self._static.get(r, [])]
                if r in self._camera:
                    items.append(("msg", r, "camera_info", self._camera[r], self.clock()))
        return items

    def _restarted(self, robots: list[str]) -> None:
        with self._lock:
            for r in robots:
                self._lost[r] = self._lost.get(r, 0) + 1

    def _deliver(self, owner: str, t: Translation, received_ns: int | None = None) -> None:
        with self._lock:
            c = self._counts[owner]
            c.ignored.update(t.ignored)
            for cause, message in t.refused:
                self._refuse(c, owner, cause, message)
            documents = t.documents
            c.submitted += len(documents)
        first = 1 if t.document is not None else 0
        for k, document in enumerate(documents):
            settle = t.settle if k < first else None  # the twin's verdict on it
            removes = t.removes[k - first] if first <= k < first + len(t.removes) else None
            reply = self._on_reply(owner, settle, removes)
            self.submit(owner, document, reply, received_ns=received_ns)

    def _on_reply(
        self, owner: str, settle: Callable[[bool], None] | None = None, removes: str | None = None
    ) -> ReplyFn:
        def on_reply(reply: Reply) -> None:
            if settle is not None:  # e.g. an obstacle tracker lets go of what the twin refused
                settle(reply.ok)
            tracker = self._obstacles.get(owner)
            if removes is not None and not reply.ok and tracker is not None and self._holds(removes):
                tracker.removal_refused(removes, now_ns=self.clock())  # tried again in a moment
            with self._lock:
                c = self._counts[owner]
                if not reply.ok:
                    self._refuse(c, owner, "twin", str(reply.body.get("error", "refused")))
                elif reply.body.get("unchanged"):
                    c.unchanged += 1
                else:
                    c.accepted += 1

        return on_reply

    def _holds(self, iri: str) -> bool:
        """Whether the twin still holds ``iri`` (not removed); True when that cannot be asked."""
        if self.select is None:
            return True
        try:
            rows = self.select(
                f"SELECT ?c WHERE {{ <{iri}> twin:ifcClass ?c "
                f"FILTER NOT EXISTS {{ <{iri}> twin:removed true }} }}"
            )
        except Exception:  # the store unreachable: the removal is worth trying again
            return True
        return bool(rows)

    def _refuse(self, c: Counts, owner: str, cause: str, message: str) -> None:
        """Count a refusal (lock held); log its cause the first time for this owner."""
        c.refused[cause] += 1
        c.last_refusal, c.last_refusal_ns = f"{cause}: {message}", self.clock()
        if cause not in c.logged:
            c.logged.add(cause)
            log.warning(
                "Refused a ROS 2 message of %s (%s): %s (logged once per cause)", owner, cause, message
            )

    # --- the sink (service thread) ------------------------------------------------------------------
    def emit(self, event: TwinEvent) -> None:
        try:
            if isinstance(event, TwinStarted):
                doors = [(e.iri, e.name) for e in event.elements if e.ifc_class.startswith("IfcDoor")]
                with self._lock:
                    self._elevations = {key: elevation for key, _, elevation in event.storeys}
                    self._door_index = DoorIndex(doors)
                self._tell(("elevations", dict(self._elevations)))
                if self._pool is not None:
                    for name in self._robots:
                        self._pool.feed(("storey", name, self.storey_of(name)), robot=name)
                if not self._restored.is_set() and self.select is not None:
                    try:
                        self._held = held_obstacles(self.select(HELD_OBSTACLES))
                    finally:
                        self._restored.set()
            elif isinstance(event, MapPublished):
                g = event.grid
                if self._wants(g.skill):
                    own = OccupancyGrid(g.frame, g.data.copy(), g.storey, g.skill, g.elevation_m)
                    with self._lock:
                        self._grids[(g.storey, g.skill)] = own
                    self._tell(("grid", own))
            elif isinstance(event, RobotStoreyChanged):
                if self._pool is not None and event.robot in self._robots:
                    self._pool.feed(("storey", event.robot, event.storey), robot=event.robot)
            elif isinstance(event, MapUpdated):
                with self._lock:
                    grid = self._grids.get((event.storey, event.skill))
                if grid is not None and grid.frame == event.frame:  # copy on write: the worker may read it
                    w = event.window
                    data = grid.data.copy()
                    data[w.row0 : w.row1, w.col0 : w.col1] = event.data
                    own = OccupancyGrid(grid.frame, data, grid.storey, grid.skill, grid.elevation_m)
                    with self._lock:
                        self._grids[(event.storey, event.skill)] = own
                    self._tell(("grid", own))
        except Exception:  # a sink must never stop the twin
            log.exception("ROS 2 ingestion failed on %s", type(event).__name__)

    def _tell(self, item: tuple[Any, ...]) -> None:
        """What the robots' translator must know (elevations, a map version): here, or every worker, in
        order with the messages already queued for it."""
        if self._pool is not None:
            self._pool.feed(item)
        elif self._translator is not None:
            if item[0] == "elevations":
                self._translator.set_elevations(item[1])
            elif item[0] == "grid":
                self._translator.set_grid(item[1])

    def _wants(self, skill: str) -> bool:
        return any(r.view_skill == skill for r in self._robots.values())

    # --- status and lifecycle -----------------------------------------------------------------------
    def status(self) -> dict[str, object]:
        """``{"ros_ingest": {"queue_depth": n, "views": bool, "counts": {owner: {...}}}}``."""
        with self._lock:
            counts = {name: c.as_dict() for name, c in sorted(self._counts.items())}
            for name, n in self._lost.items():  # its worker died n times (the arrays it held lost)
                counts[name]["worker_restarts"] = n
            sessions = dict(self._sessions)
        pool = self._pool
        return {
            "ros_ingest": {
                "queue_depth": self._queue.qsize() + (sum(pool.depths()) if pool is not None else 0),
                "queue_limit": self.queue_depth,
                "queues": {
                    "ingest": self._queue.qsize(),
                    **({f"worker{i}": d for i, d in enumerate(pool.depths())} if pool is not None else {}),
                },
                "workers": 0 if pool is None else len(pool.workers),
                "worker_restarts": 0 if pool is None else pool.restarts,
                "tf_wait_s": self.tf_wait_s,
                "hold_steady_ms": round(self.hold_steady_s * 1e3, 3),
                **(
                    {
                        "worker_bunches": pool.bunches,
                        "worker_outcomes": pool.outcomes,
                        "worker_deliveries": pool.delivered,
                    }
                    if pool is not None
                    else {}
                ),
                "views": self.fusion_terms,
                "obstacles_held": sum(t.held for t in self._obstacles.values()),
                "counts": counts,
                "tracker_sessions": {
                    name: {"session": t.label, "restarts": t.restarts} for name, t in sorted(sessions.items())
                },
            }
        }

    def close(self) -> None:
        self._restored.set()  # a start that never came: the worker must not wait for it
        for entity in [*self._entities, *(o.publisher for outs in self._diagnostics.values() for o in outs)]:
            try:
                entity.undeclare()
            except Exception:
                log.debug("undeclare failed", exc_info=True)
        self._entities.clear()
        while True:
            try:
                self._queue.put(None, timeout=0.1)
                break
            except queue.Full:
                with contextlib.suppress(queue.Empty):
                    self._queue.get_nowait()
        self._worker.join(timeout=5)
        if self._pool is not None:
            self._pool.close()
