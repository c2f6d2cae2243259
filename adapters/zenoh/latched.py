"""Latched maps on Zenoh: the publisher that answers late joiners with the current map, and the
subscription that follows one (the latched full map, then its updates).

A map is *latched* as a ROS 2 ``TRANSIENT_LOCAL`` topic is: a subscriber that joins late still gets
the map. On Zenoh a late joiner is an ``AdvancedSubscriber`` with history and late-publisher detection
(the project's watchers, rmw_zenoh's ``TRANSIENT_LOCAL`` subscriptions, zenoh-bridge-ros2dds's routes):
it queries ``<key>/@adv/**`` when it starts and the publisher's ``<key>/@adv/pub/<zid>/<eid>/_`` when
it sees the publisher's liveliness token.

zenoh-ext's ``AdvancedPublisher`` answers those queries from its cache, which holds only what was
*published*; a map goes out in full only now and then (:mod:`twin.live.publication`) and changes by its
updates in between, so that cache would replay a stale map. :class:`LatchedPublisher` therefore
declares the ``AdvancedPublisher`` with publisher detection and **no cache**, and answers the history
protocol itself: a queryable on exactly the suffix the stock cache would use
(``<key>/@adv/pub/<zid>/<eid or uhlc>/**``) replies with the *current* map (what ``answer`` returns:
the latest version, updates applied), on the topic's own key, on the caller's send lane (so the reply is
ordered with the topic's updates). A reply travels with its query's QoS (zenoh 1.x ignores the
replier's): zenoh-ext's history queries are congestion BLOCK at DATA priority, as the live samples.
A reply cannot carry zenoh-ext's source info from Python, so it carries the version's Zenoh timestamp
instead: zenoh-ext's subscriber
keeps one sample per timestamp, so the same version answered to its history query, its late-publisher
query and a heartbeat's recovery query (``_sn=..``) is delivered once. Live samples keep the sequence
numbers of the ``AdvancedPublisher`` (with the sporadic heartbeat for rmw_zenoh), which its miss
detection tracks as before.

The daemon's own keys (``map/<storey>/<skill>``, :mod:`adapters.zenoh.daemon`), the ROS 2 layouts
(:mod:`adapters.zenoh.ros_maps`) and the watchers (:mod:`adapters.zenoh.client`,
:mod:`adapters.zenoh.ros_watch`) all declare them here, so they cannot drift apart.

Example::

    latched = LatchedPublisher(session, "twin/lab/map/ground-floor/navigation",
                               answer=lambda: (cdr_now, meta_now, timestamp_now), lane=outbox)
    latched.put(cdr_map, attachment=meta)
    follow = LatchedSubscription(session, map_key, updates_key, on_map=..., on_update=...)
    ...
    follow.close()
    latched.undeclare()
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any, Protocol

import zenoh
import zenoh.ext

log = logging.getLogger(__name__)

CDR = zenoh.Encoding.APPLICATION_CDR
BLOCK = zenoh.CongestionControl.BLOCK
MAP_PRIORITY = zenoh.Priority.DATA
"""One priority for a map topic and its updates: Zenoh queues each priority apart, and an update that
overtook the full map it follows would be overwritten by it (nav2 cannot tell)."""

Answer = tuple[bytes, bytes | None, Any]
"""What a history query is answered with: the current full CDR, its attachment, its Zenoh timestamp."""


class Lane(Protocol):
    """Where sends are made, in order (an :class:`~adapters.zenoh.outbox.Outbox`)."""

    def put(self, job: Callable[[], None]) -> None: ...


class LatchedPublisher:
    """A latched map topic on ``key``: live samples from an ``AdvancedPublisher`` (publisher detection,
    no cache; reliable, BLOCK), late joiners answered with ``answer()`` (None: nothing to answer yet) on
    ``lane``. ``heartbeat_s`` adds rmw_zenoh's sporadic heartbeat (and with it sequence numbers)."""

    def __init__(
        self,
        session: zenoh.Session,
        key: str,
        *,
        answer: Callable[[], Answer | None],
        lane: Lane,
        heartbeat_s: float | None = None,
    ) -> None:
        self.key = key
        self.answer = answer
        self.lane = lane
        self.publisher: Any = zenoh.ext.declare_advanced_publisher(
            session,
            key,
            encoding=CDR,
            congestion_control=BLOCK,
            priority=MAP_PRIORITY,
            reliability=zenoh.Reliability.RELIABLE,
            publisher_detection=True,
            sample_miss_detection=(
                None
                if heartbeat_s is None
                else zenoh.ext.MissDetectionConfig(heartbeat=None, sporadic_heartbeat=heartbeat_s)
            ),
        )
        pid = self.publisher.id
        source = str(pid.eid) if heartbeat_s is not None else "uhlc"  # zenoh-ext's suffix (KE_UHLC)
        self.history_key = f"{key}/@adv/pub/{pid.zid}/{source}/**"
        self.queryable = session.declare_queryable(self.history_key, self._on_query)
        self.answered = 0

    def put(self, payload: bytes, *, attachment: bytes | None = None, timestamp: Any = None) -> None:
        """Publish a full map; ``timestamp``: its version's (what a history reply of it carries too)."""
        self.publisher.put(payload, attachment=attachment, timestamp=timestamp)

    def delete(self) -> None:
        self.publisher.delete()

    def _on_query(self, query: zenoh.Query) -> None:  # a Zenoh thread: hand it to the lane
        self.lane.put(lambda: self._reply(query))

    def _reply(self, query: zenoh.Query) -> None:
        try:
            now = self.answer()
            if now is not None:
                payload, attachment, timestamp = now
                # a reply travels with the query's QoS: zenoh-ext's history queries (and a get) are
                # BLOCK at DATA priority by default, as the map's live samples
                query.reply(self.key, payload, encoding=CDR, attachment=attachment, timestamp=timestamp)
                self.answered += 1
        finally:
            query.drop()

    def undeclare(self) -> None:
        for entity in (self.queryable, self.publisher):
            try:
                entity.undeclare()
            except Exception:
                log.debug("undeclare on %s failed", self.key, exc_info=True)


def declare_latched_publisher(session: zenoh.Session, key: str, *, heartbeat_s: float | None = None) -> Any:
    """An ``AdvancedPublisher`` of CDR on ``key`` that keeps its last sample for late joiners: for a
    topic published once and never changed (a costmap filter's info); maps use :class:`LatchedPublisher`.

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
