"""The daemon's Zenoh side: binds a :class:`twin.live.TwinService` to a session.

Declares, under the site's prefix (see :class:`~adapters.zenoh.keys.SiteKeys`):

- per map, a latched publisher on ``map/<storey>/<skill>`` (:class:`~adapters.zenoh.latched.LatchedPublisher`:
  full maps, and late joiners answered with the current map) and a publisher on
  ``map_updates/<storey>/<skill>``; both reliable, congestion BLOCK, one priority; samples carry the
  attachment ``{"revision": R, "version": V}`` (JSON);
- a queryable on ``map/**`` answering ``get`` with the current maps (CDR ``OccupancyGrid``, every
  committed change in it; to the asker alone);
- a subscriber on ``observations/*`` (best effort: errors are logged) and a queryable on
  ``observe/*`` (the JSON ack once the change is durable, or ``reply_err`` with the error);
- a subscriber on ``skills/*`` (put a JSON profile, delete to remove) and a queryable listing them;
- queryables ``sparql`` (read-only) and ``status``; the liveliness token ``daemon``.

Zenoh callbacks only enqueue work for the service's thread or read immutable snapshots. The one way off
the writer's thread is the daemon's dispatcher (:attr:`ZenohDaemon.outbox`): in the order the writer
emitted, it brings :attr:`ZenohDaemon.maps` (the one holder of each map's latest version) up to date,
then hands the sends to *lanes*, one thread each: the site's keys and acks on :attr:`ZenohDaemon.site`,
and each ROS 2 robot's topics on that robot's own lane (the ``followers``, e.g.
:class:`~adapters.zenoh.ros_maps.RosMapPublisher`, attached by ``RosMapPublisher.following(daemon,
config)``: it reads :attr:`ZenohDaemon.maps` and keeps no map of its own). A blocking send (a big map
on a slow link) holds only its lane: the writer never waits for Zenoh, and one robot never waits for
another.

Example::

    with zenoh.open(conf) as session:
        daemon = ZenohDaemon(session, service, keys=SiteKeys("twin/lab"), frame_id="map")
        service.sinks.append(daemon)
        service.start()
        ...
        daemon.close()
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh

from adapters.ros import encode_update_cells
from adapters.zenoh.gate import CallbackGate
from adapters.zenoh.keys import SiteKeys
from adapters.zenoh.latched import BLOCK, CDR, MAP_PRIORITY, Answer, LatchedPublisher
from adapters.zenoh.latest import LatestMaps
from adapters.zenoh.outbox import Outbox
from twin.errors import TwinError
from twin.live import Reply, TwinService
from twin.live.events import (
    MapPublished,
    MapRemoved,
    MapUpdated,
    PointsPublished,
    RobotStoreyChanged,
    TwinEvent,
    TwinSink,
    TwinStarted,
)

log = logging.getLogger(__name__)

JSON = zenoh.Encoding.APPLICATION_JSON


def revision_attachment(revision: int, version: int) -> bytes:
    """The attachment of every map sample: JSON ``{"revision": R, "version": V}``."""
    return json.dumps({"revision": revision, "version": version}).encode()


@dataclass(slots=True)
class _MapOut:
    latched: LatchedPublisher
    updates: zenoh.Publisher


class ZenohDaemon:
    """Publishes the service's maps and feeds it the robots' requests. A
    :class:`~twin.live.events.TwinSink`."""

    def __init__(
        self, session: zenoh.Session, service: TwinService, *, keys: SiteKeys, frame_id: str
    ) -> None:
        self.session = session
        self.service = service
        self.keys = keys
        self.frame_id = frame_id
        self.maps = LatestMaps(frame_id=frame_id, timestamp=session.new_timestamp)
        """Each map's latest version, updates applied: what a get and a late joiner are answered with."""
        self._outs: dict[tuple[str, str], _MapOut] = {}
        self.outbox = Outbox("twin-zenoh-out")
        """The dispatcher: the writer's events, in order, off its thread."""
        self.site = Outbox("twin-zenoh-site")
        """The lane of the site's keys (maps, updates) and of the replies to requests."""
        self.followers: list[TwinSink] = []
        """Sinks that publish maps too (the ROS 2 topics): called on the dispatcher after :attr:`maps`
        is up to date; they make their sends on lanes of their own."""
        self.status_sources: list[Callable[[], dict[str, object]]] = []
        """More sections of the status reply (e.g. the ROS robots' storeys), merged over the service's."""
        self.gate = CallbackGate()
        """The callbacks below, counted: :meth:`close` lets no new one in and waits for the running."""
        gate = self.gate.wrap
        self._declared: list[Any] = [
            session.liveliness().declare_token(keys.daemon),
            session.declare_subscriber(keys.all_observations, gate(self._on_observation)),
            session.declare_queryable(keys.all_observe, gate(self._on_observe)),
            session.declare_subscriber(keys.skills, gate(self._on_skill)),
            session.declare_queryable(keys.skills_listing, gate(self._on_list_skills)),
            session.declare_queryable(keys.maps, gate(self._on_get_map)),
            session.declare_queryable(keys.sparql, gate(self._on_sparql)),
            session.declare_queryable(keys.status, gate(self._on_status)),
            session.declare_queryable(keys.explain, gate(self._on_explain)),
        ]

    # --- sink ---------------------------------------------------------------------------------------
    def emit(self, event: TwinEvent) -> None:
        if isinstance(
            event, MapPublished | MapUpdated | MapRemoved | TwinStarted | RobotStoreyChanged | PointsPublished
        ):
            self.outbox.put(lambda: self._dispatch(event))

    def drain(self) -> None:
        """Wait until every map sample and reply queued so far was sent (on every lane)."""
        self.outbox.drain()
        self.site.drain()
        for follower in self.followers:
            drain = getattr(follower, "drain", None)
            if drain is not None:
                drain()

    def _dispatch(self, event: TwinEvent) -> None:
        """On the dispatcher: the holder first, then the sends, each on its lane."""
        if isinstance(event, MapPublished):
            self.maps.publish(event)
            key = (event.grid.storey, event.grid.skill)
            self.site.put(lambda: self._publish(key))
        elif isinstance(event, MapUpdated):
            if not self.maps.update(event):  # its full map follows (first map, or a new extent)
                log.debug("An update of %s/%s without its map (of that extent) held: its full map follows",
                          event.storey, event.skill)  # fmt: skip
                return
            timestamp = self.maps.timestamp_of((event.storey, event.skill))
            self.site.put(lambda: self._update(event, timestamp))
        elif isinstance(event, MapRemoved):
            self.maps.remove((event.storey, event.skill))
            self.site.put(lambda: self._remove(event.storey, event.skill))
        elif isinstance(event, PointsPublished):  # a cloud: held here, sent by its followers
            self.maps.publish_points(event)
        for follower in self.followers:
            try:
                follower.emit(event)
            except Exception:  # a layout must never stop the others
                log.exception("%s failed on %s", type(follower).__name__, type(event).__name__)

    def _answer(self, key: tuple[str, str]) -> Answer | None:
        now = self.maps.current(key)
        if now is None:
            return None
        return now.payload, revision_attachment(now.revision, now.version), now.timestamp

    def _publish(self, key: tuple[str, str]) -> None:
        """On the site lane: the current full map of ``key`` (declaring its publishers first)."""
        out = self._outs.get(key)
        if out is None:
            latched = LatchedPublisher(
                self.session, self.keys.map(*key), answer=lambda: self._answer(key), lane=self.site
            )
            updates = self.session.declare_publisher(
                self.keys.map_updates(*key),
                encoding=CDR,
                congestion_control=BLOCK,
                priority=MAP_PRIORITY,
                reliability=zenoh.Reliability.RELIABLE,
            )
            out = self._outs[key] = _MapOut(latched, updates)
        now = self._answer(key)
        if now is not None:
            out.latched.put(now[0], attachment=now[1], timestamp=now[2])

    def _update(self, event: MapUpdated, timestamp: Any) -> None:
        """On the site lane: the update, with its version's timestamp (so a router's storage that
        applies it never looks newer than the daemon's later versions)."""
        out = self._outs.get((event.storey, event.skill))
        if out is None:
            return
        payload = encode_update_cells(
            event.frame, event.window, event.data, stamp_ns=event.stamp_ns, frame_id=self.frame_id
        )
        out.updates.put(
            payload, attachment=revision_attachment(event.revision, event.version), timestamp=timestamp
        )

    def _remove(self, storey: str, skill: str) -> None:
        out = self._outs.pop((storey, skill), None)
        if out is None:
            return
        try:
            out.latched.delete()
        finally:
            out.latched.undeclare()
            out.updates.undeclare()

    # --- requests (Zenoh threads: enqueue or read snapshots only) -------------------------------------
    def _on_observation(self, sample: zenoh.Sample) -> None:
        robot = self.keys.robot_of(str(sample.key_expr))
        self.service.submit_observation(robot, sample.payload.to_bytes(), reply=None)

    def _on_observe(self, query: zenoh.Query) -> None:
        key = query.key_expr  # the reply's key, as made (a string would be parsed again)
        robot = self.keys.robot_of(str(key))
        payload = query.payload.to_bytes() if query.payload is not None else b""

        def send(r: Reply) -> None:
            try:
                if r.ok:
                    query.reply(key, r.to_json(), encoding=JSON)
                else:
                    query.reply_err(r.to_json(), encoding=JSON)
            finally:
                query.drop()  # finalise now: the robot's get returns at once, not when Python frees it

        def reply(r: Reply) -> None:  # on the writer's thread: after the map updates, off the thread
            self.outbox.put(lambda: self.site.put(lambda: send(r)))

        self.service.submit_observation(robot, payload, reply=reply)

    def _on_skill(self, sample: zenoh.Sample) -> None:
        name = self.keys.last(str(sample.key_expr))
        if sample.kind == zenoh.SampleKind.DELETE:
            self.service.submit_skill(name, None, reply=_log_reply(f"removing skill {name!r}"))
        else:
            payload = sample.payload.to_bytes()
            self.service.submit_skill(name, payload, reply=_log_reply(f"skill {name!r}"))

    def _on_list_skills(self, query: zenoh.Query) -> None:
        for name, profile in sorted(self.service.skills.items()):
            key = self.keys.skill(name)
            if zenoh.KeyExpr(key).intersects(query.key_expr):
                query.reply(key, json.dumps(profile.to_json()).encode(), encoding=JSON)

    def _on_get_map(self, query: zenoh.Query) -> None:
        self.site.put(lambda: self._reply_maps(query))  # ordered with the updates already sent

    def _reply_maps(self, query: zenoh.Query) -> None:
        try:
            for key in self.maps.held():
                name = self.keys.map(*key)
                if zenoh.KeyExpr(name).intersects(query.key_expr) and (now := self._answer(key)) is not None:
                    query.reply(name, now[0], encoding=CDR, attachment=now[1], timestamp=now[2])
        finally:
            query.drop()

    def _on_sparql(self, query: zenoh.Query) -> None:
        text = query.payload.to_string() if query.payload is not None else ""
        if not text.strip():
            query.reply_err(
                Reply.error("Send the SPARQL query as the payload of the get.").to_json(), encoding=JSON
            )
            return
        try:
            media, body = self.service.query(text)
        except TwinError as err:
            query.reply_err(Reply.error(str(err)).to_json(), encoding=JSON)
            return
        query.reply(self.keys.sparql, body, encoding=zenoh.Encoding(media))

    def _on_explain(self, query: zenoh.Query) -> None:
        """``{"storey": S, "skill": K, "x": X, "y": Y}`` in, :mod:`twin.live.explain`'s answer out."""
        try:
            text = query.payload.to_string() if query.payload is not None else ""
            if len(text) > 4096:
                raise ValueError(f"the request is {len(text)} bytes, more than 4096")
            ask = json.loads(text or "null")
            if not isinstance(ask, dict) or not {"storey", "skill", "x", "y"} <= set(ask):
                raise ValueError('send {"storey": KEY, "skill": NAME, "x": METRES, "y": METRES}')
            storey, skill, x, y = ask["storey"], ask["skill"], ask["x"], ask["y"]
            if not (isinstance(storey, str) and isinstance(skill, str)):
                raise ValueError(f"storey and skill must be strings, got {storey!r} and {skill!r}")
            if (
                isinstance(x, bool)
                or isinstance(y, bool)
                or not isinstance(x, int | float)
                or not isinstance(y, int | float)
            ):
                raise ValueError(f"x and y must be numbers of metres, got {x!r} and {y!r}")
        except (ValueError, UnicodeDecodeError) as err:
            query.reply_err(Reply.error(f"Explain: {err}.").to_json(), encoding=JSON)
            query.drop()
            return

        def send(r: Reply) -> None:
            try:
                if r.ok:
                    query.reply(self.keys.explain, r.to_json(), encoding=JSON)
                else:
                    query.reply_err(r.to_json(), encoding=JSON)
            finally:
                query.drop()

        self.service.submit_explain(
            storey,
            skill,
            float(x),
            float(y),
            lambda r: self.outbox.put(lambda: self.site.put(lambda: send(r))),
        )

    def _on_status(self, query: zenoh.Query) -> None:
        """Always answered, whatever the store's state (its ``store`` field says it)."""
        try:
            status = self.service.status()
            status["maps"] = self.maps.versions()  # the latest versions, updates included
            for source in self.status_sources:
                status.update(source())
        except Exception as err:  # a bug must cost this answer its content, never the answer
            log.exception("Could not make the status")
            query.reply_err(
                Reply.error(f"Internal error ({type(err).__name__}): {err}").to_json(), encoding=JSON
            )
            return
        query.reply(self.keys.status, json.dumps(status).encode(), encoding=JSON)

    # --- lifecycle ----------------------------------------------------------------------------------
    def close(self, timeout_s: float = 30.0) -> None:
        """Let no new request in and wait (up to ``timeout_s``) for the callbacks running, send what is
        queued, then undeclare everything (the session stays open; its owner closes it)."""
        if running := self.gate.close(timeout_s):
            log.error("%d Zenoh callback(s) still running after %.1f s", running, timeout_s)
        self.outbox.close()
        self.site.close()
        outs = list(self._outs.values())
        self._outs.clear()
        for out in outs:
            out.latched.undeclare()
            out.updates.undeclare()
        for entity in self._declared:
            try:
                entity.undeclare()
            except Exception:  # already gone with the session
                log.debug("Undeclaring %s failed", entity, exc_info=True)
        self._declared.clear()
        self.maps.clear()


def _log_reply(what: str) -> Any:
    def reply(r: Reply) -> None:
        if r.ok:
            log.info("Accepted %s: revision %s", what, r.body.get("revision"))
        else:
            log.warning("Refused %s: %s", what, r.body.get("error"))

    return reply
