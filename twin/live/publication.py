"""Full maps out: when a map goes out in full, and when each map last did.

A change costs its changed cells: its updates (the changed rectangles) go out at once and nothing else.
A map goes out in full (:class:`~twin.live.events.MapPublished`) only

- on its first publication (start-up, a skill added), on a skill change, and when its extent (grid
  frame) changed;
- as a *keyframe*: when it changed since its last full publication and that was at least
  ``keyframe_interval_s`` ago (a minute by default). The keyframe heals an update a subscriber lost
  (nav2 cannot detect the gap, nor ask) and refreshes what caches replay to late joiners (a ROS 2
  bridge's DDS cache); a map that does not change is never sent again.

A storey switch, a ``get`` and a late joiner's history query are answered by the adapters from the
latest version they hold (updates applied), not from here.

Example::

    pub = Publication(emit=sink.emit, clock=time.time_ns, keyframe_s=60.0)
    pub.publish(live_map, revision=0)            # at start: every map
    pub.changed(("ground-floor", "navigation"))  # an update went out
    pub.flush(maps, revision=7, due_only=True)   # the keyframes that are due
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

from twin.live.events import MapPublished, TwinEvent
from twin.live.live_map import LiveMap
from twin.live.overlay import MapKey
from twin.maps.grid import GridFrame


@dataclass(frozen=True, slots=True)
class PublishedVersion:
    """What went out with a map's latest full publication (not the cells: the live map holds those,
    and the adapters hold what they sent)."""

    storey: str
    skill: str
    frame: GridFrame
    revision: int
    version: int
    stamp_ns: int


class Publication:
    """When each map last went out in full, and which changed maps owe a keyframe. One writer."""

    def __init__(
        self, *, emit: Callable[[TwinEvent], None], clock: Callable[[], int], keyframe_s: float
    ) -> None:
        self.emit = emit
        self.clock = clock
        self.keyframe_ns = int(keyframe_s * 1e9)
        self.latest: dict[MapKey, PublishedVersion] = {}
        """Each map's latest *full publication* (frame, revision, version, stamp; no cells): what decides
        a keyframe. Not the map's latest version: the live map holds the cells, and the one holder of
        each map's latest version as sent (updates applied) is the Zenoh adapter's ``LatestMaps``."""
        self.pending: dict[MapKey, int] = {}
        """Maps changed since their last full publication -> when the first such change happened (ns)."""

    def publish(self, m: LiveMap, revision: int, stamp: int | None = None) -> None:
        """Publish the full current version of ``m``."""
        stamp = self.clock() if stamp is None else stamp
        grid = m.grid()
        self.latest[m.key] = PublishedVersion(grid.storey, grid.skill, grid.frame, revision, m.version, stamp)
        self.pending.pop(m.key, None)
        self.emit(MapPublished(grid, revision, m.version, stamp))

    def changed(self, key: MapKey, stamp: int) -> None:
        """An update of map ``key`` went out at ``stamp``: a keyframe is owed, in due time."""
        self.pending.setdefault(key, stamp)

    def drop(self, key: MapKey) -> None:
        """Map ``key`` is gone (its skill was removed)."""
        self.latest.pop(key, None)
        self.pending.pop(key, None)

    def due(self, key: MapKey, m: LiveMap, now: int) -> bool:
        """Whether changed map ``key`` goes out in full now: its keyframe is due, or its extent changed."""
        last = self.latest.get(key)
        return last is None or now - last.stamp_ns >= self.keyframe_ns or last.frame != m.plan.frame

    def flush(self, maps: Mapping[MapKey, LiveMap], revision: int, *, due_only: bool = False) -> None:
        """Publish the full version of every map changed since its last full publication; with
        ``due_only``, only the keyframes that are due (see :meth:`due`)."""
        stamp = self.clock()
        for key in sorted(self.pending):
            m = maps.get(key)
            if m is None:
                del self.pending[key]
            elif not due_only or self.due(key, m, stamp):
                self.publish(m, revision, stamp)
