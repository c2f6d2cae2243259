"""Latched maps on Zenoh: the publisher that keeps its last map for late joiners, and the subscription
that follows one (the latched full map, then its updates).

A map is *latched* as a ROS 2 ``TRANSIENT_LOCAL`` topic is: a subscriber that joins late still gets
the last map. On Zenoh that is an ``AdvancedPublisher`` with a cache of one sample and publisher
detection, followed by an ``AdvancedSubscriber`` with history and late-publisher detection. The
daemon's own keys (``map/<storey>/<skill>``, :mod:`adapters.zenoh.daemon`), the ROS 2 layouts
(:mod:`adapters.zenoh.ros_maps`) and the watchers (:mod:`adapters.zenoh.client`,
:mod:`adapters.zenoh.ros_watch`) all declare them here, so they cannot drift apart.

Example::

    latched = declare_latched_publisher(session, "twin/lab/map/ground-floor/navigation")
    latched.put(cdr_map, attachment=meta)
    follow = LatchedSubscription(session, map_key, updates_key, on_map=..., on_update=...)
    ...
    follow.close()
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import zenoh
import zenoh.ext

log = logging.getLogger(__name__)

CDR = zenoh.Encoding.APPLICATION_CDR


def declare_latched_publisher(session: zenoh.Session, key: str, *, heartbeat_s: float | None = None) -> Any:
    """An ``AdvancedPublisher`` of CDR on ``key`` that keeps its last sample for late joiners.

    Reliable, congestion control BLOCK (a map is never dropped), a cache of one sample and publisher
    detection (so an ``AdvancedSubscriber`` with late-publisher detection asks it for that sample).
    ``heartbeat_s`` adds a sporadic heartbeat of that period for sample-miss detection, as rmw_zenoh
    declares its ``TRANSIENT_LOCAL`` publishers. Returns the ``zenoh.ext.AdvancedPublisher``.
    """
    return zenoh.ext.declare_advanced_publisher(
        session,
        key,
        encoding=CDR,
        congestion_control=zenoh.CongestionControl.BLOCK,
        reliability=zenoh.Reliability.RELIABLE,
        cache=zenoh.ext.CacheConfig(max_samples=1),
        publisher_detection=True,
        sample_miss_detection=(
            None
            if heartbeat_s is None
            else zenoh.ext.MissDetectionConfig(heartbeat=None, sporadic_heartbeat=heartbeat_s)
        ),
    )


def declare_latched_subscriber(
    session: zenoh.Session,
    key: str,
    on_sample: Callable[[zenoh.Sample], None],
    *,
    max_samples: int | None = 1,
) -> Any:
    """An ``AdvancedSubscriber`` on ``key`` that also gets the last sample(s) of latched publishers,
    late ones included (up to ``max_samples`` a publisher; None: all it holds). Returns it."""
    history = (
        zenoh.ext.HistoryConfig(detect_late_publishers=True)
        if max_samples is None
        else zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=max_samples)
    )
    return zenoh.ext.declare_advanced_subscriber(session, key, on_sample, history=history)


class LatchedSubscription:
    """Follows one latched map: its updates on ``updates_key`` and its full map on ``map_key``.

    The updates' subscriber is declared first, so no update published after the latched map arrives
    is missed; the map's is an ``AdvancedSubscriber`` asking late publishers for their last sample.
    ``on_map`` and ``on_update`` run on Zenoh's threads. ``close`` undeclares both.
    """

    def __init__(
        self,
        session: zenoh.Session,
        map_key: str,
        updates_key: str,
        *,
        on_map: Callable[[zenoh.Sample], None],
        on_update: Callable[[zenoh.Sample], None],
    ) -> None:
        self.map_key, self.updates_key = map_key, updates_key
        self._updates = session.declare_subscriber(updates_key, on_update)
        self._maps = declare_latched_subscriber(session, map_key, on_map)

    def close(self) -> None:
        for entity in (self._maps, self._updates):
            try:
                entity.undeclare()
            except Exception:
                log.debug("undeclare of a subscriber on %s failed", self.map_key, exc_info=True)
