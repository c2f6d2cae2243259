"""``twin acl`` and ``twin router``: the Zenoh network around daemons (access control, routers)."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from typing import Any

from adapters.cli.common import (
    add_store_args,
    key_prefix,
    open_store,
    store_exists,
    store_label,
    stored_site,
    zenoh_of,
)
from adapters.zenoh.access import access_summary, site_access_control, site_acl
from adapters.zenoh.keys import SiteKeys
from adapters.zenoh.router import MapStorage, open_router
from twin.config import Config
from twin.errors import ConfigError


def guarded_site(args: argparse.Namespace, cfg: Config, command: str) -> str:
    """The site whose keys access control guards: ``--site``, else ``site.name``, else the site the store
    was imported as (``--store``, else ``store.path``); ConfigError when none of them names one (a
    guess would guard another site's keys and leave this one's open)."""
    if args.site:
        return str(args.site)
    if cfg.site_set:
        return cfg.site
    where = store_label(args, cfg)
    if store_exists(args, cfg):
        with open_store(args, cfg, read_only=True) as store:
            site = stored_site(store)
        if site is not None:
            return site
        why = f"the store at {where} names no site"
    else:
        why = f"there is no store at {where}"
    msg = f"{command} guards one site's keys: give --site NAME, site.name or --store DIR of the site ({why})."
    raise ConfigError(msg)


def cmd_acl(args: argparse.Namespace, cfg: Config) -> int:
    """Print the ``access_control`` section the daemon and ``twin router --acl`` enforce (the same
    function makes both), for a zenohd's config file."""
    site = guarded_site(args, cfg, "twin acl")
    acl = site_acl(cfg, SiteKeys(key_prefix(cfg, site)), identity=args.identity)
    json.dump({"access_control": acl}, sys.stdout, indent=2)
    print()
    return 0


def cmd_router(args: argparse.Namespace, cfg: Config) -> int:
    """Run a Zenoh router that daemons and robots connect to; optionally keep every site's maps and clouds."""
    listen = args.listen or list(zenoh_of(cfg).listen)
    site = guarded_site(args, cfg, "twin router --acl") if args.acl else args.site
    keys = SiteKeys(key_prefix(cfg, site))
    acl = site_access_control(cfg, keys, enforce=True) if args.acl else None
    stop = threading.Event()

    def on_signal(signum: int, frame: Any) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    session = open_router(zenoh_of(cfg), listen=listen, connect=args.connect or [], access_control=acl)
    storages: list[MapStorage] = []
    try:
        if args.store_maps:  # every site's maps (updates applied) and points skills' clouds
            sites = zenoh_of(cfg).prefix.replace("{site}", "*").strip("/")
            storages = [MapStorage(session, f"{sites}/map/**"), MapStorage(session, f"{sites}/points/**")]
        what = f"; keeping the latest of {', '.join(s.key_expr for s in storages)}" if storages else ""
        print(
            f"router {session.info.zid()} on {', '.join(listen)}{what}; {_access_line(acl, keys)}", flush=True
        )
        stop.wait()
    finally:
        for storage in storages:
            storage.close()
        session.close()
    print("router stopped", flush=True)
    return 0


def _access_line(acl: dict[str, Any] | None, keys: SiteKeys) -> str:
    """What the router's start line says of access control."""
    text = access_summary(acl, keys)
    return text if acl is not None else text.removesuffix(")") + "; --acl to enforce it)"


def add_parsers(sub: Any) -> None:
    sp = sub.add_parser("router", help="run a Zenoh router for several daemons and their robots")
    sp.add_argument(
        "--listen", action="append", metavar="ENDPOINT", help="default: zenoh.listen (repeatable)"
    )
    sp.add_argument("--connect", action="append", metavar="ENDPOINT", help="another router (repeatable)")
    sp.add_argument(
        "--store-maps",
        action="store_true",
        help="keep the latest map and cloud of every site (twin/*/map/**, twin/*/points/**) and answer "
        "for them while its daemon restarts",
    )
    sp.add_argument(
        "--acl",
        action="store_true",
        help="enforce the access control of the configured robots and [zenoh.access] here (as 'twin acl')",
    )
    sp.add_argument(
        "--site",
        help="with --acl: the site whose keys the access control guards (default: site.name, else the "
        "site of --store)",
    )
    add_store_args(sp)
    sp.set_defaults(func=cmd_router)

    sp = sub.add_parser(
        "acl", help="print the Zenoh access control the daemon enforces (JSON, for a zenohd config)"
    )
    sp.add_argument("--site", help="site name (default: site.name, else the site of --store)")
    add_store_args(sp)
    sp.add_argument(
        "--identity",
        choices=["username", "certificate"],
        help="how robots are known (default: zenoh.access.identity)",
    )
    sp.set_defaults(func=cmd_acl)
