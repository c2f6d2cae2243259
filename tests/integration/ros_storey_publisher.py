"""A ROS 2 node that publishes its storey on ``/<ns>/storey`` (``std_msgs/msg/String``, latched), written
from the rmw_zenoh and zenoh-plugin-ros2dds sources (own process); the message is serialised by real
rclpy (``rclpy.serialization.serialize_message`` with std_msgs' typesupport).

Usage: python -m tests.integration.ros_storey_publisher ENDPOINT LAYOUT DOMAIN NAMESPACE

Each line read from stdin is a storey key to publish; prints ``{"sent": KEY}`` after each. LAYOUT
``rmw_zenoh``: an AdvancedPublisher (cache of 1, publisher detection: TRANSIENT_LOCAL) on rmw's data key
with the 33-byte attachment and a publisher liveliness token; ``bridge``: the same on ``<ns>/storey``
without attachment (what zenoh-bridge-ros2dds routes from a latched DDS publisher).
"""

from __future__ import annotations

import json
import sys
import time

import zenoh
import zenoh.ext
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from adapters.ros.rmw_zenoh import LATCHED_QOS, RosNode, RosTopic, attachment, gid_of
from adapters.zenoh.session import client_config


def main() -> int:
    endpoint, layout, domain, ns = sys.argv[1:]
    topic = RosTopic(int(domain), ns, "storey", "std_msgs/msg/String")
    rmw = layout == "rmw_zenoh"
    with zenoh.open(client_config([endpoint])) as session:
        node = RosNode(int(domain), ns, "lift_controller", str(session.zid()), 0)
        token = node.publisher_token(topic, 1, LATCHED_QOS)
        tokens = [session.liveliness().declare_token(t) for t in (node.node_token(), token)] if rmw else []
        pub = zenoh.ext.declare_advanced_publisher(
            session,
            topic.data_key if rmw else topic.bridge_key,
            cache=zenoh.ext.CacheConfig(max_samples=1),
            publisher_detection=True,
        )
        print(json.dumps({"ready": True}), flush=True)
        for sequence, line in enumerate(sys.stdin, start=1):
            payload = serialize_message(String(data=line.strip()))
            extra = {"attachment": attachment(sequence, time.time_ns(), gid_of(token))} if rmw else {}
            pub.put(payload, **extra)
            print(json.dumps({"sent": line.strip()}), flush=True)
        pub.undeclare()
        for t in tokens:
            t.undeclare()
    return 0


if __name__ == "__main__":
    sys.exit(main())
