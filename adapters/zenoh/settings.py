"""``[zenoh]``: where the daemon meets robots, and its security (``[zenoh.tls]``, ``[zenoh.auth]``,
``[zenoh.access]``). The zenoh adapter owns this table; the core never reads it.

Example::

    zenoh = cfg.section(ZenohSettings)
    with zenoh_open(session_config(zenoh)) as session:
        keys = SiteKeys(zenoh.key_prefix(cfg.site))
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from twin.config import ConfigSection, ConfigTable
from twin.config.base import Flag, OptionalPath, OptionalText, Text, check, list_of
from twin.config.tables import NAME_PATTERN

ZenohMode = Literal["peer", "client", "router"]
Identity = Literal["username", "certificate"]

Endpoint = Annotated[
    Text, check(lambda v: isinstance(v, str) and "/" in v, 'an endpoint such as "tcp/127.0.0.1:7447"')
]
Endpoints = Annotated[tuple[Endpoint, ...], list_of('endpoints such as "tcp/127.0.0.1:7447"')]
KeyPrefix = Annotated[
    Text,
    check(
        lambda v: isinstance(v, str) and bool(v.strip("/")) and not any(c in v for c in "*$?#"),
        "a key expression without wildcards",
    ),
]


class TlsSettings(ConfigTable):
    """``[zenoh.tls]``: TLS on ``tls/...`` endpoints: this side's certificate and key, and the
    authority both trust. ``mutual`` makes a listener require client certificates (mTLS)."""

    root_ca: OptionalPath = Field(None, description="The certificate authority both sides trust.")
    certificate: OptionalPath = Field(None, description="This side's certificate (with private_key).")
    private_key: OptionalPath = None
    mutual: Flag = Field(False, description="Require the robots' certificates (mutual TLS).")
    verify_name: Flag = True

    @model_validator(mode="after")
    def _pair(self) -> TlsSettings:
        if (self.certificate is None) != (self.private_key is None):
            msg = "needs both 'certificate' and 'private_key', or neither"
            raise ValueError(msg)
        return self


class AuthSettings(ConfigTable):
    """``[zenoh.auth]``: user/password authentication: ``user`` and ``password_file`` to connect as
    someone, ``users_file`` (``name:password`` lines) to check who connects."""

    user: OptionalText = None
    password_file: OptionalPath = None
    users_file: OptionalPath = Field(None, description="name:password lines: who may connect to this side.")

    @model_validator(mode="after")
    def _pair(self) -> AuthSettings:
        if (self.user is None) != (self.password_file is None):
            msg = "needs both 'user' and 'password_file', or neither"
            raise ValueError(msg)
        return self


class AccessSettings(ConfigTable):
    """``[zenoh.access]``: access control generated from the configured robots
    (:mod:`adapters.zenoh.access`)."""

    enabled: Flag = False
    identity: Identity = Field(
        "username", description='"certificate": the common name of the robot\'s TLS certificate.'
    )
    operators: Annotated[
        tuple[Annotated[Text, Field(pattern=NAME_PATTERN)], ...], list_of("names of [A-Za-z0-9_-]")
    ] = Field((), description="Who may also change skills.")


class ZenohSettings(ConfigSection):
    """``[zenoh]``: where the daemon meets robots. ``prefix`` has ``{site}`` replaced
    (:meth:`key_prefix`)."""

    table = "zenoh"

    prefix: KeyPrefix = Field("twin/{site}", description='Key expressions live under "<prefix>/".')
    mode: ZenohMode = "peer"
    listen: Endpoints = ("tcp/127.0.0.1:7447",)
    connect: Endpoints = ()
    multicast_scouting: Flag = Field(False, description="Announce the daemon on every network interface.")
    shared_memory: Flag = False
    config_file: OptionalPath = Field(
        None, description="A zenoh JSON5 configuration file that these keys override."
    )
    tls: TlsSettings = TlsSettings()
    auth: AuthSettings = AuthSettings()
    access: AccessSettings = AccessSettings()

    def key_prefix(self, site: str) -> str:
        """The key prefix of ``site``, e.g. ``twin/lab``."""
        return self.prefix.replace("{site}", site).strip("/")
