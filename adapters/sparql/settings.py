"""The remote store's keys of ``[store]``: a SPARQL 1.1 server holding the graph instead of the
embedded store. The SPARQL adapter owns these keys; ``path`` and ``flush_every_s`` stay the core's.

Example::

    remote = remote_store_settings(cfg)   # None: the embedded store
"""

from __future__ import annotations

import re
from typing import Annotated

from pydantic import Field

from twin.config import Config, ConfigSection
from twin.config.base import Number, Text, check

_URL = re.compile(r"^https?://[^/?#\s]+")

ServerUrl = Annotated[
    Text,
    check(
        lambda v: isinstance(v, str) and (not v or bool(_URL.match(v))),
        '"" or an http(s):// URL of a SPARQL server',
    ),
]


class RemoteStoreSettings(ConfigSection):
    """``[store] url`` and the rest: a SPARQL 1.1 server (Protocol and Graph Store Protocol).

    The endpoints are paths under ``url`` (``""``: ``url`` itself) or absolute URLs; the defaults are
    Oxigraph's (``oxigraph serve``). ``timeout_s`` bounds every socket operation of every request.
    """

    table = "store"

    url: ServerUrl = Field("", description='A SPARQL 1.1 server holding the graph; "" = the embedded store.')
    query_endpoint: Text = Field("query", description="Path under url, or an absolute URL.")
    update_endpoint: Text = "update"
    graph_store_endpoint: Text = "store"
    timeout_s: Annotated[Number, Field(gt=0.0)] = Field(
        30.0, description="Every socket operation of every request to the server, seconds."
    )


def remote_store_settings(cfg: Config) -> RemoteStoreSettings | None:
    """The configured SPARQL server, or None for the embedded store (``url = ""``)."""
    settings = cfg.section(RemoteStoreSettings)
    return settings if settings.url else None
