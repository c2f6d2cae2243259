"""Points maps on Zenoh: each (storey, points skill) cloud, latched, on ``<prefix>/points/<storey>/<skill>``.

A :class:`~twin.live.events.TwinSink` for :class:`~twin.live.events.PointsPublished`: the payload is the CDR
``sensor_msgs/msg/PointCloud2`` (x y z float32 in the map frame, ``frame_id`` from ``[ros] frame_id``)
from an AdvancedPublisher with a cache of one and publisher detection (late joiners get the latest
cloud, as with the 2D maps' ``map/`` keys); each sample carries the attachment
``{"revision": R, "version": V}``. The twin publishes a changed cloud whole, at most once a second
(:data:`twin.live.live_points.POINTS_INTERVAL_S`). A removed skill's keys are undeclared.

Example::

    points = ZenohPoints(session, prefix="twin/lab", frame_id="map")
    service.sinks.append(OutboxSink(points, daemon.outbox))     # encoded off the writer's thread
"""

from __future__ import annotations

import json
import logging
from typing import Any

import zenoh

from adapters.ros.pcd import encode_point_cloud2
from adapters.zenoh.keys import check_chunk
from adapters.zenoh.latched import declare_latched_publisher
from twin.live.events import MapRemoved, PointsPublished, TwinEvent

__all__ = ["ZenohPoints", "points_key"]

log = logging.getLogger(__name__)


def points_key(prefix: str, storey: str, skill: str) -> str:
    """The native key of a points map: ``<prefix>/points/<storey>/<skill>``."""
    return f"{prefix}/points/{check_chunk(storey, 'Storey key')}/{check_chunk(skill, 'Skill name')}"


class ZenohPoints:
    """Publishes every points map's latest cloud, latched. Call :meth:`emit` from one thread."""

    def __init__(self, session: zenoh.Session, *, prefix: str, frame_id: str) -> None:
        self.session = session
        self.prefix = prefix
        self.frame_id = frame_id
        self._out: dict[tuple[str, str], Any] = {}

    def emit(self, event: TwinEvent) -> None:
        if isinstance(event, PointsPublished):
            cloud = event.cloud
            key = (cloud.storey, cloud.skill)
            payload = encode_point_cloud2(cloud, stamp_ns=event.stamp_ns, frame_id=self.frame_id)
            out = self._out.get(key)
            if out is None:
                out = self._out[key] = declare_latched_publisher(self.session, points_key(self.prefix, *key))
            attachment = json.dumps({"revision": event.revision, "version": event.version}).encode()
            out.put(payload, attachment=attachment)
            log.debug("Published %s/%s: %d points (version %d)", *key, len(cloud), event.version)
        elif isinstance(event, MapRemoved):
            out = self._out.pop((event.storey, event.skill), None)
            if out is not None:
                try:
                    out.delete()  # late joiners no longer get the removed skill's cloud
                finally:
                    out.undeclare()

    def close(self) -> None:
        for out in self._out.values():
            out.undeclare()
        self._out.clear()
