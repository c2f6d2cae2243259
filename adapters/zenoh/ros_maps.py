"""Serve skill maps to ROS 2 robots as a map_server in their namespace would (a TwinSink).

For every configured robot with a namespace (``[robots.NAME]``), the map of its (storey, skill) goes
out as ``/<ns>/map`` (``nav_msgs/OccupancyGrid``, latched) and ``/<ns>/map_updates``
(``map_msgs/OccupancyGridUpdate``) in the layouts it asks for:

- ``bridge``: keys ``<ns>/map`` and ``<ns>/map_updates`` as zenoh-bridge-ros2dds routes them to DDS;
  the map from an AdvancedPublisher with a cache and publisher detection (the bridge's route is an
  AdvancedSubscriber with history);
- ``rmw_zenoh``: rmw_zenoh_cpp's data keys with domain, DDS type name and RIHS01 hash, every sample
  with the 33-byte rmw attachment (sequence number per publisher from 1, source time, gid); the map
  from an AdvancedPublisher with a cache of 1, publisher detection and a 500 ms sporadic heartbeat;
  and liveliness tokens that put the daemon in the ROS graph as node ``<ns>/twin_map_server``.

A map shared by several robots is encoded once per version.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import zenoh
import zenoh.ext

from adapters.ros import encode_occupancy_grid, encode_update_cells
from adapters.ros.cdr import OCCUPANCY_GRID, OCCUPANCY_GRID_UPDATE
from adapters.ros.rmw_zenoh import DEFAULT_QOS, LATCHED_QOS, RosNode, RosTopic, attachment, gid_of
from twin.config import Config, RobotConfig
from twin.events import MapPublished, MapUpdated, TwinEvent

log = logging.getLogger(__name__)

NODE_NAME = "twin_map_server"
CDR = zenoh.Encoding.APPLICATION_CDR


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
class _Robot:
    config: RobotConfig
    maps: list[_Out] = field(default_factory=list)
    updates: list[_Out] = field(default_factory=list)
    tokens: list[Any] = field(default_factory=list)


def _latched(session: zenoh.Session, key: str, *, heartbeat: bool) -> Any:
    return zenoh.ext.declare_advanced_publisher(
        session,
        key,
        encoding=CDR,
        congestion_control=zenoh.CongestionControl.BLOCK,
        reliability=zenoh.Reliability.RELIABLE,
        cache=zenoh.ext.CacheConfig(max_samples=1),
        publisher_detection=True,
        sample_miss_detection=(
            zenoh.ext.MissDetectionConfig(heartbeat=None, sporadic_heartbeat=0.5) if heartbeat else None
        ),
    )


class RosMapPublisher:
    """Publishes configured robots' maps in the ROS 2 layouts. Create once the session is open."""

    def __init__(self, session: zenoh.Session, config: Config) -> None:
        self.session = session
        self.frame_id = config.frame_id
        self.robots: list[_Robot] = []
        zid = str(session.zid())
        entity = 0
        for robot in sorted(config.robots.values(), key=lambda r: r.name):
            if robot.namespace is None:
                continue
            r = _Robot(robot)
            node = RosNode(robot.domain_id, robot.namespace, NODE_NAME, zid, entity)
            entity += 1
            map_topic = RosTopic(robot.domain_id, robot.namespace, "map", OCCUPANCY_GRID)
            upd_topic = RosTopic(robot.domain_id, robot.namespace, "map_updates", OCCUPANCY_GRID_UPDATE)
            if "bridge" in robot.ros:
                r.maps.append(_Out(_latched(session, map_topic.bridge_key, heartbeat=False)))
                r.updates.append(_Out(session.declare_publisher(upd_topic.bridge_key, encoding=CDR)))
            if "rmw_zenoh" in robot.ros:
                r.tokens.append(session.liveliness().declare_token(node.node_token()))
                for topic, qos, outs, latched in (
                    (map_topic, LATCHED_QOS, r.maps, True),
                    (upd_topic, DEFAULT_QOS, r.updates, False),
                ):
                    token = node.publisher_token(topic, entity, qos)
                    entity += 1
                    pub = (
                        _latched(session, topic.data_key, heartbeat=True)
                        if latched
                        else session.declare_publisher(
                            topic.data_key, encoding=CDR, reliability=zenoh.Reliability.RELIABLE
                        )
                    )
                    outs.append(_Out(pub, gid=gid_of(token)))
                    r.tokens.append(session.liveliness().declare_token(token))
            self.robots.append(r)
            log.info("Serving %s/%s to ROS 2 robot %s as %s/map (%s)", robot.storey, robot.skill,
                     robot.name, robot.namespace, ", ".join(robot.ros))  # fmt: skip

    def _for(self, storey: str, skill: str) -> list[_Robot]:
        return [r for r in self.robots if r.config.storey == storey and r.config.skill == skill]

    def emit(self, event: TwinEvent) -> None:
        try:
            if isinstance(event, MapPublished):
                robots = self._for(event.grid.storey, event.grid.skill)
                if robots:
                    payload = encode_occupancy_grid(
                        event.grid, stamp_ns=event.stamp_ns, frame_id=self.frame_id
                    )
                    for r in robots:
                        for out in r.maps:
                            out.put(payload, event.stamp_ns)
            elif isinstance(event, MapUpdated):
                robots = self._for(event.storey, event.skill)
                if not robots:
                    return
                payload = encode_update_cells(
                    event.frame, event.window, event.data, stamp_ns=event.stamp_ns, frame_id=self.frame_id
                )
                for r in robots:
                    for out in r.updates:
                        out.put(payload, event.stamp_ns)
        except Exception:  # a ROS layout must never stop the twin
            log.exception("Publishing %s to ROS 2 robots failed", type(event).__name__)

    def close(self) -> None:
        for r in self.robots:
            for entity in (*(o.publisher for o in (*r.maps, *r.updates)), *r.tokens):
                try:
                    entity.undeclare()
                except Exception:
                    log.debug("undeclare failed", exc_info=True)
        self.robots.clear()
