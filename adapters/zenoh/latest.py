"""The one holder of each map's latest version on the Zenoh side (updates applied), for everything that
answers with the current map: a ``get`` on ``map/<storey>/<skill>``, a late joiner's history query on
any layout (:mod:`adapters.zenoh.latched`), a robot's storey switch and the full maps of a robot
topic's ``full_every_s`` policy (:mod:`adapters.zenoh.ros_maps`). It holds the points skills' clouds
too (:meth:`LatestMaps.publish_points`, :meth:`LatestMaps.cloud`), for a ``get`` on
``points/<storey>/<skill>`` (:mod:`adapters.zenoh.points`) and a robot's ``points_map`` topics
(:mod:`adapters.zenoh.ros_points`): a cloud has no updates, so each version is encoded once, when it
arrives, and only its CDR is held.

It is written on one thread (the daemon's dispatcher, off the writer's thread, in the order the writer
emitted) and read from any thread under its lock. Each version's full CDR is encoded once, when first
asked for, and each version gets a Zenoh timestamp when it is made: replies carry it, so a late joiner
that gets the same version from two of its queries (zenoh-ext's history and late-publisher queries)
keeps one.

Example::

    maps = LatestMaps(frame_id="map", timestamp=session.new_timestamp)
    maps.publish(map_published_event)
    maps.update(map_updated_event)
    current = maps.current(("ground-floor", "navigation"))   # payload, revision, version, timestamp
    maps.publish_points(points_published_event)
    cloud = maps.cloud(("ground-floor", "lidar3d"))          # the same, a CDR PointCloud2
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from adapters.ros import encode_occupancy_grid
from adapters.ros.pcd import encode_point_cloud2
from twin.live.events import MapPublished, MapUpdated, PointsPublished
from twin.maps.grid import OccupancyGrid

MapKey = tuple[str, str]


@dataclass(slots=True)
class _Held:
    grid: OccupancyGrid  # our own copy: updates are applied in place
    revision: int
    version: int
    stamp_ns: int
    timestamp: Any  # zenoh.Timestamp of this version (None without one)
    payload: bytes | None = None  # the full CDR of this version, once asked for


@dataclass(frozen=True, slots=True)
class Current:
    """A map's latest version as sent: the full CDR, its revision, version, header stamp and the Zenoh
    timestamp of the version."""

    payload: bytes
    revision: int
    version: int
    stamp_ns: int
    timestamp: Any


class LatestMaps:
    """Each map's latest version, updates applied: one writer, readers on any thread."""

    def __init__(self, *, frame_id: str, timestamp: Callable[[], Any] = lambda: None) -> None:
        self.frame_id = frame_id
        self.timestamp = timestamp
        self._lock = threading.Lock()
        self._maps: dict[MapKey, _Held] = {}
        self._clouds: dict[MapKey, Current] = {}

    def publish(self, event: MapPublished) -> None:
        """A full version: replaces what is held (a copy of it)."""
        g = event.grid
        own = OccupancyGrid(g.frame, g.data.copy(), g.storey, g.skill, g.elevation_m)
        held = _Held(own, event.revision, event.version, event.stamp_ns, self.timestamp())
        with self._lock:
            self._maps[(g.storey, g.skill)] = held

    def update(self, event: MapUpdated) -> bool:
        """Apply an update; False (nothing changed) for a map not held or of another extent."""
        ts = self.timestamp()
        with self._lock:
            held = self._maps.get((event.storey, event.skill))
            if held is None or held.grid.frame != event.frame:
                return False
            w = event.window
            held.grid.data[w.row0 : w.row1, w.col0 : w.col1] = event.data
            held.revision, held.version, held.stamp_ns = event.revision, event.version, event.stamp_ns
            held.timestamp, held.payload = ts, None
        return True

    def publish_points(self, event: PointsPublished) -> None:
        """A points map's new cloud: encoded once (CDR ``PointCloud2``), replaces what is held."""
        c = event.cloud
        payload = encode_point_cloud2(c, stamp_ns=event.stamp_ns, frame_id=self.frame_id)
        now = Current(payload, event.revision, event.version, event.stamp_ns, self.timestamp())
        with self._lock:
            self._clouds[(c.storey, c.skill)] = now

    def cloud(self, key: MapKey) -> Current | None:
        """The latest cloud of points map ``key`` (its CDR ``PointCloud2``), or None when not held."""
        with self._lock:
            return self._clouds.get(key)

    def clouds(self) -> list[MapKey]:
        """The keys of the clouds held, sorted."""
        with self._lock:
            return sorted(self._clouds)

    def remove(self, key: MapKey) -> None:
        """Forget map ``key`` (a grid or a cloud: a removed skill's)."""
        with self._lock:
            self._maps.pop(key, None)
            self._clouds.pop(key, None)

    def __contains__(self, key: object) -> bool:
        with self._lock:
            return key in self._maps

    def held(self) -> list[MapKey]:
        """The keys of the maps held, sorted."""
        with self._lock:
            return sorted(self._maps)

    def timestamp_of(self, key: MapKey) -> Any:
        """The Zenoh timestamp of map ``key``'s latest version (None: not held, or no timestamps)."""
        with self._lock:
            held = self._maps.get(key)
            return None if held is None else held.timestamp

    def versions(self) -> list[dict[str, object]]:
        """``{"storey", "skill", "version", "revision"}`` of every map held (its latest version), sorted."""
        with self._lock:
            return [
                {"storey": s, "skill": k, "version": h.version, "revision": h.revision}
                for (s, k), h in sorted(self._maps.items())
            ]

    def version(self, key: MapKey) -> int | None:
        with self._lock:
            held = self._maps.get(key)
            return None if held is None else held.version

    def current(self, key: MapKey) -> Current | None:
        """The latest version of map ``key`` as a full CDR ``OccupancyGrid`` (encoded once per version),
        or None when the map is not held."""
        with self._lock:
            held = self._maps.get(key)
            if held is None:
                return None
            if held.payload is None:
                held.payload = encode_occupancy_grid(
                    held.grid, stamp_ns=held.stamp_ns, frame_id=self.frame_id
                )
            return Current(held.payload, held.revision, held.version, held.stamp_ns, held.timestamp)

    def clear(self) -> None:
        with self._lock:
            self._maps.clear()
            self._clouds.clear()
