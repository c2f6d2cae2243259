"""``twin zone``: an operator keeps robots out of a room, or slows them down in it.

A room (``IfcSpace``) is not an element the maps are made of, so the zone is drawn as one: a virtual
element (``IfcVirtualElement``) with the room's own mesh, marked ``twin:keepout true`` or
``twin:speedLimit N``, sent as an ordinary acked observation (the sender needs the ``zones`` right;
creating and removing the zone element need ``create`` and ``dynamic``). The zone's IRI is derived
from the room's, so marking a room twice is a re-confirmation and ``--lift`` removes the one zone.

Example::

    twin zone --robot operator --space "Room B" --keepout
    twin zone --robot operator --space "Room B" --speed-limit 30
    twin zone --robot operator --space "Room B" --lift
"""

from __future__ import annotations

import argparse
import hashlib
import json
from dataclasses import dataclass
from typing import Any

from adapters.cli.common import add_client_args, open_client
from adapters.zenoh.client import TwinClient
from adapters.zenoh.errors import RemoteError
from twin.config import Config
from twin.errors import ObservationError
from twin.graph import vocab

VIRTUAL_CLASS = "IfcVirtualElement"


@dataclass(frozen=True, slots=True)
class Room:
    """A space as the graph holds it: its IRI, name, storey key, and its mesh (PLY, base64) and
    placement literals, copied as they are."""

    iri: str
    name: str
    storey: str
    ply_base64: str
    placement: str


def zone_iri(space_iri: str) -> str:
    """The zone element of a room: one per room, the same every time."""
    return f"urn:twin:zone:{hashlib.sha1(space_iri.encode()).hexdigest()[:16]}"


def find_room(twin: TwinClient, space: str) -> Room:
    """The space whose IRI or name is ``space``; ObservationError names the rooms there are."""
    rows = twin.sparql(
        f"""SELECT ?space ?name ?key ?ply ?placement WHERE {{
              ?space a bot:Space ; omg:hasGeometry ?g .
              ?g <{vocab.FOG_PLY_BINARY_LE}> ?ply ; twin:placement ?placement .
              ?storey bot:hasSpace ?space ; twin:storeyKey ?key .
              OPTIONAL {{ ?space rdfs:label ?name }}
            }}"""
    )
    assert isinstance(rows, dict)
    rooms = [
        Room(
            b["space"]["value"],
            b.get("name", {}).get("value", ""),
            b["key"]["value"],
            b["ply"]["value"],
            b["placement"]["value"],
        )
        for b in rows["results"]["bindings"]
    ]
    found = [r for r in rooms if space in (r.iri, r.name)]
    if len(found) == 1:
        return found[0]
    names = ", ".join(sorted(repr(r.name or r.iri) for r in rooms)) or "none"
    if not found:
        msg = f"No space (IfcSpace) named {space!r} with geometry; the twin's spaces are {names}."
    else:
        msg = f"{len(found)} spaces are named {space!r}; give one's IRI: " + ", ".join(r.iri for r in found)
    raise ObservationError(msg)


def zone_turtle(room: Room, *, keepout: bool, speed_limit: int | None, lift: bool) -> str:
    """The observation that draws (or removes) the room's zone element."""
    t = vocab.TWIN
    zone = zone_iri(room.iri)
    if lift:
        return f"<{zone}> <{t}removed> true .\n"
    marks = f"<{t}keepout> true" if keepout else f"<{t}speedLimit> {speed_limit}"
    return (
        f"<{zone}> <{t}ifcClass> {json.dumps(VIRTUAL_CLASS)} ; <{t}storey> {json.dumps(room.storey)} ; "
        f"<{vocab.RDFS_LABEL}> {json.dumps('zone: ' + (room.name or room.iri))} ;\n"
        f"  <{vocab.OMG_HAS_GEOMETRY}> [ <{vocab.FOG_PLY_BINARY_LE}> "
        f'"{room.ply_base64}"^^<http://www.w3.org/2001/XMLSchema#base64Binary> ; '
        f'<{t}placement> "{room.placement}"^^<{vocab.TWIN_MATRIX4}> ] ;\n'
        f"  {marks} .\n"
    )


def cmd_zone(args: argparse.Namespace, cfg: Config) -> int:
    if args.speed_limit is not None and not 1 <= args.speed_limit <= 100:
        msg = f"--speed-limit takes a percent from 1 to 100 (--lift removes a zone), got {args.speed_limit}."
        raise ObservationError(msg)
    with open_client(args, cfg) as twin:
        room = find_room(twin, args.space)
        payload = zone_turtle(room, keepout=args.keepout, speed_limit=args.speed_limit, lift=args.lift)
        try:
            ack: dict[str, Any] = twin.observe(args.robot, payload)
        except RemoteError as err:
            print(json.dumps({"ok": False, "error": str(err)}))
            return 1
    print(json.dumps({**ack, "zone": zone_iri(room.iri), "space": room.iri}))
    return 0


def add_parsers(sub: Any) -> None:
    sp = sub.add_parser("zone", help="keep robots out of a room, or slow them down in it (nav2 filter masks)")
    add_client_args(sp)
    sp.add_argument("--robot", required=True, help="who marks the zone (needs the 'zones' right)")
    sp.add_argument("--space", required=True, help="the room: an IfcSpace's name or IRI")
    what = sp.add_mutually_exclusive_group(required=True)
    what.add_argument("--keepout", action="store_true", help="robots must not enter the room")
    what.add_argument("--speed-limit", type=int, metavar="PERCENT", help="a speed limit in the room")
    what.add_argument("--lift", action="store_true", help="remove the room's zone")
    sp.set_defaults(func=cmd_zone)
