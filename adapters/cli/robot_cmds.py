"""``twin observe``, ``twin storey`` and ``twin status``: what a robot does, from the command line
(``twin watch``: :mod:`adapters.cli.watch_cmd`)."""

from __future__ import annotations

import argparse
import json
import sys
import time
import uuid
from pathlib import Path
from typing import Any

from adapters.cli.common import add_client_args, open_client
from adapters.cli.render import describe_status
from adapters.zenoh.errors import RemoteError, StoreySwitchError
from twin.config import Config
from twin.errors import ObservationError
from twin.graph import vocab


def box_turtle(iri: str, box: list[float], *, ifc_class: str, storey: str, label: str | None = None) -> str:
    """An observation of one oriented box ``[x, y, z, sx, sy, sz, yaw]`` (see docs/observations.md)."""
    t = vocab.TWIN
    text = f"<{iri}> <{t}ifcClass> {json.dumps(ifc_class)} ; <{t}storey> {json.dumps(storey)} ; "
    if label is not None:
        text += f"<{vocab.RDFS_LABEL}> {json.dumps(label)} ; "
    return text + f'<{t}box> "{" ".join(repr(v) for v in box)}" .\n'


def observation_turtle(args: argparse.Namespace) -> bytes:
    """The observation document the options describe."""
    t = vocab.TWIN
    if args.turtle:
        return Path(args.turtle).read_bytes()
    if args.box:
        try:
            values = [float(v) for v in args.box.split(",")]
        except ValueError:
            values = []
        if len(values) != 7:
            msg = f"--box takes 7 comma-separated numbers x,y,z,sx,sy,sz,yaw, got {args.box!r}."
            raise ObservationError(msg)
        if not args.ifc_class or not args.storey:
            msg = "--box needs --class IFCCLASS and --storey KEY."
            raise ObservationError(msg)
        iri = args.id or f"urn:twin:{args.robot}:{uuid.uuid4()}"
        return box_turtle(iri, values, ifc_class=args.ifc_class, storey=args.storey).encode()
    marks = (
        (args.remove, "removed", "true"),
        (args.open, "isOpen", "true"),
        (args.close, "isOpen", "false"),
        (args.keepout, "keepout", "true"),
        (args.no_keepout, "keepout", "false"),
    )
    for iri, predicate, value in marks:
        if iri:
            return f"<{iri}> <{t}{predicate}> {value} .\n".encode()
    if args.speed_limit:
        iri, percent = args.speed_limit
        if not percent.isdigit():
            msg = f"--speed-limit takes an IRI and a percent from 0 (no limit) to 100, got {percent!r}."
            raise ObservationError(msg)
        return f"<{iri}> <{t}speedLimit> {int(percent)} .\n".encode()
    msg = (
        "Say what was observed: --box ... | --turtle FILE | --remove IRI | --open IRI | --close IRI | "
        "--keepout IRI | --no-keepout IRI | --speed-limit IRI PERCENT."
    )
    raise ObservationError(msg)


def cmd_observe(args: argparse.Namespace, cfg: Config) -> int:
    payload = observation_turtle(args)
    with open_client(args, cfg) as twin:
        if args.no_ack:
            twin.publish_observation(args.robot, payload)
            time.sleep(0.2)  # let the put leave before the session closes
            print("sent (no ack requested)")
            return 0
        try:
            ack = twin.observe(args.robot, payload)
        except RemoteError as err:
            print(json.dumps({"ok": False, "error": str(err)}))
            return 1
    print(json.dumps(ack))
    return 0


def cmd_storey(args: argparse.Namespace, cfg: Config) -> int:
    """``twin storey --robot NAME [KEY]``: print the robot's storey, after switching it to KEY if given."""
    with open_client(args, cfg) as twin:
        robots = twin.status().get("robots") or {}
        if args.robot not in robots:
            site = twin.keys.prefix
            known = (
                f"the robots configured at {site} ([robots.NAME]) are {', '.join(sorted(robots))}"
                if robots
                else f"the daemon of {site} has no robots configured (no [robots.NAME] table)"
            )
            msg = f"Unknown robot {args.robot!r}: {known}."
            raise StoreySwitchError(msg)
        try:
            storey = twin.robot_storey(args.robot, args.storey)
        except RemoteError as err:
            print(f"twin: error: {err}", file=sys.stderr)
            return 1
    print(storey)
    return 0


def add_parsers(sub: Any) -> None:
    common = add_client_args

    sp = sub.add_parser("observe", help="send a robot's observation to the daemon and print the ack")
    common(sp)
    sp.add_argument("--robot", required=True, help="the observing robot's name")
    what = sp.add_mutually_exclusive_group(required=True)
    what.add_argument("--box", metavar="x,y,z,sx,sy,sz,yaw", help="an oriented box (z above the storey)")
    what.add_argument("--turtle", metavar="FILE", help="a Turtle observation document")
    what.add_argument("--remove", metavar="IRI", help="the element is gone")
    what.add_argument("--open", metavar="IRI", help="the door was seen open")
    what.add_argument("--close", metavar="IRI", help="the door was seen closed")
    what.add_argument("--keepout", metavar="IRI", help="mark a keepout zone (needs the 'zones' right)")
    what.add_argument("--no-keepout", metavar="IRI", help="lift a keepout zone")
    what.add_argument(
        "--speed-limit", nargs=2, metavar=("IRI", "PERCENT"), help="mark a speed zone (0 lifts it)"
    )
    sp.add_argument("--id", help="IRI of the boxed element (default: a new urn:twin:<robot>:<uuid>)")
    sp.add_argument("--class", dest="ifc_class", help="IFC class of the boxed element, e.g. IfcFurniture")
    sp.add_argument("--storey", help="storey key of the boxed element (see 'twin stats')")
    sp.add_argument("--no-ack", action="store_true", help="best effort: put, do not wait for an ack")
    sp.set_defaults(func=cmd_observe)

    sp = sub.add_parser("status", help="the running daemon's status: revision, elements, maps, robots, ...")
    common(sp)
    sp.add_argument("--json", action="store_true", help="print the daemon's JSON as it is")
    sp.set_defaults(func=cmd_status)

    sp = sub.add_parser("storey", help="print a robot's current storey, or switch it (the lift)")
    common(sp)
    sp.add_argument("--robot", required=True, help="the robot's name ([robots.NAME])")
    sp.add_argument("storey", nargs="?", help="the storey key to switch to (see 'twin stats')")
    sp.set_defaults(func=cmd_storey)


def cmd_status(args: argparse.Namespace, cfg: Config) -> int:
    """``twin status``: what the daemon answers on ``<prefix>/status``."""
    with open_client(args, cfg) as twin:
        status = twin.status()
    print(json.dumps(status, indent=2) if args.json else describe_status(status))
    return 0
