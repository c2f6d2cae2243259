"""The daemon's Zenoh side: binds a :class:`twin.live.TwinService` to a session.

Declares, under the site's prefix (see :class:`~adapters.zenoh.keys.SiteKeys`):

- per map, an advanced publisher on ``map/<storey>/<skill>`` (cache of one, publisher detection:
  latched) and a publisher on ``map_updates/<storey>/<skill>``; both reliable, congestion BLOCK;
  samples carry the attachment ``{"revision": R, "version": V}`` (JSON);
- a queryable on ``map/**`` answering ``get`` with the latest full maps (CDR ``OccupancyGrid``);
- a subscriber on ``observations/*`` (best effort: errors are logged) and a queryable on
  ``observe/*`` (the JSON ack once the change is durable, or ``reply_err`` with the error);
- a subscriber on ``skills/*`` (put a JSON profile, delete to remove) and a queryable listing them;
- queryables ``sparql`` (read-only) and ``status``; the liveliness token ``daemon``.

Zenoh callbacks only enqueue work for the service's thread or read immutable snapshots. What the
service's thread sends (map samples, acks) goes through the :class:`~adapters.zenoh.outbox.Outbox`, in
order, so the writer never waits for Zenoh.

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
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh

from adapters.ros import encode_occupancy_grid, encode_update_cells
from adapters.zenoh.keys import SiteKeys
from adapters.zenoh.latched import CDR, declare_latched_publisher
from adapters.zenoh.outbox import Outbox
from twin.errors import TwinError
from twin.events import MapPublished, MapRemoved, MapUpdated, TwinEvent
from twin.live import Reply, TwinService

log = logging.getLogger(__name__)

JSON = zenoh.Encoding.APPLICATION_JSON


def revision_attachment(revision: int, version: int) -> bytes:
    """The attachment of every map sample: JSON ``{"revision": R, "version": V}``."""
    return json.dumps({"revision": revision, "version": version}).encode()


@dataclass(slots=True)
class _MapOut:
    latched: Any  # zenoh.ext.AdvancedPublisher
    updates: zenoh.Publisher
    full: bytes  # the CDR of the last full map published
    revision: int
    version: int


class ZenohDaemon:
    """Publishes the service's maps and feeds it the robots' requests. A :class:`~twin.events.TwinSink`."""

    def __init__(
        self, session: zenoh.Session, service: TwinService, *, keys: SiteKeys, frame_id: str
    ) -> None:
        self.session = session
        self.service = service
        self.keys = keys
        self.frame_id = frame_id
        self._maps: dict[tuple[str, str], _MapOut] = {}
        self._lock = threading.Lock()
        self.outbox = Outbox("twin-zenoh-out")
        self.status_sources: list[Callable[[], dict[str, object]]] = []
        """More sections of the status reply (e.g. the ROS robots' storeys), merged over the service's."""
        self._declared: list[Any] = [
            session.liveliness().declare_token(keys.daemon),
            session.declare_subscriber(keys.all_observations, self._on_observation),
            session.declare_queryable(keys.all_observe, self._on_observe),
            session.declare_subscriber(keys.skills, self._on_skill),
            session.declare_queryable(keys.skills_listing, self._on_list_skills),
            session.declare_queryable(keys.maps, self._on_get_map),
            session.declare_queryable(keys.sparql, self._on_sparql),
            session.declare_queryable(keys.status, self._on_status),
            session.declare_queryable(keys.explain, self._on_explain),
        ]

    # --- sink ---------------------------------------------------------------------------------------
    def emit(self, event: TwinEvent) -> None:
        if isinstance(event, MapPublished | MapUpdated | MapRemoved):
            self.outbox.put(lambda: self._send(event))

    def drain(self) -> None:
        """Wait until every map sample and reply queued so far was sent."""
        self.outbox.drain()

    def _send(self, event: TwinEvent) -> None:
        if isinstance(event, MapPublished):
            self._publish(event)
        elif isinstance(event, MapUpdated):
            self._update(event)
        elif isinstance(event, MapRemoved):
            self._remove(event.storey, event.skill)

    def _publish(self, event: MapPublished) -> None:
        grid = event.grid
        key = (grid.storey, grid.skill)
        payload = encode_occupancy_grid(grid, stamp_ns=event.stamp_ns, frame_id=self.frame_id)
        out = self._maps.get(key)
        if out is None:
            latched = declare_latched_publisher(self.session, self.keys.map(*key))
            updates = self.session.declare_publisher(
                self.keys.map_updates(*key),
                encoding=CDR,
                congestion_control=zenoh.CongestionControl.BLOCK,
                reliability=zenoh.Reliability.RELIABLE,
            )
            out = _MapOut(latched, updates, payload, event.revision, event.version)
        else:
            out.full, out.revision, out.version = payload, event.revision, event.version
        with self._lock:
            self._maps[key] = out
        out.latched.put(payload, attachment=revision_attachment(event.revision, event.version))

    def _update(self, event: MapUpdated) -> None:
        out = self._maps.get((event.storey, event.skill))
        if out is None:
            log.warning("An update of %s/%s came before its map: ignored", event.storey, event.skill)
            return
        payload = encode_update_cells(
            event.frame, event.window, event.data, stamp_ns=event.stamp_ns, frame_id=self.frame_id
        )
        out.updates.put(payload, attachment=revision_attachment(event.revision, event.version))

    def _remove(self, storey: str, skill: str) -> None:
        with self._lock:
            out = self._maps.pop((storey, skill), None)
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
        robot = self.keys.robot_of(str(query.key_expr))
        payload = query.payload.to_bytes() if query.payload is not None else b""
        key = str(query.key_expr)

        def send(r: Reply) -> None:
            try:
                if r.ok:
                    query.reply(key, r.to_json(), encoding=JSON)
                else:
                    query.reply_err(r.to_json(), encoding=JSON)
            finally:
                query.drop()  # finalise now: the robot's get returns at once, not when Python frees it

        def reply(r: Reply) -> None:  # on the writer's thread: after the map updates, off the thread
            self.outbox.put(lambda: send(r))

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
        with self._lock:
            maps = list(self._maps.items())
        for (storey, skill), out in maps:
            key = self.keys.map(storey, skill)
            if zenoh.KeyExpr(key).intersects(query.key_expr):
                query.reply(
                    key, out.full, encoding=CDR, attachment=revision_attachment(out.revision, out.version)
                )

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
            storey, skill, float(x), float(y), lambda r: self.outbox.put(lambda: send(r))
        )

    def _on_status(self, query: zenoh.Query) -> None:
        status = self.service.status()
        for source in self.status_sources:
            status.update(source())
        query.reply(self.keys.status, json.dumps(status).encode(), encoding=JSON)

    # --- lifecycle ----------------------------------------------------------------------------------
    def close(self) -> None:
        """Send what is queued, then undeclare everything (the session stays open; its owner closes it)."""
        self.outbox.close()
        with self._lock:
            maps = list(self._maps.values())
            self._maps.clear()
        for out in maps:
            out.latched.undeclare()
            out.updates.undeclare()
        for entity in self._declared:
            try:
                entity.undeclare()
            except Exception:  # already gone with the session
                log.debug("Undeclaring %s failed", entity, exc_info=True)
        self._declared.clear()


def _log_reply(what: str) -> Any:
    def reply(r: Reply) -> None:
        if r.ok:
            log.info("Accepted %s: revision %s", what, r.body.get("revision"))
        else:
            log.warning("Refused %s: %s", what, r.body.get("error"))

    return reply
