"""``twin acl`` and ``twin router``: the Zenoh network around daemons (access control, routers)."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from typing import Any

from adapters.cli.common import key_prefix, zenoh_of
from adapters.zenoh.access import site_access_control, site_acl
from adapters.zenoh.keys import SiteKeys
from adapters.zenoh.router import MapStorage, open_router
from twin.config import Config


def cmd_acl(args: argparse.Namespace, cfg: Config) -> int:
    """Print the ``access_control`` section the daemon and ``twin router --acl`` enforce (the same
    function makes both), for a zenohd's config file."""
    acl = site_acl(cfg, SiteKeys(key_prefix(cfg, args.site)), identity=args.identity)
    json.dump({"access_control": acl}, sys.stdout, indent=2)
    print()
    return 0


def cmd_router(args: argparse.Namespace, cfg: Config) -> int:
    """Run a Zenoh router that daemons and robots connect to; optionally keep every site's maps and clouds."""
    listen = args.listen or list(zenoh_of(cfg).listen)
    keys = SiteKeys(key_prefix(cfg, args.site))
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
    if acl is None:
        return "access control off (anyone who connects may read and write everything; --acl to enforce it)"
    names = [str(n) for s in acl["subjects"] for k, v in s.items() if k != "id" for n in v]
    return f"access control on for {keys.prefix}/** (robots and operators: {', '.join(names)})"


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
        "--site", help="with --acl: the site whose keys the access control guards (default: site.name)"
    )
    sp.set_defaults(func=cmd_router)

    sp = sub.add_parser(
        "acl", help="print the Zenoh access control the daemon enforces (JSON, for a zenohd config)"
    )
    sp.add_argument("--site", help="site name (default: site.name)")
    sp.add_argument(
        "--identity",
        choices=["username", "certificate"],
        help="how robots are known (default: zenoh.access.identity)",
    )
    sp.set_defaults(func=cmd_acl)
