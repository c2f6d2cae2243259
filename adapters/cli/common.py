"""What every ``twin`` command shares: the store a command works on, and readable sizes."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from adapters.cli.args import SITE_HELP as SITE_HELP  # noqa: PLC0414 (re-exported for the commands)
from adapters.cli.args import add_client_args as add_client_args  # noqa: PLC0414
from adapters.cli.args import add_store_args as add_store_args  # noqa: PLC0414
from adapters.sparql.remote_store import RemoteStore
from adapters.sparql.settings import RemoteStoreSettings, remote_store_settings
from adapters.zenoh.client import TwinClient
from adapters.zenoh.settings import ZenohSettings
from twin.config import Config
from twin.config.tables import NAME_PATTERN
from twin.errors import ConfigError
from twin.graph import vocab
from twin.graph.rdf import literal_value
from twin.graph.store import EmbeddedStore, GraphStore

AnyStore = EmbeddedStore | RemoteStore


def store_path_of(args: argparse.Namespace, cfg: Config) -> Path:
    """The store directory a command works on: ``--store`` if given, else the configuration's."""
    store = getattr(args, "store", None)
    return Path(store) if store else cfg.store_path


def zenoh_of(cfg: Config) -> ZenohSettings:
    """The ``[zenoh]`` table."""
    return cfg.section(ZenohSettings)


def check_site(site: str, option: str = "--site") -> str:
    """``site`` if it is a site name (1-64 of ``A-Z a-z 0-9 _ -``: it is a key chunk and part of IRIs),
    else ConfigError naming it and a name that would do."""
    from twin.graph.vocab import site_slug

    if re.fullmatch(NAME_PATTERN, site):
        return site
    msg = (
        f"{option} {site!r} is not a site name: 1-64 of A-Z a-z 0-9 _ - (it is the key prefix "
        f"twin/<site> and part of every IRI); e.g. {site_slug(site) or 'lab'!r}."
    )
    raise ConfigError(msg)


def key_prefix(cfg: Config, site: str | None = None) -> str:
    """The Zenoh key prefix of ``site`` (default: the configured one), e.g. ``twin/lab``."""
    return zenoh_of(cfg).key_prefix(check_site(site) if site else cfg.site)


def remote_store_of(args: argparse.Namespace, cfg: Config) -> RemoteStoreSettings | None:
    """The SPARQL server a command works on, if any: ``--store-url``, else ``[store] url`` unless
    ``--store DIR`` names an embedded store."""
    url = getattr(args, "store_url", None)
    if url:
        return cfg.section(RemoteStoreSettings).model_copy(update={"url": url})
    if getattr(args, "store", None):
        return None
    return remote_store_settings(cfg)


def store_label(args: argparse.Namespace, cfg: Config) -> str:
    """Where the command's store is, for messages: the server's URL or the directory."""
    remote = remote_store_of(args, cfg)
    return remote.url if remote is not None else str(store_path_of(args, cfg))


def store_exists(args: argparse.Namespace, cfg: Config) -> bool:
    """Whether there is a store to look into without creating one (a server always is one)."""
    return remote_store_of(args, cfg) is not None or store_path_of(args, cfg).exists()


def open_store(
    args: argparse.Namespace, cfg: Config, *, read_only: bool = False, create: bool = True
) -> AnyStore:
    """Open the command's store: a :class:`RemoteStore` on a SPARQL server, else the embedded one."""
    remote = remote_store_of(args, cfg)
    if remote is not None:
        return RemoteStore.open(
            remote.url,
            query=remote.query_endpoint,
            update=remote.update_endpoint,
            graph_store=remote.graph_store_endpoint,
            timeout_s=remote.timeout_s,
            read_only=read_only,
        )
    return EmbeddedStore.open(store_path_of(args, cfg), read_only=read_only, create=create)


_SITE_CHARS = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-")


def stored_site(store: GraphStore) -> str | None:
    """The site name the store's model was imported as (its ``twin:Model``'s label), or None."""
    rows = store.select(
        f"SELECT ?site WHERE {{ ?m a <{vocab.TWIN_MODEL}> ; <{vocab.RDFS_LABEL}> ?site }} LIMIT 1"
    )
    site = str(literal_value(rows[0]["site"]) or "") if rows else ""
    ok = 0 < len(site) <= vocab.SITE_SLUG_MAX and set(site) <= _SITE_CHARS
    return site if ok else None


def client_prefix(args: argparse.Namespace, cfg: Config) -> str | None:
    """The key prefix a client command talks to: of ``--site`` or of a configured ``site.name``;
    None (no site given): the client talks to the one daemon alive, whatever its site."""
    site = getattr(args, "site", None)
    return key_prefix(cfg, site) if site or cfg.site_set else None


def client_endpoints(args: argparse.Namespace, cfg: Config) -> list[str]:
    """Where a client command connects: ``--connect``, else ``[zenoh] connect``, else ``[zenoh] listen``
    (the daemon's own endpoint on this machine)."""
    zenoh = zenoh_of(cfg)
    return list(getattr(args, "connect", None) or zenoh.connect or zenoh.listen)


def open_client(args: argparse.Namespace, cfg: Config, *, prefix: str | None = None) -> TwinClient:
    """A :class:`TwinClient` as the command's options and the ``[zenoh]`` table say (mode, TLS,
    authentication, prefix); the site of ``--site``/``site.name``, else of the one daemon alive."""
    return TwinClient.connect(
        client_endpoints(args, cfg),
        prefix=prefix if prefix is not None else client_prefix(args, cfg),
        timeout_s=args.timeout,
        settings=zenoh_of(cfg),
        mode=getattr(args, "mode", None),
    )


def human_size(n: int) -> str:
    """``1234567`` -> ``"1.2 MB"``."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:,.1f} {unit}"
    return f"{n} B"
