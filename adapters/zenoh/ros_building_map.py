"""Open-RMF's building map on ROS 2: ``/map``, an ``rmf_building_map_msgs/msg/BuildingMap``, latched.

``building_map_server`` publishes the building map once on ``/map`` with KEEP_LAST 1, RELIABLE,
TRANSIENT_LOCAL; so does the daemon, in both ROS 2 layouts (:mod:`adapters.zenoh.ros_maps` has the
details): for ``zenoh-bridge-ros2dds``, key ``map``; for ``rmw_zenoh``, the topic's data key with the
type's RIHS01 hash, a node ``/twin_building_map_server`` and its publisher's liveliness tokens, and
rmw_zenoh's attachment on the sample. Both are ``AdvancedPublisher``s with a cache of one sample and
publisher detection, so a late joiner (the bridge's route, an rmw_zenoh ``TRANSIENT_LOCAL``
subscription) gets the current map. Robots' maps never use ``/map``: a robot's namespace is required
and is never ``/``.

Example::

    out = RosBuildingMap(session, payload, domain_id=0)
    out.put(new_payload)      # a new version of the building
    out.close()
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from typing import Any

import zenoh

from adapters.ros.building_map_msgs import BUILDING_MAP
from adapters.ros.rmw_zenoh import LATCHED_QOS, RosNode, RosTopic, attachment, gid_of
from adapters.ros.settings import RosLayout
from adapters.zenoh.latched import declare_latched_publisher

log = logging.getLogger(__name__)

NODE_NAME = "twin_building_map_server"
ENTITY_BASE = 9000
"""Node and entity ids of this node in the daemon's rmw_zenoh graph (the robots' nodes count from 0)."""
RMW_HEARTBEAT_S = 0.5


class RosBuildingMap:
    """The latched ``/map`` topic of the building map, in the given layouts."""

    def __init__(
        self,
        session: zenoh.Session,
        payload: bytes,
        *,
        domain_id: int = 0,
        layouts: Sequence[RosLayout] = ("bridge", "rmw_zenoh"),
    ) -> None:
        self.topic = RosTopic(domain_id, "/", "map", BUILDING_MAP)
        self._entities: list[Any] = []
        self._outs: list[tuple[Any, bytes | None]] = []
        self._sequence = 0
        if "bridge" in layouts:
            publisher = declare_latched_publisher(session, self.topic.bridge_key)
            self._entities.append(publisher)
            self._outs.append((publisher, None))
        if "rmw_zenoh" in layouts:
            node = RosNode(domain_id, "/", NODE_NAME, str(session.zid()), ENTITY_BASE)
            token = node.publisher_token(self.topic, ENTITY_BASE + 1, LATCHED_QOS)
            publisher = declare_latched_publisher(session, self.topic.data_key, heartbeat_s=RMW_HEARTBEAT_S)
            self._entities += [
                session.liveliness().declare_token(node.node_token()),
                session.liveliness().declare_token(token),
                publisher,
            ]
            self._outs.append((publisher, gid_of(token)))
        self.put(payload)

    def put(self, payload: bytes) -> None:
        """Publish ``payload`` (CDR ``BuildingMap``) as the current building map."""
        self._sequence += 1
        stamp = time.time_ns()
        for publisher, gid in self._outs:
            if gid is None:
                publisher.put(payload)
            else:
                publisher.put(payload, attachment=attachment(self._sequence, stamp, gid))

    def close(self) -> None:
        for entity in reversed(self._entities):
            try:
                entity.undeclare()
            except Exception:
                log.debug("undeclare of a /map entity failed", exc_info=True)
