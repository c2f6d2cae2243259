"""Zenoh session configuration: the daemon's and robots' sessions from the ``[zenoh]`` table.

Safe defaults: multicast scouting off (nothing is announced on the network's interfaces), shared
memory off (no files left in ``/dev/shm``), timestamping on (the advanced publishers that latch maps
need it). A zenoh JSON5 file (``config_file``) is read first and the explicit settings override it.

Security, from ``[zenoh.tls]`` and ``[zenoh.auth]``: TLS certificates for ``tls/...`` endpoints
(mutual TLS with ``mutual = true``), user/password authentication (a user to connect as, a users
file to check others against), and an ``access_control`` section (``adapters.zenoh.access``).

Example::

    with zenoh.open(session_config(cfg.section(ZenohSettings), listen=["tcp/127.0.0.1:7447"])) as session:
        ...
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import zenoh

from adapters.zenoh.errors import TransportError
from adapters.zenoh.settings import ZenohMode, ZenohSettings


def session_config(
    settings: ZenohSettings,
    *,
    mode: ZenohMode | None = None,
    listen: Sequence[str] | None = None,
    connect: Sequence[str] | None = None,
    access_control: Mapping[str, object] | None = None,
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
        **_security(settings),
    }
    if access_control is not None:
        values["access_control"] = dict(access_control)
    for key, value in values.items():
        try:
            conf.insert_json5(key, json.dumps(value))
        except Exception as err:
            msg = f"Invalid zenoh setting {key} = {value!r}: {err}"
            raise TransportError(msg) from err
    return conf


def _file(path: Path, what: str) -> str:
    if not path.is_file():
        msg = f"The {what} {path} does not exist."
        raise TransportError(msg)
    return str(path.resolve())


def _security(settings: ZenohSettings) -> dict[str, object]:
    """zenoh's TLS and user/password settings from ``[zenoh.tls]`` and ``[zenoh.auth]``."""
    out: dict[str, object] = {}
    tls, auth = settings.tls, settings.auth
    link = "transport/link/tls"
    if tls.root_ca is not None:
        out[f"{link}/root_ca_certificate"] = _file(tls.root_ca, "certificate authority (zenoh.tls.root_ca)")
    if tls.certificate is not None and tls.private_key is not None:
        cert = _file(tls.certificate, "certificate (zenoh.tls.certificate)")
        key = _file(tls.private_key, "private key (zenoh.tls.private_key)")
        out |= {
            f"{link}/listen_certificate": cert,
            f"{link}/listen_private_key": key,
            f"{link}/connect_certificate": cert,
            f"{link}/connect_private_key": key,
        }
    if tls.mutual:
        out[f"{link}/enable_mtls"] = True
    if not tls.verify_name:
        out[f"{link}/verify_name_on_connect"] = False
    if auth.user is not None and auth.password_file is not None:
        password = Path(_file(auth.password_file, "password file (zenoh.auth.password_file)")).read_text()
        out["transport/auth/usrpwd/user"] = auth.user
        out["transport/auth/usrpwd/password"] = password.strip()
    if auth.users_file is not None:
        out["transport/auth/usrpwd/dictionary_file"] = _file(
            auth.users_file, "users file (zenoh.auth.users_file)"
        )
    return out


def client_config(
    connect: Sequence[str],
    *,
    settings: ZenohSettings | None = None,
    mode: ZenohMode = "peer",
    listen: Sequence[str] = (),
) -> zenoh.Config:
    """A robot's session: connect to ``connect`` (the daemon or a router), listen nowhere by default;
    a lost link is retried every second at most.

    With a TLS certificate of its own, the robot presents it (zenoh sends a client certificate only
    with ``enable_mtls``), so that a daemon with ``mutual = true`` knows it by its common name.
    """
    settings = settings or ZenohSettings()
    if settings.tls.certificate is not None and not settings.tls.mutual:
        settings = settings.model_copy(update={"tls": settings.tls.model_copy(update={"mutual": True})})
    conf = session_config(settings, mode=mode, listen=list(listen), connect=list(connect))
    retry = {"period_init_ms": 250, "period_max_ms": 1000, "period_increase_factor": 2}
    conf.insert_json5("connect/retry", json.dumps(retry))  # find a restarted daemon within a second
    return conf
