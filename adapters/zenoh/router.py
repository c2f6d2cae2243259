"""A Zenoh router for many daemons, and an in-memory storage that keeps their latest maps.

Several daemons (one per site, or per storey group) join one network through a router; robots connect
to the router and reach every site under its own key prefix. The router can keep the latest full map
of every site (``MapStorage``): a robot that starts while a daemon restarts still gets the map (its
``get`` or ``MapWatcher`` is answered by the storage; the daemon's own answers win once it is back,
being newer).

Example::

    with open_router(cfg.section(ZenohSettings), listen=["tcp/127.0.0.1:7447"]) as session:
        storage = MapStorage(session, "twin/*/map/**")
        ...
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import zenoh

from adapters.zenoh.errors import TransportError
from adapters.zenoh.session import session_config
from adapters.zenoh.settings import ZenohSettings

log = logging.getLogger(__name__)


def open_router(
    settings: ZenohSettings,
    *,
    listen: Sequence[str] | None = None,
    connect: Sequence[str] | None = None,
    access_control: Mapping[str, object] | None = None,
) -> zenoh.Session:
    """A router-mode session (TLS, authentication and access control from ``settings`` as usual)."""
    conf = session_config(
        settings, mode="router", listen=listen, connect=connect, access_control=access_control
    )
    try:
        return zenoh.open(conf)
    except Exception as err:
        endpoints = ", ".join(listen or settings.listen)
        msg = f"Cannot open the Zenoh router (listening on {endpoints}): {err}"
        raise TransportError(msg) from err


@dataclass(frozen=True, slots=True)
class _Stored:
    payload: bytes
    encoding: zenoh.Encoding
    attachment: bytes | None
    timestamp: Any


class MapStorage:
    """The latest sample of every key under ``key_expr`` (full maps), answering queries on them."""

    def __init__(self, session: zenoh.Session, key_expr: str) -> None:
        self.key_expr = key_expr
        self._lock = threading.Lock()
        self._latest: dict[str, _Stored] = {}
        self._sub = session.declare_subscriber(key_expr, self._on_sample)
        self._queryable = session.declare_queryable(key_expr, self._on_query, complete=False)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        if "@" in key:
            return
        with self._lock:
            if sample.kind == zenoh.SampleKind.DELETE:
                self._latest.pop(key, None)
                return
            attachment = sample.attachment.to_bytes() if sample.attachment is not None else None
            self._latest[key] = _Stored(
                sample.payload.to_bytes(), sample.encoding, attachment, sample.timestamp
            )

    def _on_query(self, query: zenoh.Query) -> None:
        wanted = zenoh.KeyExpr(str(query.key_expr))
        with self._lock:
            hits = [(k, v) for k, v in self._latest.items() if wanted.intersects(zenoh.KeyExpr(k))]
        for key, stored in hits:
            try:
                query.reply(
                    key,
                    stored.payload,
                    encoding=stored.encoding,
                    attachment=stored.attachment,
                    timestamp=stored.timestamp,
                )
            except Exception as err:  # a querier that went away
                log.debug("storage reply on %s failed: %s", key, err)

    def keys(self) -> list[str]:
        with self._lock:
            return sorted(self._latest)

    def close(self) -> None:
        self._queryable.undeclare()
        self._sub.undeclare()
