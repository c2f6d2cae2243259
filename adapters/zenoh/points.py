"""Points maps on Zenoh: each (storey, points skill) cloud, latched, on ``<prefix>/points/<storey>/<skill>``.

A :class:`~twin.live.events.TwinSink` for :class:`~twin.live.events.PointsPublished`: the payload is the CDR
``sensor_msgs/msg/PointCloud2`` (x y z normal_x normal_y normal_z float32, 24-byte points, in the map
frame, ``frame_id`` from ``[ros] frame_id``)
from a :class:`~adapters.zenoh.latched.LatchedPublisher` (late joiners get the latest cloud, as with the
2D maps' ``map/`` keys); each sample carries the attachment
``{"revision": R, "version": V}``. A queryable on ``<prefix>/points/**`` answers a ``get`` with the
latest cloud of every points map the key expression names (to the asker alone, same attachment), as
``map/**`` answers with the 2D maps. The twin publishes a changed cloud whole, at most once a second
(:data:`twin.live.live_points.POINTS_INTERVAL_S`). A removed skill's keys are undeclared.

The clouds are read from :class:`~adapters.zenoh.latest.LatestMaps` (the daemon's one holder,
``daemon.maps``, brought up to date before this follower is called), and
sent, like the replies, on one lane (in the daemon the site's: ``daemon.site``).

Example::

    points = ZenohPoints(session, prefix="twin/lab", frame_id="map", maps=daemon.maps, lane=daemon.site)
    daemon.followers.append(points)     # on the daemon's dispatcher, off the writer's thread
"""

from __future__ import annotations

import logging

import zenoh

from adapters.zenoh.daemon import revision_attachment
from adapters.zenoh.keys import SiteKeys
from adapters.zenoh.latched import CDR, Answer, Lane, LatchedPublisher
from adapters.zenoh.latest import Current, LatestMaps
from adapters.zenoh.outbox import Outbox
from twin.live.events import MapRemoved, PointsPublished, TwinEvent

__all__ = ["ZenohPoints", "points_key"]

log = logging.getLogger(__name__)


def points_key(prefix: str, storey: str, skill: str) -> str:
    """The native key of a points map: ``<prefix>/points/<storey>/<skill>``."""
    return SiteKeys(prefix).points_map(storey, skill)


def _attachment(now: Current) -> bytes:
    return revision_attachment(now.revision, now.version)  # the 2D maps' attachment


class ZenohPoints:
    """Publishes every points map's latest cloud, latched, and answers ``get`` with it. Call :meth:`emit`
    from one thread."""

    def __init__(
        self,
        session: zenoh.Session,
        *,
        prefix: str,
        frame_id: str,
        maps: LatestMaps,
        lane: Lane | None = None,
    ) -> None:
        self.session = session
        self.keys = SiteKeys(prefix)
        self.frame_id = frame_id
        self.maps = maps
        """The daemon's one holder of each map's and cloud's latest version (the dispatcher writes it
        before this follower is called; read here)."""
        self._own_lane: Outbox | None = None
        if lane is None:
            lane = self._own_lane = Outbox("twin-zenoh-points")
        self.lane = lane
        self._out: dict[tuple[str, str], LatchedPublisher] = {}
        self._queryable = session.declare_queryable(self.keys.points, self._on_get)

    def emit(self, event: TwinEvent) -> None:
        if isinstance(event, PointsPublished):
            key = (event.cloud.storey, event.cloud.skill)
            self.lane.put(lambda: self._put(key))
        elif isinstance(event, MapRemoved):
            self.lane.put(lambda: self._remove((event.storey, event.skill)))

    def _put(self, key: tuple[str, str]) -> None:
        """On the lane: the latest cloud of ``key`` (declaring its publisher first)."""
        now = self.maps.cloud(key)
        if now is None:
            return
        out = self._out.get(key)
        if out is None:
            name = self.keys.points_map(*key)
            out = self._out[key] = LatchedPublisher(
                self.session, name, answer=lambda: self._answer(key), lane=self.lane
            )
        out.put(now.payload, attachment=_attachment(now), timestamp=now.timestamp)
        log.debug("Published the cloud %s/%s (version %d)", *key, now.version)

    def _answer(self, key: tuple[str, str]) -> Answer | None:
        """A late joiner's cloud of ``key``: the latest one (on the lane)."""
        now = self.maps.cloud(key)
        return None if now is None else (now.payload, _attachment(now), now.timestamp)

    def _remove(self, key: tuple[str, str]) -> None:
        out = self._out.pop(key, None)
        if out is not None:
            try:
                out.delete()  # subscribers see the cloud go, as a removed map
            finally:
                out.undeclare()

    def _on_get(self, query: zenoh.Query) -> None:  # a Zenoh thread: answered on the lane
        self.lane.put(lambda: self._reply(query))

    def _reply(self, query: zenoh.Query) -> None:
        try:
            for key in self.maps.clouds():
                name = self.keys.points_map(*key)
                if (
                    zenoh.KeyExpr(name).intersects(query.key_expr)
                    and (now := self.maps.cloud(key)) is not None
                ):
                    query.reply(
                        name, now.payload, encoding=CDR, attachment=_attachment(now), timestamp=now.timestamp
                    )
        finally:
            query.drop()

    def drain(self) -> None:
        """Wait until the sends and replies queued so far were made (own lane only; the daemon drains its
        site lane itself)."""
        if self._own_lane is not None:
            self._own_lane.drain()

    def close(self) -> None:
        if self._own_lane is not None:
            self._own_lane.close()
        try:
            self._queryable.undeclare()
        except Exception:  # already gone with the session
            log.debug("Undeclaring the points queryable failed", exc_info=True)
        for out in self._out.values():
            out.undeclare()
        self._out.clear()
