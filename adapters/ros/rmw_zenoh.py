"""How ROS 2 sees a topic on Zenoh: rmw_zenoh_cpp's key expressions, attachment and liveliness tokens,
and zenoh-bridge-ros2dds's keys. Pure functions (no Zenoh import): the publisher is in
``adapters/zenoh/ros_maps.py``.

Checked against rmw_zenoh_cpp ``src/detail/liveliness_utils.cpp`` (``KeyexprIndex``, ``mangle_name``,
``qos_to_keyexpr`` eliding rmw defaults), ``attachment_helpers.cpp`` (sequence number, source
timestamp, gid, zenoh-ext serialised) and ``rmw_publisher_data.cpp`` (the data key
``<domain>/<topic without leading slash>/<dds type>/<type hash>``) as described in DESIGN.md; and
zenoh-plugin-ros2dds (the bridge maps ROS topic ``/map`` in namespace ``/robot1`` to key
``robot1/map``, payload the CDR bytes).

Example::

    topic = RosTopic(domain_id=0, namespace="/robot1", name="map", type_name=OCCUPANCY_GRID)
    topic.data_key          # "0/robot1/map/nav_msgs::msg::dds_::OccupancyGrid_/RIHS01_8d34..."
    topic.bridge_key        # "robot1/map"
    attachment(1, stamp_ns, gid_of(token))  # 33 bytes
"""

from __future__ import annotations

import functools
import hashlib
import struct
from dataclasses import dataclass

from adapters.ros.cdr import _typestore
from twin.errors import MapError

ADMIN_SPACE = "@ros2_lv"
SLASH = "%"
# rmw_zenoh's default QoS (rmw_qos_profile_default: RELIABLE, VOLATILE, KEEP_LAST 10) is elided from
# tokens; a latched map is RELIABLE (default, elided), TRANSIENT_LOCAL (1), KEEP_LAST (default) depth 1.
LATCHED_QOS = ":1:,1:,:,:,,"
# map_updates: RELIABLE, VOLATILE, KEEP_LAST 10: all defaults.
DEFAULT_QOS = "::,:,:,:,,"
# the /<ns>/storey subscription: RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 1, as the latched map (a robot
# that publishes its storey latched is read when the daemon starts; volatile publishers work too).
STATE_QOS = LATCHED_QOS


@functools.cache
def type_hash(type_name: str) -> str:
    """The RIHS01 type hash of a ROS 2 message type, computed from its definition with rosbags."""
    value: str = _typestore().hash_rihs01(type_name)
    return value


def dds_type_name(type_name: str) -> str:
    """``nav_msgs/msg/OccupancyGrid`` -> ``nav_msgs::msg::dds_::OccupancyGrid_`` (rmw's type name)."""
    pkg, kind, name = type_name.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def mangle(name: str) -> str:
    """A ROS name as one key chunk: every ``/`` becomes ``%``."""
    return name.replace("/", SLASH)


def demangle(chunk: str) -> str:
    return chunk.replace(SLASH, "/")


def _namespace(ns: str) -> str:
    ns = "/" + ns.strip("/")
    return ns


def resolve_name(namespace: str, name: str) -> tuple[str, str]:
    """``(namespace, relative name)`` of a topic: a relative ``name`` goes under ``namespace``, an
    absolute one (``/tf``) stays where it is (namespace ``/``), as ROS resolves names."""
    if name.startswith("/"):
        return "/", name.lstrip("/")
    return namespace, name


@dataclass(frozen=True, slots=True)
class RosTopic:
    """A topic in a robot's namespace, e.g. ``/robot1/map``."""

    domain_id: int
    namespace: str
    name: str
    type_name: str

    @property
    def fqn(self) -> str:
        """The fully qualified topic name, e.g. ``/robot1/map``."""
        ns = _namespace(self.namespace)
        return f"{ns.rstrip('/')}/{self.name}"

    @property
    def data_key(self) -> str:
        """rmw_zenoh's key: ``<domain>/<topic without the leading slash>/<dds type>/<RIHS01 hash>``."""
        topic = self.fqn.strip("/")
        return f"{self.domain_id}/{topic}/{dds_type_name(self.type_name)}/{type_hash(self.type_name)}"

    @property
    def bridge_key(self) -> str:
        """zenoh-bridge-ros2dds's key for the topic in its namespace: no domain, type or hash."""
        return self.fqn.strip("/")


@dataclass(frozen=True, slots=True)
class RosNode:
    """The node the daemon appears as in a robot's ROS graph, e.g. ``/robot1/twin_map_server``."""

    domain_id: int
    namespace: str
    name: str
    zid: str
    nid: int

    def node_token(self) -> str:
        return "/".join(
            [ADMIN_SPACE, str(self.domain_id), self.zid, str(self.nid), str(self.nid), "NN", SLASH,
             mangle(_namespace(self.namespace)), mangle(self.name)]
        )  # fmt: skip

    def publisher_token(self, topic: RosTopic, entity_id: int, qos: str) -> str:
        return self._entity_token("MP", topic, entity_id, qos)

    def subscriber_token(self, topic: RosTopic, entity_id: int, qos: str) -> str:
        """The token of a subscription (``MS``): ``ros2 topic info`` counts it as a subscriber."""
        return self._entity_token("MS", topic, entity_id, qos)

    def _entity_token(self, kind: str, topic: RosTopic, entity_id: int, qos: str) -> str:
        return "/".join(
            [ADMIN_SPACE, str(self.domain_id), self.zid, str(self.nid), str(entity_id), kind, SLASH,
             mangle(_namespace(self.namespace)), mangle(self.name), mangle(topic.fqn),
             mangle(dds_type_name(topic.type_name)), mangle(type_hash(topic.type_name)), qos]
        )  # fmt: skip


@dataclass(frozen=True, slots=True)
class ParsedToken:
    """A liveliness token as rmw_zenoh's graph cache reads it."""

    domain_id: int
    zid: str
    nid: str
    entity_id: str
    kind: str
    enclave: str
    namespace: str
    node: str
    topic: str | None = None
    type_name: str | None = None
    type_hash: str | None = None
    qos: dict[str, int | None] | None = None


def parse_qos(text: str) -> dict[str, int | None]:
    """``reliability:durability:history,depth:deadline:lifespan:liveliness`` (empty = rmw default)."""
    parts = text.split(":")
    if len(parts) < 6:
        msg = f"Not an rmw_zenoh QoS string (6 ':'-separated parts): {text!r}."
        raise MapError(msg)

    def num(s: str) -> int | None:
        return int(s) if s else None

    history = parts[2].split(",")
    return {
        "reliability": num(parts[0]),
        "durability": num(parts[1]),
        "history": num(history[0]),
        "depth": num(history[1]) if len(history) > 1 else None,
    }


def parse_token(key: str) -> ParsedToken:
    """Split a liveliness token into its parts (as rmw_zenoh's ``Entity::make(keyexpr)``)."""
    parts = key.split("/")
    if len(parts) < 9 or parts[0] != ADMIN_SPACE or any(not p for p in parts):
        msg = f"Not an rmw_zenoh liveliness token: {key!r}."
        raise MapError(msg)
    common = {
        "domain_id": int(parts[1]),
        "zid": parts[2],
        "nid": parts[3],
        "entity_id": parts[4],
        "kind": parts[5],
        "enclave": demangle(parts[6]),
        "namespace": demangle(parts[7]),
        "node": demangle(parts[8]),
    }
    if parts[5] == "NN":
        return ParsedToken(**common)  # type: ignore[arg-type]
    if len(parts) < 13:
        msg = f"A {parts[5]} liveliness token needs topic, type, hash and QoS: {key!r}."
        raise MapError(msg)
    return ParsedToken(
        **common,  # type: ignore[arg-type]
        topic=demangle(parts[9]),
        type_name=demangle(parts[10]),
        type_hash=demangle(parts[11]),
        qos=parse_qos(parts[12]),
    )


def gid_of(token: str) -> bytes:
    """A stable 16-byte gid for a publisher, derived from its liveliness token (as rmw_zenoh hashes it)."""
    return hashlib.blake2b(token.encode(), digest_size=16).digest()


def attachment(sequence: int, stamp_ns: int, gid: bytes) -> bytes:
    """rmw_zenoh's per-sample attachment: zenoh-ext serialisation of (int64 sequence number,
    int64 source timestamp in ns, 16-byte gid), 33 bytes (the gid's length 16 is one LEB128 byte)."""
    if len(gid) != 16:
        msg = f"A gid has 16 bytes, got {len(gid)}."
        raise MapError(msg)
    return struct.pack("<qqB", sequence, stamp_ns, 16) + gid


def parse_attachment(data: bytes) -> tuple[int, int, bytes]:
    """Inverse of :func:`attachment`; MapError if the layout is not rmw_zenoh's."""
    if len(data) != 33 or data[16] != 16:
        msg = f"Not an rmw_zenoh attachment (33 bytes, gid length 16): {len(data)} bytes."
        raise MapError(msg)
    sequence, stamp = struct.unpack_from("<qq", data)
    return int(sequence), int(stamp), bytes(data[17:])
