"""A robot that streams acked observations until its stdin closes (for the durability test).

Usage: python -m tests.integration.robot ENDPOINT SEED

Each attempt prints one JSON line: {"i", "op", "iri", "box", "acked", "revision"}. Operations: add a
new box (its own IRI), move an earlier acked one, remove an earlier acked one. While the daemon is
down, attempts time out and are printed with "acked": false.
"""

from __future__ import annotations

import json
import random
import sys
import threading
import time

from adapters.zenoh.client import TwinClient
from twin.errors import TwinError

TWIN = "https://w3id.org/building-twin#"


def box_turtle(iri: str, box: str) -> str:
    """Each item is an object of its own (``twin:distinct``: fusion never takes one for another)."""
    return (
        f'<{iri}> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "ground-floor" ; <{TWIN}box> "{box}" ; '
        f"<{TWIN}distinct> true ."
    )


def main() -> int:
    endpoint, seed = sys.argv[1], int(sys.argv[2])
    rng = random.Random(seed)
    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
    live: list[str] = []
    where: dict[str, tuple[float, float]] = {}
    i = 0
    with TwinClient.connect([endpoint], timeout_s=2.0) as twin:
        while not stop.is_set():
            op = "add" if len(live) < 3 else rng.choice(["add", "add", "move", "remove"])
            iri = f"urn:robot:item-{i}" if op == "add" else rng.choice(live)
            x, y, yaw = rng.uniform(11, 21), rng.uniform(5.5, 8.5), rng.uniform(0, 3)
            while iri in where and abs(x - where[iri][0]) + abs(y - where[iri][1]) < 0.8:
                x, y = rng.uniform(11, 21), rng.uniform(5.5, 8.5)  # a move fusion applies at once
            box = f"{x:.3f} {y:.3f} 0.3 0.4 0.4 0.6 {yaw:.3f}"
            payload = f"<{iri}> <{TWIN}removed> true ." if op == "remove" else box_turtle(iri, box)
            try:
                ack = twin.observe("robot1", payload)
                acked, revision = bool(ack["ok"]), int(ack["revision"])
            except TwinError:
                acked, revision = False, -1
                time.sleep(0.05)  # no daemon (no route: the request fails at once): try again soon
            if acked and op != "remove":
                where[iri] = (x, y)
            if acked and op == "add":
                live.append(iri)
            if acked and op == "remove":
                live.remove(iri)
            line = {"i": i, "op": op, "iri": iri, "box": box, "acked": acked, "revision": revision}
            print(json.dumps(line), flush=True)
            i += 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
