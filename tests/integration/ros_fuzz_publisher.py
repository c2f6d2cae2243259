"""A hostile ROS 2 robot and building system (own process): mutated ``vision_msgs/msg/Detection3DArray``,
``tf2_msgs/msg/TFMessage``, ``rmf_obstacle_msgs/msg/Obstacles`` and ``rmf_door_msgs/msg/DoorState``
payloads on both layouts (rmw_zenoh's keys with the 33-byte attachment, and zenoh-bridge-ros2dds's
keys), published reliably with congestion control BLOCK so that every one reaches the daemon.

Usage: python -m tests.integration.ros_fuzz_publisher ENDPOINT COUNT SEED [RATE]

Prints ``{"ready": true}`` once its publishers are declared, then after the last payload one line
``{"sent": N, "owners": {owner: n}, "mutations": {kind: n}}``. ``RATE`` (payloads per second, 0: as
fast as it can) paces it. The daemon under test is configured with :data:`CONFIG`.

The mutations (:func:`hostile_payloads`), each on a valid message of the four types: ``truncated``,
``bitflip`` (1 to 8 bits), ``huge_length`` (a 4-byte aligned word set to a length of 2**31 or more),
``random`` bytes, ``empty``, ``wrong_type`` (another type's bytes; on rmw_zenoh also under another
type's key), ``nan`` (NaN and infinite poses, sizes, scores, a zero quaternion), ``future`` (stamps an
hour and decades ahead), ``huge_payload`` (a 2 MB frame id, rarely) and ``valid`` (unchanged, about 2%:
what the daemon may accept).
"""

from __future__ import annotations

import json
import random
import struct
import sys
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import zenoh

from adapters.ros.interfaces import DETECTION_3D_ARRAY, DOOR_STATE, OBSTACLES, TF_MESSAGE
from adapters.ros.rmw_zenoh import RosTopic, attachment
from adapters.zenoh.session import client_config
from tests.adapters.ros_reports import (
    OPTICAL,
    Det,
    Obstacle,
    Tf,
    cdr_detections,
    cdr_door_state,
    cdr_obstacles,
    cdr_tf,
)

CONFIG = """
[robots.robot1]
namespace = "/robot1"
storey = "ground-floor"
ros = ["rmw_zenoh", "bridge"]
[robots.robot1.detections]
classes = { table = "IfcFurniture" }
fov_deg = 87
range_m = 6.0
optical = true

[sources.doors]
kind = "rmf_doors"
ros = ["rmw_zenoh", "bridge"]
doors = { lab_door_a = "Door A" }

[sources.obstacles]
kind = "rmf_obstacles"
ros = ["rmw_zenoh", "bridge"]
classes = { human = "IfcBuildingElementProxy" }
levels.L1 = { storey = "ground-floor" }
"""
"""The daemon's configuration: one robot with detections, a door source and an obstacle source, each
subscribed on both layouts."""

TOPICS = {
    ("/robot1/detections", DETECTION_3D_ARRAY): "robot1",
    ("/robot1/tf", TF_MESSAGE): "robot1",
    ("/door_states", DOOR_STATE): "doors",
    ("/rmf_obstacles", OBSTACLES): "obstacles",
}
LAYOUTS = ("rmw_zenoh", "bridge")
WRONG_KEY_TYPE = "std_msgs/msg/String"
NAN, INF = float("nan"), float("inf")
FAR_FUTURE_S = 2**31 - 1


@dataclass(frozen=True, slots=True)
class Payload:
    topic: str
    type_name: str
    layout: str
    data: bytes
    mutation: str
    type_key: str = ""
    """On rmw_zenoh: publish under this type's key instead (a wrong type)."""

    @property
    def owner(self) -> str:
        return TOPICS[(self.topic, self.type_name)]


def _valid(topic: str, stamp_ns: int, rng: random.Random) -> bytes:
    """A valid message of the topic's type, around the lab's ground floor."""
    x, y = rng.uniform(12.0, 20.0), rng.uniform(6.0, 8.0)
    if topic.endswith("detections"):
        table = Det((("table", 0.9),), (0.0, 0.6, 2.4), (0.6, 0.6, 0.75), (0.5, -0.5, 0.5, 0.5), id="t7")
        return cdr_detections(stamp_ns, "camera_optical_frame", [table])
    if topic.endswith("tf"):
        return cdr_tf(
            [
                Tf("map", "base_link", (x, y, 0.0), stamp_ns=stamp_ns),
                Tf("base_link", "camera_optical_frame", (0.2, 0.0, 1.0), OPTICAL, stamp_ns=stamp_ns),
            ]
        )
    if topic.endswith("door_states"):
        return cdr_door_state(stamp_ns, "lab_door_a", rng.choice((0, 1, 2)))
    person = Obstacle(rng.randrange(8), "cam", "L1", "human", (x, y, 0.9), (0.5, 0.5, 1.8), lifetime_ns=10**9)
    return cdr_obstacles(stamp_ns, [person])


def _nan(topic: str, stamp_ns: int, rng: random.Random) -> bytes:
    bad = rng.choice((NAN, INF, -INF, 1e308))
    if topic.endswith("detections"):
        det = rng.choice(
            (
                Det((("table", bad),), (0.0, 0.6, 2.4), (0.6, 0.6, 0.75)),
                Det((("table", 0.9),), (bad, 0.6, 2.4), (0.6, 0.6, 0.75)),
                Det((("table", 0.9),), (0.0, 0.6, 2.4), (bad, 0.6, -1.0)),
                Det((("table", 0.9),), (0.0, 0.6, 2.4), (0.6, 0.6, 0.75), (0.0, 0.0, 0.0, 0.0)),
            )
        )
        return cdr_detections(stamp_ns, "camera_optical_frame", [det])
    if topic.endswith("tf"):
        return cdr_tf(
            [Tf("map", "base_link", (bad, 7.0, 0.0), rng.choice(((0, 0, 0, 0), (bad, 0, 0, 1))), stamp_ns)]
        )
    if topic.endswith("door_states"):
        return cdr_door_state(stamp_ns, "lab_door_a", rng.choice((3, 255, 2**32 - 1)))  # no such mode
    o = rng.choice(
        (
            Obstacle(1, "cam", "L1", "human", (bad, 7.0, 0.9), (0.5, 0.5, 1.8)),
            Obstacle(1, "cam", "L1", "human", (10.0, 7.0, 0.9), (bad, -0.5, 1.8)),
            Obstacle(1, "cam", "L1", "human", (10.0, 7.0, 0.9), (0.5, 0.5, 1.8), orientation=(0, 0, 0, 0)),
            Obstacle(1, "cam", "L1", "human", (10.0, 7.0, 0.9), (0.5, 0.5, 1.8), action=-7),
        )
    )
    return cdr_obstacles(stamp_ns, [o])


def _future(topic: str, stamp_ns: int, rng: random.Random) -> bytes:
    ahead = rng.choice((3600 * 10**9, (FAR_FUTURE_S * 10**9) - stamp_ns))
    return _valid(topic, stamp_ns + ahead, rng)


def _huge_length(data: bytes, rng: random.Random) -> bytes:
    out = bytearray(data)
    words = (len(out) - 4) // 4
    at = 4 + 4 * rng.randrange(max(words, 1))
    out[at : at + 4] = struct.pack("<I", rng.choice((2**31, 2**32 - 1, 2**31 + 7, 0x7FFFFFF0)))
    return bytes(out[: max(len(data), 8)])


def _bitflip(data: bytes, rng: random.Random) -> bytes:
    out = bytearray(data)
    for _ in range(rng.randint(1, 8)):
        bit = rng.randrange(len(out) * 8)
        out[bit // 8] ^= 1 << (bit % 8)
    return bytes(out)


def hostile_payloads(count: int, seed: int, *, clock: Any = time.time_ns) -> Iterator[Payload]:
    """``count`` payloads, seeded: every mutation on every topic and layout, in a random order."""
    rng = random.Random(seed)
    topics = sorted(TOPICS)
    kinds = ["truncated", "bitflip", "huge_length", "random", "empty", "wrong_type", "nan", "future"]
    for n in range(count):
        topic, type_name = rng.choice(topics)
        layout = LAYOUTS[n % 2]
        stamp = clock()
        type_key = ""
        r = rng.random()
        if r < 0.02:
            kind = "valid"
            data = _valid(topic, stamp, rng)
        elif r < 0.0205:
            kind = "huge_payload"
            data = cdr_detections(stamp, "x" * 2_000_000, []) if n % 4 else rng.randbytes(2_000_000)
        else:
            kind = rng.choice(kinds)
            valid = _valid(topic, stamp, rng)
            if kind == "truncated":
                data = valid[: rng.randrange(len(valid))]
            elif kind == "bitflip":
                data = _bitflip(valid, rng)
            elif kind == "huge_length":
                data = _huge_length(valid, rng)
            elif kind == "random":
                data = rng.randbytes(rng.randrange(1, 512))
            elif kind == "empty":
                data = b""
            elif kind == "wrong_type":
                other = rng.choice([t for t in topics if t[1] != type_name])
                data = _valid(other[0], stamp, rng)
                if layout == "rmw_zenoh" and rng.random() < 0.5:
                    type_key = WRONG_KEY_TYPE
                    data = b"\x00\x01\x00\x00\x0c\x00\x00\x00not a table\x00"
            elif kind == "nan":
                data = _nan(topic, stamp, rng)
            else:
                data = _future(topic, stamp, rng)
        yield Payload(topic, type_name, layout, data, kind, type_key)


def main() -> int:
    endpoint, count, seed = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    rate = float(sys.argv[4]) if len(sys.argv) > 4 else 0.0
    publishers: dict[tuple[str, str, str], tuple[Any, bytes | None]] = {}
    sequence = 0
    owners: Counter[str] = Counter()
    mutations: Counter[str] = Counter()
    with zenoh.open(client_config([endpoint])) as session:
        gid = bytes(range(16))
        for topic, type_name in TOPICS:
            ns, _, name = topic.rpartition("/")
            for type_key in (type_name, WRONG_KEY_TYPE):
                t = RosTopic(0, ns or "/", name, type_key)
                for layout, key, g in (("rmw_zenoh", t.data_key, gid), ("bridge", t.bridge_key, None)):
                    publishers[(layout, topic, type_key)] = (
                        session.declare_publisher(
                            key,
                            reliability=zenoh.Reliability.RELIABLE,
                            congestion_control=zenoh.CongestionControl.BLOCK,
                        ),
                        g,
                    )
        time.sleep(1.0)  # let the daemon's subscriptions meet the publishers
        print(json.dumps({"ready": True}), flush=True)
        t0 = time.monotonic()
        for n, p in enumerate(hostile_payloads(count, seed)):
            pub, g = publishers[(p.layout, p.topic, p.type_key or p.type_name)]
            sequence += 1
            extra = {"attachment": attachment(sequence, time.time_ns(), g)} if g is not None else {}
            pub.put(p.data, **extra)
            owners[p.owner] += 1
            mutations[p.mutation] += 1
            if rate > 0 and (ahead := t0 + (n + 1) / rate - time.monotonic()) > 0:
                time.sleep(ahead)
        print(
            json.dumps({"sent": sum(owners.values()), "owners": owners, "mutations": mutations}), flush=True
        )
        sys.stdin.read()  # stay connected until told to go (reliable delivery of the tail)
        for pub, _ in publishers.values():
            pub.undeclare()
    return 0


if __name__ == "__main__":
    sys.exit(main())
