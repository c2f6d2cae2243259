"""Route graphs on Zenoh: ``<prefix>/routes/<skill>``, the JSON of each routes skill's graph, latched.

Each graph goes out from a ``zenoh.ext`` AdvancedPublisher with a cache of one sample and publisher
detection, so an AdvancedSubscriber with late-publisher detection (a fleet manager that starts later)
gets the current graph at once; a plain ``get`` on ``<prefix>/routes/**`` (or one skill's key) is
answered by a queryable with every current graph it names. The payload is
:meth:`twin.routes.graph.RouteGraph.to_json` with ``"version"`` (1, 2, ... per skill), encoded
``application/json``. A graph is replaced whole when it is published again.

Example::

    routes = ZenohRoutes(session, prefix="twin/lab")
    routes.publish("cleaners", graph.to_json())
    ...
    routes.close()
"""

from __future__ import annotations

import json
import logging
import threading
from typing import Any

import zenoh
import zenoh.ext

log = logging.getLogger(__name__)

JSON = zenoh.Encoding.APPLICATION_JSON


def routes_key(prefix: str, skill: str) -> str:
    return f"{prefix}/routes/{skill}"


class ZenohRoutes:
    """The latched route graphs of a site and the queryable that answers ``get`` with them."""

    def __init__(self, session: zenoh.Session, *, prefix: str) -> None:
        self.session = session
        self.prefix = prefix
        self._lock = threading.Lock()
        self._graphs: dict[str, bytes] = {}
        self._versions: dict[str, int] = {}
        self._publishers: dict[str, Any] = {}
        self._queryable = session.declare_queryable(f"{prefix}/routes/**", self._on_get)

    def publish(self, skill: str, graph: dict[str, Any]) -> int:
        """Publish ``graph`` (JSON-ready) as the current graph of ``skill``; returns its version."""
        key = routes_key(self.prefix, skill)
        with self._lock:
            version = self._versions.get(skill, 0) + 1
            payload = json.dumps({**graph, "version": version}, separators=(",", ":")).encode()
            publisher = self._publishers.get(skill)
            if publisher is None:
                publisher = self._publishers[skill] = zenoh.ext.declare_advanced_publisher(
                    self.session,
                    key,
                    encoding=JSON,
                    congestion_control=zenoh.CongestionControl.BLOCK,
                    reliability=zenoh.Reliability.RELIABLE,
                    cache=zenoh.ext.CacheConfig(max_samples=1),
                    publisher_detection=True,
                )
            self._graphs[skill] = payload
            self._versions[skill] = version
            publisher.put(payload)
        return version

    def version(self, skill: str) -> int:
        """The version of ``skill``'s current graph (0: none published)."""
        with self._lock:
            return self._versions.get(skill, 0)

    def _on_get(self, query: zenoh.Query) -> None:  # a Zenoh thread; the reply is small and ready
        try:
            with self._lock:
                current = list(self._graphs.items())
            for skill, payload in current:
                key = routes_key(self.prefix, skill)
                if query.key_expr.intersects(zenoh.KeyExpr(key)):
                    query.reply(key, payload, encoding=JSON)
        finally:
            query.drop()

    def close(self) -> None:
        for entity in (self._queryable, *self._publishers.values()):
            try:
                entity.undeclare()
            except Exception:
                log.debug("undeclare of a routes entity failed", exc_info=True)
