"""``twin acl`` and ``twin router``: the Zenoh network around daemons (access control, routers)."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from adapters.zenoh.access import access_control, ros_map_keys
from adapters.zenoh.keys import SiteKeys
from twin.config import Config


def cmd_acl(args: argparse.Namespace, cfg: Config) -> int:
    """Print the ``access_control`` section the daemon uses, for a router's or zenohd's config file."""
    identity = args.identity or cfg.zenoh.access.identity
    acl = access_control(
        SiteKeys(cfg.key_prefix(args.site)),
        sorted(cfg.robots),
        identity=identity,
        operators=cfg.zenoh.access.operators,
        ros_keys=ros_map_keys(cfg.robots.values()),
    )
    json.dump({"access_control": acl}, sys.stdout, indent=2)
    print()
    return 0


def add_parsers(sub: Any) -> None:
    sp = sub.add_parser(
        "acl", help="print the Zenoh access control of the configured robots (JSON, for a router's config)"
    )
    sp.add_argument("--site", help="site name (default: site.name)")
    sp.add_argument(
        "--identity",
        choices=["username", "certificate"],
        help="how robots are known (default: zenoh.access.identity)",
    )
    sp.set_defaults(func=cmd_acl)
