"""Points maps on ROS 2 robots' topics: ``/<ns>/points_map``, the cloud of the robot's current storey.

For every configured robot with a namespace, each ``points`` skill's cloud of the storey the robot is
on goes out as ``sensor_msgs/msg/PointCloud2`` (latched, as map_server's map) on ``/<ns>/points_map``
(one points skill) or ``/<ns>/points_map_<skill>`` (several; ``-`` becomes ``_``), in the robot's
layouts, as :mod:`adapters.zenoh.ros_maps` serves the 2D maps: ``bridge`` (key ``<ns>/points_map``) and
``rmw_zenoh`` (rmw_zenoh_cpp's data key with type hash, the 33-byte attachment on every sample, a
500 ms sporadic heartbeat, liveliness tokens of node ``<ns>/twin_points_server`` and of its
publishers), each from a :class:`~adapters.zenoh.latched.LatchedPublisher`: a late joiner is answered
with the current cloud of the robot's current storey (nothing for a removed skill). When the robot
switches storey (a :class:`~twin.live.events.RobotStoreyChanged`), the new storey's cloud is published.
PointCloud2 has no update message: the twin publishes a changed cloud whole, at most once a second.

The clouds are read from :class:`~adapters.zenoh.latest.LatestMaps`, encoded once per version (the
daemon's one holder, ``daemon.maps``, brought up to date before this follower is called); each
robot's sends and history replies are made on that robot's own lane.

Example::

    ros_points = RosPointsPublisher(session, config, maps=daemon.maps)
    daemon.followers.append(ros_points)    # on the daemon's dispatcher, off the writer's thread
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import zenoh

from adapters.ros.pcd import POINT_CLOUD2
from adapters.ros.rmw_zenoh import LATCHED_QOS, RosNode, RosTopic, attachment, gid_of
from adapters.ros.settings import RosSettings, ros_robots
from adapters.zenoh.latched import Answer, LatchedPublisher
from adapters.zenoh.latest import LatestMaps
from adapters.zenoh.outbox import Outbox
from twin.config import Config
from twin.live.events import PointsPublished, RobotStoreyChanged, TwinEvent

__all__ = ["NODE_NAME", "RosPointsPublisher", "points_topic"]

log = logging.getLogger(__name__)

NODE_NAME = "twin_points_server"
_ENTITY_BASE = 1 << 20
"""Entity ids of this node and its publishers: apart from the map server's (same session)."""
_RMW_HEARTBEAT_S = 0.5


def points_topic(skill: str, *, several: bool) -> str:
    """The topic name of a points skill under a robot's namespace."""
    return f"points_map_{skill.replace('-', '_')}" if several else "points_map"


@dataclass(eq=False, slots=True)
class _Pub:
    """One layout's publisher of a topic, and for rmw_zenoh its gid and sequence counter."""

    publisher: Any = None
    gid: bytes | None = None
    sequence: int = 0

    def put(self, payload: bytes, stamp_ns: int, timestamp: Any) -> None:
        if self.gid is None:
            self.publisher.put(payload, timestamp=timestamp)
            return
        self.sequence += 1
        self.publisher.put(
            payload, attachment=attachment(self.sequence, stamp_ns, self.gid), timestamp=timestamp
        )

    def reply_attachment(self, stamp_ns: int) -> bytes | None:
        """A history reply's attachment (rmw_zenoh): the last sequence number put, the stamp, the gid."""
        return None if self.gid is None else attachment(max(self.sequence, 1), stamp_ns, self.gid)


@dataclass(eq=False, slots=True)
class _Robot:
    storey: str | None
    lane: Outbox
    topics: dict[str, list[_Pub]] = field(default_factory=dict)
    """Per points skill, its publishers (one per layout)."""
    entities: list[Any] = field(default_factory=list)
    shown: Any = None
    """The Zenoh timestamp of the last storey switch: what the robot's topics send is never older."""


def _newer(version: Any, shown: Any) -> Any:
    """A cloud's timestamp on a robot's topic: its version's, or the switch that made it the topic's if
    later (a late joiner keeps one sample per timestamp, the newest)."""
    return shown if shown is not None and (version is None or shown > version) else version


class RosPointsPublisher:
    """Publishes the points skills' clouds to the configured robots. Call :meth:`emit` from one thread."""

    def __init__(self, session: zenoh.Session, config: Config, *, maps: LatestMaps) -> None:
        self.session = session
        self.frame_id = config.section(RosSettings).frame_id
        skills = sorted(name for name, s in config.skills.items() if s.kind == "points")
        self.maps = maps
        """The daemon's one holder of each cloud's latest version (written by the dispatcher first)."""
        self._robots: dict[str, _Robot] = {}
        zid = str(session.zid())
        entity = _ENTITY_BASE
        for robot in sorted(ros_robots(config).values(), key=lambda r: r.name):
            if robot.namespace is None or not skills:
                continue
            r = self._robots[robot.name] = _Robot(robot.storey, Outbox(f"twin-ros-points-{robot.name}"))
            node = RosNode(robot.domain_id, robot.namespace, NODE_NAME, zid, entity)
            entity += 1
            rmw = "rmw_zenoh" in robot.ros
            if rmw:
                r.entities.append(session.liveliness().declare_token(node.node_token()))
            for skill in skills:
                topic = RosTopic(
                    robot.domain_id,
                    robot.namespace,
                    points_topic(skill, several=len(skills) > 1),
                    POINT_CLOUD2,
                )
                pubs = r.topics[skill] = []
                if "bridge" in robot.ros:
                    pubs.append(self._latched(r, skill, topic.bridge_key, gid=None))
                if rmw:
                    token = node.publisher_token(topic, entity, LATCHED_QOS)
                    entity += 1
                    pubs.append(self._latched(r, skill, topic.data_key, gid=gid_of(token)))
                    r.entities.append(session.liveliness().declare_token(token))
            log.info(
                "Serving %s the points maps %s (%s)", robot.namespace, ", ".join(skills), ", ".join(robot.ros)
            )

    def _latched(self, r: _Robot, skill: str, key: str, *, gid: bytes | None) -> _Pub:
        """A topic's publisher in one layout, late joiners answered on the robot's lane."""
        pub = _Pub(gid=gid)
        heartbeat = _RMW_HEARTBEAT_S if gid is not None else None
        pub.publisher = LatchedPublisher(
            self.session, key, answer=lambda: self._answer(r, skill, pub), lane=r.lane, heartbeat_s=heartbeat
        )
        return pub

    def _answer(self, r: _Robot, skill: str, pub: _Pub) -> Answer | None:
        """A late joiner's cloud: the current one of the robot's storey (on its lane)."""
        now = self.maps.cloud((r.storey or "", skill))
        if now is None:
            return None
        return now.payload, pub.reply_attachment(now.stamp_ns), _newer(now.timestamp, r.shown)

    def emit(self, event: TwinEvent) -> None:
        if isinstance(event, PointsPublished):
            cloud = event.cloud
            for r in self._robots.values():
                if r.storey == cloud.storey:
                    self._send(r, cloud.skill)
        elif isinstance(event, RobotStoreyChanged):
            robot = self._robots.get(event.robot)
            if robot is not None and robot.storey != event.storey:
                robot.storey = event.storey
                robot.shown = self.session.new_timestamp()
                for skill in robot.topics:
                    self._send(robot, skill)

    def _send(self, r: _Robot, skill: str) -> None:
        r.lane.put(lambda: self._put(r, skill))

    def _put(self, r: _Robot, skill: str) -> None:
        """On the robot's lane: the topic's cloud as the holder has it now (the robot's storey's)."""
        now = self.maps.cloud((r.storey or "", skill))
        if now is None:
            return
        timestamp = _newer(now.timestamp, r.shown)
        for pub in r.topics.get(skill, []):
            pub.put(now.payload, now.stamp_ns, timestamp)

    def drain(self) -> None:
        """Wait until every robot's lane made the sends queued so far."""
        for r in list(self._robots.values()):
            r.lane.drain()

    def close(self) -> None:
        for r in self._robots.values():
            r.lane.close()
            for pubs in r.topics.values():
                for pub in pubs:
                    pub.publisher.undeclare()
            for e in r.entities:
                e.undeclare()
        self._robots.clear()
