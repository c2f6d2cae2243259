"""``twin explain``: why is this map cell occupied (or free)? Asks the running daemon.

Example::

    twin explain --storey ground-floor --skill navigation --at 16.6,7.0
    twin explain --storey ground-floor --skill localization --at 21.9,7.0 --json
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from adapters.cli.common import add_client_args, open_client
from adapters.cli.render import describe_explain
from adapters.zenoh.errors import RemoteError
from twin.config import Config
from twin.errors import ExplainError


def cmd_explain(args: argparse.Namespace, cfg: Config) -> int:
    try:
        x, y = (float(v) for v in args.at.split(","))
    except ValueError as err:
        msg = f"--at takes the point as X,Y in metres (the map's frame), got {args.at!r}."
        raise ExplainError(msg) from err
    with open_client(args, cfg) as twin:
        try:
            answer = twin.explain(args.storey, args.skill, x, y)
        except RemoteError as err:
            if args.json:
                print(json.dumps({"ok": False, "error": str(err)}))
            else:
                print(f"twin: error: {err}", file=sys.stderr)
            return 1
    print(json.dumps(answer, indent=2) if args.json else describe_explain(answer))
    return 0


def add_parser(sub: Any) -> None:
    sp = sub.add_parser("explain", help="why a map cell is occupied or free (asks the daemon)")
    add_client_args(sp)
    sp.add_argument("--storey", required=True, help="the storey key (see 'twin stats')")
    sp.add_argument("--skill", required=True, help="the skill whose map to explain")
    sp.add_argument("--at", required=True, metavar="X,Y", help="the point, metres in the map's frame")
    sp.add_argument(
        "--json", action="store_true", help="print the daemon's JSON answer (times in ns), for machines"
    )
    sp.set_defaults(func=cmd_explain)
