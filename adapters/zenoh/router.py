"""A Zenoh router for many daemons, and an in-memory storage that keeps their latest maps and clouds.

Several daemons (one per site, or per storey group) join one network through a router; robots connect
to the router and reach every site under its own key prefix. The router can keep the latest map of
every site (``MapStorage`` on ``twin/*/map/**``: the full maps with the updates applied) and the latest
cloud of every points skill (``MapStorage`` on ``twin/*/points/**``: clouds have no updates): a robot
that starts while a daemon restarts still gets them (its ``get`` or ``MapWatcher`` is answered by the
storage; the daemon's own answers win once it is back, being newer). A map or cloud the daemon deletes
(a removed skill) is forgotten.

Example::

    with open_router(cfg.section(ZenohSettings), listen=["tcp/127.0.0.1:7447"]) as session:
        maps, clouds = MapStorage(session, "twin/*/map/**"), MapStorage(session, "twin/*/points/**")
        ...
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import zenoh

from adapters.ros import decode_occupancy_grid, decode_occupancy_grid_update, encode_occupancy_grid
from adapters.ros.cdr import OCCUPANCY_GRID, _typestore
from adapters.zenoh.errors import TransportError
from adapters.zenoh.session import session_config
from adapters.zenoh.settings import ZenohSettings
from twin.maps.grid import OccupancyGrid

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


@dataclass(slots=True)
class _Stored:
    payload: bytes | None  # None: re-encode ``grid`` (an update was applied since)
    encoding: zenoh.Encoding
    attachment: bytes | None
    timestamp: Any
    version: int | None = None  # from the attachment {"revision": R, "version": V}
    grid: OccupancyGrid | None = None
    frame_id: str = "map"
    stamp_ns: int = 0


class MapStorage:
    """The latest version of every map under ``key_expr`` (``<prefix>/map/**``), answering queries on
    them: each full map as it was published, with the daemon's updates (``<prefix>/map_updates/**``)
    applied in version order, so that it stays the current map between the daemon's keyframes; after
    a gap (an update missed) it waits for the next full map. On ``<prefix>/points/**`` (or any other
    key expression) it keeps each key's latest sample as published (a cloud is always sent whole).
    A deleted key is forgotten."""

    def __init__(self, session: zenoh.Session, key_expr: str) -> None:
        self.key_expr = key_expr
        self._lock = threading.Lock()
        self._latest: dict[str, _Stored] = {}
        self._sub = session.declare_subscriber(key_expr, self._on_sample)
        self._updates = None
        if key_expr.endswith("/map/**"):
            updates = key_expr.removesuffix("/map/**") + "/map_updates/**"
            self._updates = session.declare_subscriber(updates, self._on_update)
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
                sample.payload.to_bytes(), sample.encoding, attachment, sample.timestamp, _version(attachment)
            )

    def _on_update(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr).replace("/map_updates/", "/map/", 1)
        attachment = sample.attachment.to_bytes() if sample.attachment is not None else None
        version = _version(attachment)
        try:
            window, cells, stamp_ns = decode_occupancy_grid_update(sample.payload.to_bytes())
            with self._lock:
                stored = self._latest.get(key)
                if (
                    stored is None
                    or version is None
                    or stored.version is None
                    or version != stored.version + 1
                ):
                    return  # not held, or a gap: the next full map brings it back
                if stored.grid is None:
                    assert stored.payload is not None
                    stored.grid, _ = decode_occupancy_grid(stored.payload)
                    stored.frame_id = (
                        _typestore().deserialize_cdr(stored.payload, OCCUPANCY_GRID).header.frame_id
                    )
                stored.grid.data[window.row0 : window.row1, window.col0 : window.col1] = cells
                stored.payload, stored.attachment, stored.version = None, attachment, version
                stored.stamp_ns, stored.timestamp = stamp_ns, sample.timestamp or stored.timestamp
        except Exception as err:  # a malformed update must not stop the storage
            log.warning("The map storage could not apply an update on %s: %s", sample.key_expr, err)

    def _on_query(self, query: zenoh.Query) -> None:
        wanted = zenoh.KeyExpr(str(query.key_expr))
        with self._lock:
            hits = []
            for k, v in self._latest.items():
                if wanted.intersects(zenoh.KeyExpr(k)):
                    if v.payload is None and v.grid is not None:
                        v.payload = encode_occupancy_grid(v.grid, stamp_ns=v.stamp_ns, frame_id=v.frame_id)
                    hits.append((k, v))
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
        if self._updates is not None:
            self._updates.undeclare()


def _version(attachment: bytes | None) -> int | None:
    """The map version in a sample's attachment ``{"revision": R, "version": V}`` (None: none)."""
    try:
        version = json.loads(attachment or b"null")["version"]
    except (ValueError, TypeError, KeyError):
        return None
    return version if isinstance(version, int) else None
