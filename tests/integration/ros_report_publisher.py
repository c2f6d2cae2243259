"""A ROS 2 robot (or building system) that publishes what it sees, written from the rmw_zenoh and
zenoh-plugin-ros2dds sources (own process).

Usage: python -m tests.integration.ros_report_publisher ENDPOINT LAYOUT DOMAIN

Each stdin line is JSON ``{"topic": "/robot1/tf", "type": "tf2_msgs/msg/TFMessage", "hex": CDR,
"latched": false}``; prints ``{"sent": N}`` after each. LAYOUT ``rmw_zenoh``: rmw's data key with the type
and its RIHS01 hash (``"type_key"`` may name another type for the key, to publish a wrong type), the
33-byte attachment and a publisher liveliness token; latched topics from an AdvancedPublisher with a
cache (TRANSIENT_LOCAL). ``bridge``: key ``<ns>/<topic>``, payload the CDR bytes, no attachment.
"""

from __future__ import annotations

import json
import sys
import time
from typing import Any

import zenoh
import zenoh.ext

from adapters.ros.rmw_zenoh import DEFAULT_QOS, LATCHED_QOS, RosNode, RosTopic, attachment, gid_of
from adapters.zenoh.session import client_config


def main() -> int:
    endpoint, layout, domain = sys.argv[1:]
    rmw = layout == "rmw_zenoh"
    publishers: dict[tuple[str, str], tuple[Any, bytes | None, list[int]]] = {}
    tokens: list[Any] = []
    with zenoh.open(client_config([endpoint])) as session:
        zid = str(session.zid())
        print(json.dumps({"ready": True}), flush=True)
        for count, line in enumerate(sys.stdin, start=1):
            m = json.loads(line)
            ns, _, name = m["topic"].rpartition("/")
            type_name = m.get("type_key") or m["type"]
            entry = publishers.get((m["topic"], type_name))
            if entry is None:
                topic = RosTopic(int(domain), ns or "/", name, type_name)
                key = topic.data_key if rmw else topic.bridge_key
                pub = (
                    zenoh.ext.declare_advanced_publisher(
                        session, key, cache=zenoh.ext.CacheConfig(max_samples=1), publisher_detection=True
                    )
                    if m.get("latched")
                    else session.declare_publisher(key, reliability=zenoh.Reliability.RELIABLE)
                )
                gid = None
                if rmw:
                    node = RosNode(int(domain), ns or "/", "robot_driver", zid, len(publishers))
                    token = node.publisher_token(topic, 1, LATCHED_QOS if m.get("latched") else DEFAULT_QOS)
                    tokens += [session.liveliness().declare_token(t) for t in (node.node_token(), token)]
                    gid = gid_of(token)
                entry = publishers[(m["topic"], type_name)] = (pub, gid, [0])
                time.sleep(0.3)  # let the daemon's subscription meet the new publisher
            pub, gid, sequence = entry
            sequence[0] += 1
            extra = {"attachment": attachment(sequence[0], time.time_ns(), gid)} if gid is not None else {}
            pub.put(bytes.fromhex(m["hex"]), **extra)
            print(json.dumps({"sent": count}), flush=True)
        for pub, _, _ in publishers.values():
            pub.undeclare()
        for t in tokens:
            t.undeclare()
    return 0


if __name__ == "__main__":
    sys.exit(main())
