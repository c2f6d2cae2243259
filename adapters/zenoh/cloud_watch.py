"""Follow a latched point cloud (``sensor_msgs/msg/PointCloud2``) as a 3D localizer would: the daemon's
``points/<storey>/<skill>`` keys or a ROS 2 robot's ``points_map`` topic (for ``twin watch``).

A cloud has no update message: every sample is a whole cloud. The subscriber is latched (history and
late-publisher detection, :func:`~adapters.zenoh.latched.declare_latched_subscriber`), so a watcher
that joins late still gets the current cloud.

Example::

    watcher = CloudWatcher(session, "twin/lab/points/ground-floor/lidar3d", on_cloud=print)
    ...
    watcher.close()
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import zenoh

from adapters.ros.pcd import FIELDS, decode_point_cloud2
from adapters.zenoh.latched import declare_latched_subscriber

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class CloudSample:
    """One whole cloud: ``points (n, 6) float32`` (x y z normal_x normal_y normal_z, the map frame),
    its stamp and the sample's attachment (the daemon's revision and version, or rmw_zenoh's)."""

    key: str
    points: npt.NDArray[np.float32]
    stamp_ns: int
    attachment: bytes | None


class CloudWatcher:
    """Calls ``on_cloud`` with every cloud published on ``key`` (the latched one first); ``latest`` is
    the last one. Samples that are not a readable ``PointCloud2`` are logged and skipped."""

    def __init__(self, session: zenoh.Session, key: str, *, on_cloud: Callable[[CloudSample], None]) -> None:
        self.key = key
        self.on_cloud = on_cloud
        self.latest: CloudSample | None = None
        self._lock = threading.Lock()
        self._sub = declare_latched_subscriber(session, key, self._on_sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.DELETE:
            return
        try:
            values, stamp, _ = decode_point_cloud2(sample.payload.to_bytes(), fields=FIELDS)
        except Exception as err:  # a foreign payload on the key: say so, keep watching
            log.warning("A sample on %s is not a PointCloud2 this watcher reads: %s", sample.key_expr, err)
            return
        attachment = sample.attachment.to_bytes() if sample.attachment is not None else None
        cloud = CloudSample(str(sample.key_expr), values, stamp, attachment)
        with self._lock:
            self.latest = cloud
        self.on_cloud(cloud)

    def close(self) -> None:
        try:
            self._sub.undeclare()
        except Exception:
            log.debug("undeclare of the cloud subscriber on %s failed", self.key, exc_info=True)
