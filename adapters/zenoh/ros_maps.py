"""Serve skill maps to ROS 2 robots as map_servers in their namespace would, and follow the storey each
robot is on (a follower of the daemon's dispatcher).

For every configured robot with a namespace (``[robots.NAME]``), each of its topics
(``[robots.NAME.maps]``, topic = skill; default ``map`` = localization for AMCL, ``navigation_map`` =
navigation for the costmap's static layer) carries that skill's map of the robot's current storey as
``/<ns>/<topic>`` (``nav_msgs/OccupancyGrid``, latched) and its changes as ``/<ns>/<topic>_updates``
(``map_msgs/OccupancyGridUpdate``), in the layouts the robot asks for:

- ``bridge``: keys ``<ns>/<topic>`` and ``<ns>/<topic>_updates`` as zenoh-bridge-ros2dds routes them to
  DDS; the map from a :class:`~adapters.zenoh.latched.LatchedPublisher` (publisher detection, late
  joiners answered with the current map: the bridge's route is an AdvancedSubscriber with history);
- ``rmw_zenoh``: rmw_zenoh_cpp's data keys with domain, DDS type name and RIHS01 hash, every sample
  with the 33-byte rmw attachment (sequence number per publisher from 1, source time, gid); the map
  from a LatchedPublisher with publisher detection and a 500 ms sporadic heartbeat, as rmw_zenoh's
  TRANSIENT_LOCAL publishers (whose subscriptions query history and recover by heartbeat);
  and liveliness tokens (one per publisher and subscriber) that put the daemon in the ROS graph as
  node ``<ns>/twin_map_server``.

**nav2 costmap filters.** A topic whose skill is a mask (``kind = "keepout"`` or ``"speed"``) also gets
``/<ns>/<topic>_info`` (``nav2_msgs/msg/CostmapFilterInfo``, latched, published once: type 0 for
keepout, 1 for a speed limit in percent; the mask topic's full name; base 0, multiplier 1), which is
what nav2's ``KeepoutFilter`` and ``SpeedFilter`` read as their ``filter_info_topic``.

**Storey switching.** A robot's current storey starts as its configured ``storey`` and changes at run
time through ``twin/<site>/robots/<name>/storey`` (a put of the storey key; a ``get`` answers the
current one, a ``get`` with a storey key as payload switches and answers, or replies an error) or
through the ROS topic ``/<ns>/storey`` (``std_msgs/msg/String``, subscribed in the robot's layouts,
with a subscriber liveliness token on rmw_zenoh). Every switch is a request to the twin's writer
(``TwinService.submit_storey``, through :meth:`RosMapPublisher.ask`): the writer refuses an unknown
robot or storey with an error naming it (nothing changes), keeps each robot's storey and emits
:class:`~twin.live.events.RobotStoreyChanged` on its own thread (the Rerun recording logs it); the same
storey again is a no-op (robots re-report it often). When that event reaches this publisher (on the
daemon's dispatcher) every topic of the robot republishes the new storey's map, latched (a late joiner
gets the new floor), and the switch is logged and counted in the status (:meth:`RosMapPublisher.status`).

**What goes out.** After a topic's first map, a change goes out as its update only; the topic's map
goes out in full on a storey switch, on the twin's keyframes (:mod:`twin.live.publication`) and, for a
topic with a ``full_every_s`` policy (``[robots.NAME] full_every_s = { map = 10 }``, for subscribers
that do not apply updates: AMCL, a static layer with ``subscribe_to_updates: false``; a mask topic
defaults to 1 s, as nav2's costmap filters read only full masks), at most every that many seconds
while its map changes (after the update; never for a change that leaves the topic's map unchanged).
A late joiner (rmw_zenoh's ``TRANSIENT_LOCAL`` history query, the bridge's route) is answered with
the current map by :class:`~adapters.zenoh.latched.LatchedPublisher`.

**One holder, one lane per robot.** Every full map sent (switch, keyframe, policy, history reply) is
read from :class:`~adapters.zenoh.latest.LatestMaps`, the daemon's one holder of each map's latest
version (updates applied), encoded once per version: this publisher keeps no copy of its own. Each
robot's sends are made on that robot's own lane (an :class:`~adapters.zenoh.outbox.Outbox`): reliable,
congestion BLOCK, one priority for a map and its updates, so a robot on a slow link holds only its own
lane; the order on a lane is the order of the twin's changes, history replies included.
"""

from __future__ import annotations

import functools
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import zenoh

from adapters.ros import encode_update_cells
from adapters.ros.cdr import (
    COSTMAP_FILTER_INFO,
    KEEPOUT_FILTER,
    OCCUPANCY_GRID,
    OCCUPANCY_GRID_UPDATE,
    SPEED_FILTER_PERCENT,
    STRING,
    decode_string,
    encode_costmap_filter_info,
)
from adapters.ros.rmw_zenoh import (
    DEFAULT_QOS,
    LATCHED_QOS,
    STATE_QOS,
    RosNode,
    RosTopic,
    attachment,
    gid_of,
)
from adapters.ros.settings import RosRobot, RosSettings, ros_robots
from adapters.zenoh.errors import StoreySwitchError
from adapters.zenoh.keys import SiteKeys
from adapters.zenoh.latched import (
    BLOCK,
    CDR,
    MAP_PRIORITY,
    Answer,
    LatchedPublisher,
    declare_latched_publisher,
    declare_latched_subscriber,
)
from adapters.zenoh.latest import LatestMaps
from adapters.zenoh.outbox import Outbox
from twin.config import Config
from twin.errors import TwinError
from twin.live.events import (
    MapPublished,
    MapUpdated,
    RobotStoreyChanged,
    TwinEvent,
    TwinStarted,
)
from twin.live.requests import Reply

if TYPE_CHECKING:
    from adapters.zenoh.daemon import ZenohDaemon

log = logging.getLogger(__name__)

NODE_NAME = "twin_map_server"
STOREY_TOPIC = "storey"
RMW_HEARTBEAT_S = 0.5
"""The sporadic heartbeat of rmw_zenoh's latched (TRANSIENT_LOCAL) publishers, seconds."""
MASK_FULL_EVERY_S = 1.0
"""The ``full_every_s`` of a mask topic (keepout, speed) unless configured: nav2's costmap filters read
only full masks, never ``_updates``, and a zone must reach them within a second, not a keyframe later."""
TEXT = zenoh.Encoding.TEXT_PLAIN
Source = str  # "zenoh" or "ros"


@dataclass(eq=False, slots=True)
class _Out:
    """One publisher: its Zenoh entity (a LatchedPublisher for a map), and for rmw_zenoh its gid and
    sequence counter."""

    publisher: Any
    gid: bytes | None = None
    sequence: int = 0

    def put(self, payload: bytes, stamp_ns: int, timestamp: Any = None) -> None:
        """Publish ``payload``; ``timestamp``: the Zenoh timestamp of a full map's version."""
        extra = {} if timestamp is None else {"timestamp": timestamp}
        if self.gid is None:
            self.publisher.put(payload, **extra)
            return
        self.sequence += 1
        self.publisher.put(payload, attachment=attachment(self.sequence, stamp_ns, self.gid), **extra)

    def reply_attachment(self, stamp_ns: int) -> bytes | None:
        """A history reply's attachment: the sequence number of the last map put (rmw_zenoh counts a
        jump as lost messages), the version's stamp and the gid."""
        return None if self.gid is None else attachment(max(self.sequence, 1), stamp_ns, self.gid)


@dataclass(eq=False, slots=True)
class _Topic:
    """``/<ns>/<name>`` (the map of ``skill``) and ``/<ns>/<name>_updates``, in every layout."""

    name: str
    skill: str
    full_every_s: float | None = None
    """The topic's policy for subscribers that do not apply updates (None: keyframes only)."""
    maps: list[_Out] = field(default_factory=list)
    updates: list[_Out] = field(default_factory=list)
    info: list[_Out] = field(default_factory=list)
    """``/<ns>/<name>_info`` (CostmapFilterInfo) when the skill is a mask."""
    shown: Any = None
    """The Zenoh timestamp of the last storey switch: a history reply is never older than it."""
    last_full: float = float("-inf")
    """When the topic's map last went out in full (monotonic s)."""
    owed: bool = False
    """A change went out as an update since then, and the policy owes a full map."""
    fulls: int = 0


@dataclass(eq=False, slots=True)
class _Robot:
    config: RosRobot
    storey: str | None
    lane: Outbox | None = None
    topics: list[_Topic] = field(default_factory=list)
    entities: list[Any] = field(default_factory=list)
    """Liveliness tokens and subscribers, undeclared on close."""
    switches: int = 0
    switched_ns: int | None = None
    refused: str | None = None
    timers: set[threading.Timer] = field(default_factory=set)


class RosMapPublisher:
    """Publishes configured robots' maps in the ROS 2 layouts and follows their storeys.

    Made by :meth:`following` (the daemon's composition: ``serve`` and the tests use it), which reads
    every full map from the daemon's holder (``maps``), asks the daemon's writer for every storey switch
    (``request``) and adds the publisher to ``daemon.followers``: its :meth:`emit` is then called on
    the daemon's dispatcher, after the holder is up to date, never on the writer's thread. Its sends
    are made on one lane per robot. ``keys`` enables ``robots/<name>/storey`` (every configured robot).
    """

    @classmethod
    def following(cls, daemon: ZenohDaemon, config: Config) -> RosMapPublisher:
        """The daemon's ROS 2 map topics: the daemon's session, holder, keys and writer; a follower of
        its dispatcher and a section (``robots``) of its status."""
        ros = cls(
            daemon.session,
            config,
            maps=daemon.maps,
            request=daemon.service.submit_storey,
            keys=daemon.keys,
            clock=daemon.service.clock,
        )
        daemon.status_sources.append(ros.status)
        daemon.followers.append(ros)
        return ros

    def __init__(
        self,
        session: zenoh.Session,
        config: Config,
        *,
        maps: LatestMaps,
        request: StoreyRequester,
        keys: SiteKeys | None = None,
        clock: Callable[[], int] | None = None,
    ) -> None:
        self.session = session
        self.request = request
        """The writer's storey requests (``TwinService.submit_storey``): every switch is decided by the
        twin's writer, and this publisher republishes a robot's topics when the writer's
        :class:`RobotStoreyChanged` reaches it (:meth:`emit`)."""
        self.maps = maps
        """The daemon's holder of each map's latest version (written by the dispatcher, read here)."""
        self.frame_id = config.section(RosSettings).frame_id
        self.keys = keys
        self.clock = clock or time.time_ns
        self._lock = threading.RLock()
        self._storeys: tuple[str, ...] | None = None
        self._robots: dict[str, _Robot] = {}
        self._declared: list[Any] = []
        self._kinds = {name: skill.kind for name, skill in config.skills.items()}
        zid = str(session.zid())
        entity = 0
        for robot in sorted(ros_robots(config).values(), key=lambda r: r.name):
            r = _Robot(robot, robot.storey)
            self._robots[robot.name] = r
            if robot.namespace is None:
                continue
            r.lane = lane = Outbox(f"twin-ros-{robot.name}")
            policy = dict(robot.full_every_s)
            node = RosNode(robot.domain_id, robot.namespace, NODE_NAME, zid, entity)
            entity += 1
            rmw = "rmw_zenoh" in robot.ros
            if rmw:
                r.entities.append(session.liveliness().declare_token(node.node_token()))
            for name, skill in robot.maps:
                mask = config.skills.get(skill)
                every = policy.get(name, MASK_FULL_EVERY_S if mask is not None and mask.is_mask else None)
                t = _Topic(name, skill, every)
                map_topic = RosTopic(robot.domain_id, robot.namespace, name, OCCUPANCY_GRID)
                upd_topic = RosTopic(
                    robot.domain_id, robot.namespace, f"{name}_updates", OCCUPANCY_GRID_UPDATE
                )
                if "bridge" in robot.ros:
                    t.maps.append(self._map_out(r, t, map_topic.bridge_key, lane, gid=None))
                    t.updates.append(_Out(_updates_publisher(session, upd_topic.bridge_key)))
                if rmw:
                    token = node.publisher_token(map_topic, entity, LATCHED_QOS)
                    t.maps.append(self._map_out(r, t, map_topic.data_key, lane, gid=gid_of(token)))
                    r.entities.append(session.liveliness().declare_token(token))
                    token = node.publisher_token(upd_topic, entity + 1, DEFAULT_QOS)
                    t.updates.append(_Out(_updates_publisher(session, upd_topic.data_key), gid=gid_of(token)))
                    r.entities.append(session.liveliness().declare_token(token))
                    entity += 2
                if mask is not None and mask.is_mask:
                    self._declare_info(t, robot, node, mask=map_topic, entity=entity, tokens=r.entities)
                    entity += 1
                r.topics.append(t)
            storey_topic = RosTopic(robot.domain_id, robot.namespace, STOREY_TOPIC, STRING)
            on_storey = self._ros_storey_handler(robot.name)
            for layout, key in (("bridge", storey_topic.bridge_key), ("rmw_zenoh", storey_topic.data_key)):
                if layout in robot.ros:
                    r.entities.append(declare_latched_subscriber(session, key, on_storey, max_samples=None))
            if rmw:
                token = node.subscriber_token(storey_topic, entity, STATE_QOS)
                entity += 1
                r.entities.append(session.liveliness().declare_token(token))
            topics = ", ".join(f"{robot.namespace}/{t.name} = {t.skill}" for t in r.topics)
            log.info("Serving ROS 2 robot %s on storey %s: %s (%s)", robot.name, robot.storey, topics,
                     ", ".join(robot.ros))  # fmt: skip
        self._skills = {t.skill for r in self._robots.values() for t in r.topics}
        if keys is not None:
            self._declared += [
                session.declare_subscriber(keys.robot_storeys, self._on_storey_put),
                session.declare_queryable(keys.robot_storeys, self._on_storey_get),
            ]

    def _declare_info(
        self, t: _Topic, robot: RosRobot, node: RosNode, *, mask: RosTopic, entity: int, tokens: list[Any]
    ) -> None:
        """Declare ``/<ns>/<name>_info`` and publish its one CostmapFilterInfo (latched)."""
        assert robot.namespace is not None
        topic = RosTopic(robot.domain_id, robot.namespace, f"{t.name}_info", COSTMAP_FILTER_INFO)
        kind = KEEPOUT_FILTER if self._kinds.get(t.skill) == "keepout" else SPEED_FILTER_PERCENT
        if "bridge" in robot.ros:
            t.info.append(_Out(declare_latched_publisher(self.session, topic.bridge_key)))
        if "rmw_zenoh" in robot.ros:
            token = node.publisher_token(topic, entity, LATCHED_QOS)
            info = declare_latched_publisher(self.session, topic.data_key, heartbeat_s=RMW_HEARTBEAT_S)
            t.info.append(_Out(info, gid=gid_of(token)))
            tokens.append(self.session.liveliness().declare_token(token))
        stamp = self.clock()
        payload = encode_costmap_filter_info(kind, mask.fqn, stamp_ns=stamp, frame_id=self.frame_id)
        for out in t.info:
            out.put(payload, stamp)

    def _map_out(self, r: _Robot, t: _Topic, key: str, lane: Outbox, *, gid: bytes | None) -> _Out:
        """A map topic's latched publisher in one layout, late joiners answered on the robot's lane."""
        out = _Out(None, gid=gid)
        heartbeat = RMW_HEARTBEAT_S if gid is not None else None
        out.publisher = LatchedPublisher(
            self.session, key, answer=lambda: self._answer(r, t, out), lane=lane, heartbeat_s=heartbeat
        )
        return out

    def _answer(self, r: _Robot, t: _Topic, out: _Out) -> Answer | None:
        """A late joiner's map of topic ``t``: the current map of the robot's storey (on its lane)."""
        storey = r.storey
        now = None if storey is None else self.maps.current((storey, t.skill))
        if now is None:
            return None
        return now.payload, out.reply_attachment(now.stamp_ns), _newer(now.timestamp, t.shown)

    # --- the sink (the daemon's dispatcher, after the holder) ---------------------------------------
    def emit(self, event: TwinEvent) -> None:
        try:
            with self._lock:
                if isinstance(event, TwinStarted):
                    self._started(event)
                elif isinstance(event, MapPublished):
                    self._publish(event.grid.storey, event.grid.skill)
                elif isinstance(event, MapUpdated):
                    self._update(event)
                elif isinstance(event, RobotStoreyChanged):
                    self._apply(event.robot, event.storey)  # the writer decided: republish
        except Exception:  # a ROS layout must never stop the twin
            log.exception("Publishing %s to ROS 2 robots failed", type(event).__name__)

    def drain(self) -> None:
        """Wait until every robot's lane made the sends queued so far."""
        for r in list(self._robots.values()):
            if r.lane is not None:
                r.lane.drain()

    def _started(self, event: TwinStarted) -> None:
        self._storeys = tuple(key for key, _, _ in event.storeys)
        for r in self._robots.values():
            if r.storey is not None and r.storey not in self._storeys:
                log.error(
                    "Robot %s is configured on storey %r, which the twin does not have (storeys: %s): "
                    "it gets no map until it switches to one",
                    r.config.name, r.storey, ", ".join(self._storeys),
                )  # fmt: skip

    def _on(self, storey: str, skill: str) -> list[tuple[_Robot, _Topic]]:
        return [
            (r, t) for r in self._robots.values() if r.storey == storey for t in r.topics if t.skill == skill
        ]

    def _publish(self, storey: str, skill: str) -> None:
        """A full version of (storey, skill) went out (first map, keyframe, skill change): every topic
        that shows it sends it in full."""
        if skill in self._skills:
            for r, t in self._on(storey, skill):
                self._send_full(r, t)

    def _send_full(self, r: _Robot, t: _Topic) -> None:
        """Queue topic ``t``'s current map on the robot's lane (read when the lane sends it). Locked."""
        t.owed, t.last_full = False, time.monotonic()
        assert r.lane is not None
        r.lane.put(lambda: self._put_full(r, t))

    def _put_full(self, r: _Robot, t: _Topic) -> None:
        """On the robot's lane: the topic's map as the holder has it now (its storey's, updates applied)."""
        storey = r.storey
        now = None if storey is None else self.maps.current((storey, t.skill))
        if now is None:
            return
        t.fulls += 1
        timestamp = _newer(now.timestamp, t.shown)
        for out in t.maps:
            out.put(now.payload, now.stamp_ns, timestamp)

    def _update(self, event: MapUpdated) -> None:
        targets = self._on(event.storey, event.skill)
        if not targets:
            return
        payload = encode_update_cells(
            event.frame, event.window, event.data, stamp_ns=event.stamp_ns, frame_id=self.frame_id
        )
        for r, t in targets:
            assert r.lane is not None
            r.lane.put(functools.partial(_put_all, t.updates, payload, event.stamp_ns))
            if t.full_every_s is not None:
                self._owe(r, t)

    def _owe(self, r: _Robot, t: _Topic) -> None:
        """The policy ``full_every_s``: a full map after this update, at most every N s. Locked."""
        if t.owed or t.full_every_s is None:
            return
        t.owed = True
        delay = t.last_full + t.full_every_s - time.monotonic()
        if delay <= 0:
            self._send_full(r, t)
            return
        timer = threading.Timer(delay, self._owed_due, args=(r, t))
        timer.daemon = True
        r.timers = {other for other in r.timers if other.is_alive()}  # kept until ended: close joins them
        r.timers.add(timer)
        timer.start()

    def _owed_due(self, r: _Robot, t: _Topic) -> None:
        with self._lock:
            if t.owed and r.config.name in self._robots:
                self._send_full(r, t)

    # --- storey switching (any thread) --------------------------------------------------------------
    def storey_of(self, robot: str) -> str | None:
        """The storey ``robot`` is on (None: not known yet); StoreySwitchError for an unknown robot."""
        with self._lock:
            return self._robot(robot).storey

    def _robot(self, name: str) -> _Robot:
        r = self._robots.get(name)
        if r is None:
            known = ", ".join(sorted(self._robots)) or "none"
            msg = f"Unknown robot {name!r}: configured robots ([robots.NAME]) are {known}."
            raise StoreySwitchError(msg)
        return r

    def ask(self, robot: str, storey: str, *, source: Source, reply: Callable[[Reply], None]) -> None:
        """Ask the writer for ``robot`` on ``storey`` (the one way a storey switch happens); ``reply``
        gets its answer on the writer's thread, and a refusal is kept for the status."""

        def answered(answer: Reply) -> None:
            if not answer.ok:
                with self._lock:
                    known = self._robots.get(robot)
                    if known is not None:
                        known.refused = str(answer.body.get("error", ""))
            reply(answer)

        self.request(robot, storey, source=source, reply=answered)

    def _apply(self, robot: str, storey: str) -> None:
        """The writer put ``robot`` on ``storey``: republish every topic of the robot with that storey's
        maps (nothing when it is there already)."""
        with self._lock:
            r = self._robots.get(robot)
            if r is None or r.storey == storey:
                return
            previous, r.storey = r.storey, storey
            stamp = self.clock()
            r.switches += 1
            r.switched_ns = stamp
            shown = self.session.new_timestamp()
            for t in r.topics:
                t.shown = shown
                if (storey, t.skill) not in self.maps:
                    log.warning("No %s map of storey %s yet for %s/%s", t.skill, storey, robot, t.name)
                    continue
                self._send_full(r, t)
        log.info("Robot %s is now on storey %s (was %s): %d topic(s) republished",
                 robot, storey, previous, len(r.topics))  # fmt: skip

    def _ros_storey_handler(self, robot: str) -> Callable[[zenoh.Sample], None]:
        def on_sample(sample: zenoh.Sample) -> None:
            try:
                storey = decode_string(sample.payload.to_bytes()).strip()
            except TwinError as err:
                log.warning("Refused a storey on %s: %s", sample.key_expr, err)
                return
            self.ask(robot, storey, source="ros", reply=_warn_refusal(str(sample.key_expr)))

        return on_sample

    def _on_storey_put(self, sample: zenoh.Sample) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            return
        robot = str(sample.key_expr).split("/")[-2]
        try:
            storey = _storey_text(sample.payload.to_bytes())
        except TwinError as err:  # a put has no reply: a warning, never a traceback
            log.warning("Refused a storey put on %s: %s", sample.key_expr, err)
            return
        self.ask(robot, storey, source="zenoh", reply=_warn_refusal(str(sample.key_expr)))

    def _on_storey_get(self, query: zenoh.Query) -> None:
        assert self.keys is not None
        key = str(query.key_expr)
        try:
            wanted = _storey_text(query.payload.to_bytes()) if query.payload is not None else ""
        except TwinError as err:
            query.reply_err(str(err).encode(), encoding=TEXT)
            return
        if "*" in key:  # a listing: every configured robot the selector matches
            if wanted:
                query.reply_err(f"Name one robot to switch its storey, not {key}.".encode(), encoding=TEXT)
                return
            with self._lock:
                names = [n for n in self._robots if zenoh.KeyExpr(self.keys.robot_storey(n)).intersects(key)]
        else:
            names = [key.split("/")[-2]]
        if wanted and len(names) == 1:
            name = names[0]
            keys = self.keys

            def answer(reply: Reply) -> None:  # on the writer's thread once it decided
                try:
                    if reply.ok:
                        query.reply(keys.robot_storey(name), wanted.encode(), encoding=TEXT)
                    else:
                        query.reply_err(str(reply.body.get("error", "refused")).encode(), encoding=TEXT)
                except Exception:  # the asker may have gone
                    log.debug("Could not answer a storey switch of %s", name, exc_info=True)

            self.ask(name, wanted, source="zenoh", reply=answer)
            return
        for name in names:
            try:
                storey = self.storey_of(name)
            except TwinError as err:
                query.reply_err(str(err).encode(), encoding=TEXT)
                continue
            if storey is None:
                query.reply_err(f"Robot {name!r} has not reported a storey yet.".encode(), encoding=TEXT)
            else:
                query.reply(self.keys.robot_storey(name), storey.encode(), encoding=TEXT)

    # --- status and lifecycle ----------------------------------------------------------------------
    def status(self) -> dict[str, object]:
        """``{"robots": {name: {storey, topics, switches, switched_ns, refused}}}``, for the status."""
        with self._lock:
            robots: dict[str, object] = {}
            for name, r in sorted(self._robots.items()):
                robots[name] = {
                    "storey": r.storey,
                    "namespace": r.config.namespace,
                    "topics": {f"{r.config.namespace}/{t.name}": t.skill for t in r.topics},
                    "switches": r.switches,
                    "switched_ns": r.switched_ns,
                    "refused": r.refused,
                }
        return {"robots": robots}

    def close(self) -> None:
        """Make every robot's queued sends, then undeclare everything."""
        with self._lock:
            robots = list(self._robots.values())
            self._robots.clear()
            entities = [*self._declared]
            self._declared.clear()
            timers = [timer for r in robots for timer in r.timers]
            for timer in timers:
                timer.cancel()
        for timer in timers:  # one that was already sending: it finds its robot gone, or ends its send
            timer.join(5.0)
        for r in robots:
            if r.lane is not None:
                r.lane.close()
            outs = [o.publisher for t in r.topics for o in (*t.maps, *t.updates, *t.info)]
            entities += [*outs, *r.entities]
        for entity in entities:
            try:
                entity.undeclare()
            except Exception:
                log.debug("undeclare failed", exc_info=True)


def _updates_publisher(session: zenoh.Session, key: str) -> zenoh.Publisher:
    """A topic's ``_updates``: reliable, BLOCK (a lost update is not healed before the next keyframe;
    the block holds only the robot's lane), the priority of its map (never overtakes it)."""
    return session.declare_publisher(
        key,
        encoding=CDR,
        reliability=zenoh.Reliability.RELIABLE,
        congestion_control=BLOCK,
        priority=MAP_PRIORITY,
    )


def _newer(version: Any, shown: Any) -> Any:
    """The timestamp a topic's full map carries: its version's, or the storey switch that made it the
    topic's map if that is later (a late joiner keeps one sample per timestamp, the newest)."""
    if shown is not None and (version is None or shown > version):
        return shown
    return version


def _put_all(outs: list[_Out], payload: bytes, stamp_ns: int) -> None:
    for out in outs:
        out.put(payload, stamp_ns)


def _storey_text(payload: bytes) -> str:
    """The storey key a put or get on ``robots/<name>/storey`` carries (UTF-8 text, trimmed);
    StoreySwitchError naming the bytes when they are not UTF-8 (zenoh's ``to_string`` would raise a
    ValueError)."""
    try:
        return payload.decode("utf-8").strip()
    except UnicodeDecodeError as err:
        shown = payload[:32]
        msg = (
            f"A storey key is UTF-8 text; got {len(payload)} bytes that are not "
            f"({err.reason} at byte {err.start}): {shown!r}{'...' if len(payload) > 32 else ''}."
        )
        raise StoreySwitchError(msg) from None


__all__ = ["NODE_NAME", "STOREY_TOPIC", "RosMapPublisher"]


StoreyRequester = Callable[..., None]
"""``TwinService.submit_storey(robot, storey, *, source, reply)``."""


def _warn_refusal(where: str) -> Callable[[Reply], None]:
    def warn(reply: Reply) -> None:
        if not reply.ok:
            log.warning("Refused a storey on %s: %s", where, reply.body.get("error"))

    return warn
