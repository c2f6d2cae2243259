"""Serve skill maps to ROS 2 robots as map_servers in their namespace would, and follow the storey each
robot is on (a TwinSink).

For every configured robot with a namespace (``[robots.NAME]``), each of its topics
(``[robots.NAME.maps]``, topic = skill; default ``map`` = localization for AMCL, ``navigation_map`` =
navigation for the costmap's static layer) carries that skill's map of the robot's current storey as
``/<ns>/<topic>`` (``nav_msgs/OccupancyGrid``, latched) and its changes as ``/<ns>/<topic>_updates``
(``map_msgs/OccupancyGridUpdate``), in the layouts the robot asks for:

- ``bridge``: keys ``<ns>/<topic>`` and ``<ns>/<topic>_updates`` as zenoh-bridge-ros2dds routes them to
  DDS; the map from an AdvancedPublisher with a cache and publisher detection (the bridge's route is an
  AdvancedSubscriber with history);
- ``rmw_zenoh``: rmw_zenoh_cpp's data keys with domain, DDS type name and RIHS01 hash, every sample
  with the 33-byte rmw attachment (sequence number per publisher from 1, source time, gid); the map
  from an AdvancedPublisher with a cache of 1, publisher detection and a 500 ms sporadic heartbeat;
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
with a subscriber liveliness token on rmw_zenoh). On a switch every topic of the robot republishes the
new storey's map, latched (a late joiner gets the new floor), the switch is logged, counted in the
status (:meth:`RosMapPublisher.status`) and emitted as :class:`~twin.events.RobotStoreyChanged` to the
other sinks (the Rerun recording). An unknown robot or storey is refused with an error naming it and
changes nothing; the same storey again is a no-op (robots re-report it often).

The publisher keeps its own copy of the latest version of every map a robot may need (updates
applied), so a switch publishes exactly what the twin holds, even between a change's update and the
next full map. A map shared by several robots is encoded once per version.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import zenoh

from adapters.ros import encode_occupancy_grid, encode_update_cells
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
from adapters.zenoh.errors import StoreySwitchError
from adapters.zenoh.keys import SiteKeys
from adapters.zenoh.latched import CDR, declare_latched_publisher, declare_latched_subscriber
from twin.config import Config, RobotConfig
from twin.errors import TwinError
from twin.events import MapPublished, MapUpdated, RobotStoreyChanged, TwinEvent, TwinSink, TwinStarted
from twin.grid import OccupancyGrid

log = logging.getLogger(__name__)

NODE_NAME = "twin_map_server"
STOREY_TOPIC = "storey"
RMW_HEARTBEAT_S = 0.5
"""The sporadic heartbeat of rmw_zenoh's latched (TRANSIENT_LOCAL) publishers, seconds."""
TEXT = zenoh.Encoding.TEXT_PLAIN
Source = str  # "zenoh" or "ros"


@dataclass(eq=False, slots=True)
class _Out:
    """One publisher: its Zenoh entity, and for rmw_zenoh its gid and sequence counter."""

    publisher: Any
    gid: bytes | None = None
    sequence: int = 0

    def put(self, payload: bytes, stamp_ns: int) -> None:
        if self.gid is None:
            self.publisher.put(payload)
            return
        self.sequence += 1
        self.publisher.put(payload, attachment=attachment(self.sequence, stamp_ns, self.gid))


@dataclass(eq=False, slots=True)
class _Topic:
    """``/<ns>/<name>`` (the map of ``skill``) and ``/<ns>/<name>_updates``, in every layout."""

    name: str
    skill: str
    maps: list[_Out] = field(default_factory=list)
    updates: list[_Out] = field(default_factory=list)
    info: list[_Out] = field(default_factory=list)
    """``/<ns>/<name>_info`` (CostmapFilterInfo) when the skill is a mask."""


@dataclass(eq=False, slots=True)
class _Robot:
    config: RobotConfig
    storey: str | None
    topics: list[_Topic] = field(default_factory=list)
    entities: list[Any] = field(default_factory=list)
    """Liveliness tokens and subscribers, undeclared on close."""
    switches: int = 0
    switched_ns: int | None = None
    refused: str | None = None


@dataclass(eq=False, slots=True)
class _Latest:
    """The latest version of a map (updates applied in place) and the CDR of its last full version."""

    grid: OccupancyGrid
    stamp_ns: int
    payload: bytes | None


def _latched(session: zenoh.Session, key: str, *, rmw: bool) -> Any:
    """The latched publisher of a map (or filter info) topic; rmw_zenoh's with its heartbeat."""
    return declare_latched_publisher(session, key, heartbeat_s=RMW_HEARTBEAT_S if rmw else None)


class RosMapPublisher:
    """Publishes configured robots' maps in the ROS 2 layouts and follows their storeys.

    Create once the session is open and add it to the service's sinks before the service starts.
    ``keys`` enables ``robots/<name>/storey`` (every configured robot); ``sinks`` receive the
    :class:`RobotStoreyChanged` events (pass the service's own list: ``service.sinks``); ``revision``
    tells the twin revision at a switch.
    """

    def __init__(
        self,
        session: zenoh.Session,
        config: Config,
        *,
        keys: SiteKeys | None = None,
        sinks: Sequence[TwinSink] = (),
        revision: Callable[[], int] = lambda: 0,
        clock: Callable[[], int] | None = None,
    ) -> None:
        self.session = session
        self.frame_id = config.frame_id
        self.keys = keys
        self.sinks = sinks
        self.revision = revision
        self.clock = clock or time.time_ns
        self._lock = threading.RLock()
        self._storeys: tuple[str, ...] | None = None
        self._latest: dict[tuple[str, str], _Latest] = {}
        self._robots: dict[str, _Robot] = {}
        self._declared: list[Any] = []
        self._kinds = {name: skill.kind for name, skill in config.skills.items()}
        zid = str(session.zid())
        entity = 0
        for robot in sorted(config.robots.values(), key=lambda r: r.name):
            r = _Robot(robot, robot.storey)
            self._robots[robot.name] = r
            if robot.namespace is None:
                continue
            node = RosNode(robot.domain_id, robot.namespace, NODE_NAME, zid, entity)
            entity += 1
            rmw = "rmw_zenoh" in robot.ros
            if rmw:
                r.entities.append(session.liveliness().declare_token(node.node_token()))
            for name, skill in robot.maps:
                t = _Topic(name, skill)
                map_topic = RosTopic(robot.domain_id, robot.namespace, name, OCCUPANCY_GRID)
                upd_topic = RosTopic(
                    robot.domain_id, robot.namespace, f"{name}_updates", OCCUPANCY_GRID_UPDATE
                )
                if "bridge" in robot.ros:
                    t.maps.append(_Out(_latched(session, map_topic.bridge_key, rmw=False)))
                    t.updates.append(_Out(session.declare_publisher(upd_topic.bridge_key, encoding=CDR)))
                if rmw:
                    for topic, qos, outs, latched in (
                        (map_topic, LATCHED_QOS, t.maps, True),
                        (upd_topic, DEFAULT_QOS, t.updates, False),
                    ):
                        token = node.publisher_token(topic, entity, qos)
                        entity += 1
                        pub = (
                            _latched(session, topic.data_key, rmw=True)
                            if latched
                            else session.declare_publisher(
                                topic.data_key, encoding=CDR, reliability=zenoh.Reliability.RELIABLE
                            )
                        )
                        outs.append(_Out(pub, gid=gid_of(token)))
                        r.entities.append(session.liveliness().declare_token(token))
                mask = config.skills.get(skill)
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
        self, t: _Topic, robot: RobotConfig, node: RosNode, *, mask: RosTopic, entity: int, tokens: list[Any]
    ) -> None:
        """Declare ``/<ns>/<name>_info`` and publish its one CostmapFilterInfo (latched)."""
        assert robot.namespace is not None
        topic = RosTopic(robot.domain_id, robot.namespace, f"{t.name}_info", COSTMAP_FILTER_INFO)
        kind = KEEPOUT_FILTER if self._kinds.get(t.skill) == "keepout" else SPEED_FILTER_PERCENT
        if "bridge" in robot.ros:
            t.info.append(_Out(_latched(self.session, topic.bridge_key, rmw=False)))
        if "rmw_zenoh" in robot.ros:
            token = node.publisher_token(topic, entity, LATCHED_QOS)
            t.info.append(_Out(_latched(self.session, topic.data_key, rmw=True), gid=gid_of(token)))
            tokens.append(self.session.liveliness().declare_token(token))
        stamp = self.clock()
        payload = encode_costmap_filter_info(kind, mask.fqn, stamp_ns=stamp, frame_id=self.frame_id)
        for out in t.info:
            out.put(payload, stamp)

    # --- the sink (service thread) ------------------------------------------------------------------
    def emit(self, event: TwinEvent) -> None:
        try:
            with self._lock:
                if isinstance(event, TwinStarted):
                    self._started(event)
                elif isinstance(event, MapPublished):
                    self._publish(event)
                elif isinstance(event, MapUpdated):
                    self._update(event)
        except Exception:  # a ROS layout must never stop the twin
            log.exception("Publishing %s to ROS 2 robots failed", type(event).__name__)

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

    def _publish(self, event: MapPublished) -> None:
        grid = event.grid
        if grid.skill not in self._skills:
            return
        own = OccupancyGrid(grid.frame, grid.data.copy(), grid.storey, grid.skill, grid.elevation_m)
        latest = _Latest(own, event.stamp_ns, None)
        self._latest[(grid.storey, grid.skill)] = latest
        targets = self._on(grid.storey, grid.skill)
        if targets:
            latest.payload = encode_occupancy_grid(grid, stamp_ns=event.stamp_ns, frame_id=self.frame_id)
            for _, t in targets:
                for out in t.maps:
                    out.put(latest.payload, event.stamp_ns)

    def _update(self, event: MapUpdated) -> None:
        latest = self._latest.get((event.storey, event.skill))
        if latest is None:
            return
        w = event.window
        latest.grid.data[w.row0 : w.row1, w.col0 : w.col1] = event.data
        latest.stamp_ns, latest.payload = event.stamp_ns, None
        targets = self._on(event.storey, event.skill)
        if not targets:
            return
        payload = encode_update_cells(
            event.frame, event.window, event.data, stamp_ns=event.stamp_ns, frame_id=self.frame_id
        )
        for _, t in targets:
            for out in t.updates:
                out.put(payload, event.stamp_ns)

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

    def switch(self, robot: str, storey: str, *, source: Source = "zenoh") -> RobotStoreyChanged | None:
        """Put ``robot`` on ``storey``: every topic of the robot republishes that storey's maps, latched.

        Returns the event (also emitted to the sinks), or None when the robot was already there.
        Raises StoreySwitchError, changing nothing, for an unknown robot or storey.
        """
        with self._lock:
            r = self._robot(robot)
            try:
                if self._storeys is None:
                    msg = f"Cannot put robot {robot!r} on storey {storey!r}: the twin has not started yet."
                    raise StoreySwitchError(msg)
                if storey not in self._storeys:
                    msg = (
                        f"Unknown storey {storey!r} for robot {robot!r}: the twin's storeys are "
                        f"{', '.join(self._storeys) or 'none'}."
                    )
                    raise StoreySwitchError(msg)
            except StoreySwitchError as err:
                r.refused = str(err)
                raise
            if r.storey == storey:
                return None
            previous, r.storey = r.storey, storey
            stamp = self.clock()
            r.switches += 1
            r.switched_ns = stamp
            for t in r.topics:
                latest = self._latest.get((storey, t.skill))
                if latest is None:
                    log.warning("No %s map of storey %s yet for %s/%s", t.skill, storey, robot, t.name)
                    continue
                if latest.payload is None:
                    latest.payload = encode_occupancy_grid(
                        latest.grid, stamp_ns=latest.stamp_ns, frame_id=self.frame_id
                    )
                for out in t.maps:
                    out.put(latest.payload, stamp)
            event = RobotStoreyChanged(robot, storey, previous, source, self.revision(), stamp)
        log.info("Robot %s is now on storey %s (was %s), via %s: %d topic(s) republished",
                 robot, storey, previous, source, len(r.topics))  # fmt: skip
        for sink in list(self.sinks):
            if sink is self:
                continue
            try:
                sink.emit(event)
            except Exception:  # a sink must never stop the switch
                log.exception("Sink %s failed on %s", type(sink).__name__, type(event).__name__)
        return event

    def _ros_storey_handler(self, robot: str) -> Callable[[zenoh.Sample], None]:
        def on_sample(sample: zenoh.Sample) -> None:
            try:
                storey = decode_string(sample.payload.to_bytes()).strip()
                self.switch(robot, storey, source="ros")
            except TwinError as err:
                log.warning("Refused a storey on %s: %s", sample.key_expr, err)

        return on_sample

    def _on_storey_put(self, sample: zenoh.Sample) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            return
        robot = str(sample.key_expr).split("/")[-2]
        try:
            self.switch(robot, _storey_text(sample.payload.to_bytes()), source="zenoh")
        except TwinError as err:  # a put has no reply: a warning, never a traceback
            log.warning("Refused a storey put on %s: %s", sample.key_expr, err)

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
        for name in names:
            try:
                if wanted:
                    self.switch(name, wanted, source="zenoh")
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
        with self._lock:
            robots = list(self._robots.values())
            self._robots.clear()
            entities = [*self._declared]
            self._declared.clear()
        for r in robots:
            outs = [o.publisher for t in r.topics for o in (*t.maps, *t.updates, *t.info)]
            entities += [*outs, *r.entities]
        for entity in entities:
            try:
                entity.undeclare()
            except Exception:
                log.debug("undeclare failed", exc_info=True)
        self._latest.clear()


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
