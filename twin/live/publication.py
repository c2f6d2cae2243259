"""Full maps out: the latest full version of every map, and the changed maps that still owe one.

Updates (the changed rectangles) go out at once; a changed map's full version follows
``full_map_interval_s`` after its first unpublished change, so it comes after its updates and a burst
of changes is coalesced into one full map.

Example::

    pub = Publication(emit=sink.emit, clock=time.time_ns, interval_s=0.2)
    pub.publish(live_map, revision=0)            # at start: every map
    pub.changed(("ground-floor", "navigation"))  # an update went out
    pub.flush(maps, revision=7, due_only=True)   # the full versions that are due
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

from twin.events import MapPublished, TwinEvent
from twin.grid import OccupancyGrid
from twin.live.live_map import LiveMap
from twin.live.overlay import MapKey


@dataclass(frozen=True, slots=True)
class PublishedMap:
    """The latest full version of a map that was published (what a ``get`` answers)."""

    grid: OccupancyGrid
    revision: int
    version: int
    stamp_ns: int


class Publication:
    """Which full map versions went out, and which changed maps owe one. One writer."""

    def __init__(
        self, *, emit: Callable[[TwinEvent], None], clock: Callable[[], int], interval_s: float
    ) -> None:
        self.emit = emit
        self.clock = clock
        self.interval_ns = int(interval_s * 1e9)
        self.latest: dict[MapKey, PublishedMap] = {}
        self.pending: dict[MapKey, int] = {}
        """Maps changed since their last full publication -> when the first such change happened (ns)."""

    def publish(self, m: LiveMap, revision: int, stamp: int | None = None) -> None:
        """Publish the full current version of ``m``."""
        stamp = self.clock() if stamp is None else stamp
        grid = m.grid()
        self.latest[m.key] = PublishedMap(grid, revision, m.version, stamp)
        self.emit(MapPublished(grid, revision, m.version, stamp))

    def changed(self, key: MapKey, stamp: int) -> None:
        """An update of map ``key`` went out at ``stamp``: its full version is owed."""
        self.pending.setdefault(key, stamp)

    def drop(self, key: MapKey) -> None:
        """Map ``key`` is gone (its skill was removed)."""
        self.latest.pop(key, None)
        self.pending.pop(key, None)

    def flush(self, maps: Mapping[MapKey, LiveMap], revision: int, *, due_only: bool = False) -> None:
        """Publish the full version of every map changed since its last full publication; with
        ``due_only``, only of those whose first unpublished change is ``interval_s`` old."""
        stamp = self.clock()
        for key, since in sorted(self.pending.items()):
            if due_only and stamp - since < self.interval_ns:
                continue
            del self.pending[key]
            m = maps.get(key)
            if m is not None:
                self.publish(m, revision, stamp)
