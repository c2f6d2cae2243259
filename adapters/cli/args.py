"""The options many ``twin`` commands share, without what they need to run: building the parser of
one command imports only argparse (``common`` re-exports them for the commands)."""

from __future__ import annotations

import argparse


def add_store_args(sp: argparse.ArgumentParser) -> None:
    """``--store DIR`` or ``--store-url URL``: the embedded store or a SPARQL 1.1 server."""
    group = sp.add_mutually_exclusive_group()
    group.add_argument("--store", help="store directory (default: store.path of the configuration)")
    group.add_argument(
        "--store-url",
        metavar="URL",
        help="a SPARQL 1.1 server holding the graph instead, e.g. http://127.0.0.1:7878 (oxigraph serve)",
    )


SITE_HELP = "site name (key prefix twin/<site>; default: site.name if set, else the one daemon running)"


def add_client_args(sp: argparse.ArgumentParser) -> None:
    """What every command that talks to a running daemon takes: where, which site, how long, how."""
    sp.add_argument(
        "--connect",
        action="append",
        metavar="ENDPOINT",
        help="the daemon or a router (repeatable; default: zenoh.connect, else zenoh.listen)",
    )
    sp.add_argument("--site", help=SITE_HELP)
    sp.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for the daemon (default 10)")
    sp.add_argument(
        "--mode", choices=["peer", "client"], help="the Zenoh session's mode (default: zenoh.mode, peer)"
    )
