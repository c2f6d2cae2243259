"""A robot whose clock is off, reporting at 5 Hz (for the clocks test, own process).

Usage: python -m tests.integration.clock_robot ENDPOINT ROBOT OFFSET_S COUNT KIND

KIND ``chair``: sees the chair at world (12.0, 6.0) in each observation; ``view``: looks at the floor
around it (a view of IfcFurniture) and sees nothing. Every sense time is the robot's clock: the
daemon's plus OFFSET_S. It makes COUNT observations (0: until its stdin closes), then prints one JSON
line: {"sent", "stale", "refused"}.
"""

from __future__ import annotations

import datetime as dt
import json
import sys
import threading
import time

from adapters.zenoh.client import TwinClient
from twin.errors import TwinError

TWIN = "https://w3id.org/building-twin#"
XSD = "http://www.w3.org/2001/XMLSchema#"


def stamp(ns: int) -> str:
    seconds, nanos = divmod(ns, 1_000_000_000)
    moment = dt.datetime.fromtimestamp(seconds, tz=dt.UTC).strftime("%Y-%m-%dT%H:%M:%S")
    return f'"{moment}.{nanos:09d}Z"^^<{XSD}dateTime>'


def main() -> int:
    endpoint, robot, offset_s, count, kind = sys.argv[1:]
    offset, left = int(float(offset_s) * 1e9), int(count) or -1
    closed = threading.Event()
    if left < 0:
        threading.Thread(target=lambda: (sys.stdin.read(), closed.set()), daemon=True).start()
    sent = stale = refused = 0
    with TwinClient.connect([endpoint], timeout_s=30.0) as twin:
        while left and not closed.is_set():
            left -= 1
            now = stamp(time.time_ns() + offset)
            if kind == "chair":
                doc = (
                    f'<urn:{robot}:chair> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "ground-floor" ; '
                    f'<{TWIN}box> "12.0 6.0 0.45 0.5 0.5 0.9 0" ; <{TWIN}senseTime> {now} .'
                )
            else:
                doc = (
                    f'[] a <{TWIN}View> ; <{TWIN}storey> "ground-floor" ; <{TWIN}detects> "IfcFurniture" ; '
                    f'<{TWIN}polygon> "11.4 5.4 12.6 5.4 12.6 6.6 11.4 6.6" ; <{TWIN}senseTime> {now} .'
                )
            try:
                ack = twin.observe(robot, doc)
                sent += 1
                stale += len(ack.get("stale", []))
            except TwinError:
                refused += 1
            time.sleep(0.2)
    print(json.dumps({"sent": sent, "stale": stale, "refused": refused}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
