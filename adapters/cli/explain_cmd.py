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
from adapters.zenoh.errors import RemoteError
from twin.config import Config
from twin.errors import ExplainError


def _line(e: dict[str, Any]) -> str:
    name = f"{e.get('name')!r} " if e.get("name") else ""
    text = f"{name}{e.get('class') or ''} <{e['iri']}>"
    if e.get("global_id"):
        text += f" GlobalId {e['global_id']}"
    seen = e.get("observed")
    if seen:
        text += f", observed by {seen['robot']} at {seen['at']} (revision {seen['revision']})"
    return text


def describe(answer: dict[str, Any]) -> str:
    """The answer as an operator reads it."""
    cell = answer["cell"]
    out = [
        f"{answer['storey']}/{answer['skill']} at ({answer['x']}, {answer['y']}), cell "
        f"({cell['col']}, {cell['row']}): {answer['state']} ({answer['value']})"
    ]
    out += [f"  occupied by {_line(e)}" for e in answer["occupied_by"]]
    out += [f"  within the inflation radius of {_line(e)}" for e in answer["within_inflation_of"]]
    out += [f"  near ({e['distance_m']} m), not drawn: {e['why_not']}: {_line(e)}" for e in answer["near"]]
    return "\n".join(out)


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
    print(json.dumps(answer, indent=2) if args.json else describe(answer))
    return 0


def add_parser(sub: Any) -> None:
    sp = sub.add_parser("explain", help="why a map cell is occupied or free (asks the daemon)")
    add_client_args(sp)
    sp.add_argument("--storey", required=True, help="the storey key (see 'twin stats')")
    sp.add_argument("--skill", required=True, help="the skill whose map to explain")
    sp.add_argument("--at", required=True, metavar="X,Y", help="the point, metres in the map's frame")
    sp.add_argument("--json", action="store_true", help="print the daemon's JSON answer")
    sp.set_defaults(func=cmd_explain)
