"""Zenoh session configuration: the daemon's and robots' sessions from the ``[zenoh]`` table.

Safe defaults: multicast scouting off (nothing is announced on the network's interfaces), shared
memory off (no files left in ``/dev/shm``), timestamping on (the advanced publishers that latch maps
need it). A zenoh JSON5 file (``config_file``; e.g. with TLS or access control) is read first and
the explicit settings override it.

Example::

    with zenoh.open(session_config(cfg.zenoh, listen=["tcp/127.0.0.1:7447"])) as session:
        ...
"""

from __future__ import annotations

import json
from collections.abc import Sequence

import zenoh

from adapters.zenoh.errors import TransportError
from twin.config import ZenohConfig, ZenohMode


def session_config(
    settings: ZenohConfig,
    *,
    mode: ZenohMode | None = None,
    listen: Sequence[str] | None = None,
    connect: Sequence[str] | None = None,
) -> zenoh.Config:
    """A zenoh configuration from ``settings``; ``mode``, ``listen`` and ``connect`` override them."""
    try:
        conf = zenoh.Config.from_file(str(settings.config_file)) if settings.config_file else zenoh.Config()
    except Exception as err:  # zenoh raises ZError for a bad file
        msg = f"Cannot read the zenoh configuration file {settings.config_file}: {err}"
        raise TransportError(msg) from err
    values: dict[str, object] = {
        "mode": mode or settings.mode,
        "scouting/multicast/enabled": settings.multicast_scouting,
        "transport/shared_memory/enabled": settings.shared_memory,
        "timestamping/enabled": True,
        "listen/endpoints": list(settings.listen if listen is None else listen),
        "connect/endpoints": list(settings.connect if connect is None else connect),
    }
    for key, value in values.items():
        try:
            conf.insert_json5(key, json.dumps(value))
        except Exception as err:
            msg = f"Invalid zenoh setting {key} = {value!r}: {err}"
            raise TransportError(msg) from err
    return conf


def client_config(
    connect: Sequence[str],
    *,
    settings: ZenohConfig | None = None,
    mode: ZenohMode = "peer",
    listen: Sequence[str] = (),
) -> zenoh.Config:
    """A robot's session: connect to ``connect`` (the daemon or a router), listen nowhere by default."""
    return session_config(settings or ZenohConfig(), mode=mode, listen=list(listen), connect=list(connect))
