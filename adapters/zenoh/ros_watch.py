"""Subscribe to a robot's map topic (``/<ns>/map`` by default) as a ROS 2 node would (for
``twin watch --ros NAMESPACE [--topic NAME]``).

``rmw_zenoh``: a :class:`~adapters.zenoh.latched.LatchedSubscription` (history and late-publisher
detection, as rmw_zenoh_cpp subscribes to TRANSIENT_LOCAL topics) on rmw_zenoh's data keys of the
topic and of ``<topic>_updates``; every sample's attachment must have rmw's 33-byte layout.
``bridge``: the same on zenoh-bridge-ros2dds's keys ``<ns>/<topic>`` and ``<ns>/<topic>_updates``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import zenoh

from adapters.ros import apply_update, decode_occupancy_grid, decode_occupancy_grid_update
from adapters.ros.cdr import OCCUPANCY_GRID, OCCUPANCY_GRID_UPDATE
from adapters.ros.rmw_zenoh import RosTopic, parse_attachment
from adapters.zenoh.latched import LatchedSubscription
from twin.maps.grid import OccupancyGrid

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class RosSample:
    """What arrived: ``kind`` is ``"map"`` or ``"update"``; ``sequence`` from the rmw attachment."""

    kind: str
    grid: OccupancyGrid
    stamp_ns: int
    sequence: int | None


class RosMapWatcher:
    """Keeps a copy of ``<ns>/<topic>`` with ``<ns>/<topic>_updates`` applied; calls ``on_sample``."""

    def __init__(
        self, session: zenoh.Session, *, namespace: str, layout: str = "rmw_zenoh", domain_id: int = 0,
        topic: str = "map", on_sample: Callable[[RosSample], None] | None = None,
    ) -> None:  # fmt: skip
        self.layout = layout
        self.on_sample = on_sample
        self.latest: OccupancyGrid | None = None
        maps = RosTopic(domain_id, namespace, topic, OCCUPANCY_GRID)
        updates = RosTopic(domain_id, namespace, f"{topic}_updates", OCCUPANCY_GRID_UPDATE)
        rmw = layout == "rmw_zenoh"
        self.keys = (maps.data_key, updates.data_key) if rmw else (maps.bridge_key, updates.bridge_key)
        self._follow = LatchedSubscription(
            session, self.keys[0], self.keys[1], on_map=self._on_map, on_update=self._on_update
        )

    def _sequence(self, sample: zenoh.Sample) -> int | None:
        if self.layout != "rmw_zenoh":
            return None
        if sample.attachment is None:
            log.warning("A sample on %s has no rmw attachment: rmw_zenoh would drop it", sample.key_expr)
            return None
        return parse_attachment(sample.attachment.to_bytes())[0]

    def _emit(self, kind: str, grid: OccupancyGrid, stamp: int, seq: int | None) -> None:
        self.latest = grid
        if self.on_sample is not None:
            self.on_sample(RosSample(kind, grid, stamp, seq))

    def _on_map(self, sample: zenoh.Sample) -> None:
        grid, stamp = decode_occupancy_grid(sample.payload.to_bytes())
        self._emit("map", grid, stamp, self._sequence(sample))

    def _on_update(self, sample: zenoh.Sample) -> None:
        if self.latest is None:
            return
        window, cells, stamp = decode_occupancy_grid_update(sample.payload.to_bytes())
        self._emit("update", apply_update(self.latest, window, cells), stamp, self._sequence(sample))

    def close(self) -> None:
        self._follow.close()
