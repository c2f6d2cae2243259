"""A ROS 2 map subscriber written from the rmw_zenoh and zenoh-plugin-ros2dds sources (own process);
maps are decoded by real rclpy (``rclpy.serialization.deserialize_message`` with nav_msgs' typesupport).

Usage: python -m tests.integration.ros_subscriber ENDPOINT LAYOUT DOMAIN NAMESPACE OUT_DIR [TOPIC]

LAYOUT ``rmw_zenoh``: an AdvancedSubscriber with history (depth 1), late-publisher detection, recovery
by heartbeat and subscriber detection on the rmw data key of ``<ns>/<topic>`` (as
rmw_subscription_data.cpp does for RELIABLE + TRANSIENT_LOCAL), and a subscriber on
``<ns>/<topic>_updates``; every sample must carry the 33-byte attachment (checked with zenoh-ext's own
deserialiser). LAYOUT ``bridge``: the same on ``<ns>/<topic>`` and ``<ns>/<topic>_updates`` without
attachment. TOPIC defaults to ``map``. Prints a JSON line per sample; on EOF of stdin saves the map copy
(updates applied) to OUT_DIR/map.npy.
"""

from __future__ import annotations

import json
import sys
import threading
from pathlib import Path

import numpy as np
import zenoh
import zenoh.ext
from nav_msgs.msg import OccupancyGrid as RosOccupancyGrid
from rclpy.serialization import deserialize_message

from adapters.ros import decode_occupancy_grid_update
from adapters.ros.cdr import OCCUPANCY_GRID, OCCUPANCY_GRID_UPDATE
from adapters.ros.rmw_zenoh import RosTopic
from adapters.zenoh.session import client_config


def main() -> int:
    endpoint, layout, domain, ns, out, *rest = sys.argv[1:]
    name = rest[0] if rest else "map"
    maps = RosTopic(int(domain), ns, name, OCCUPANCY_GRID)
    updates = RosTopic(int(domain), ns, f"{name}_updates", OCCUPANCY_GRID_UPDATE)
    rmw = layout == "rmw_zenoh"
    key_map, key_upd = (maps.data_key, updates.data_key) if rmw else (maps.bridge_key, updates.bridge_key)
    lock = threading.Lock()
    state: dict[str, np.ndarray] = {}

    def check(sample: zenoh.Sample) -> dict[str, object]:
        info: dict[str, object] = {"key": str(sample.key_expr)}
        if rmw:
            assert sample.attachment is not None, "rmw_zenoh drops samples without attachment"
            raw = sample.attachment.to_bytes()
            seq, stamp, gid = zenoh.ext.z_deserialize(
                tuple[zenoh.ext.Int64, zenoh.ext.Int64, bytes], sample.attachment
            )
            assert len(raw) == 33 and len(gid) == 16
            info.update(seq=int(seq), stamp=int(stamp), gid=bytes(gid).hex())
        return info

    def on_map(sample: zenoh.Sample) -> None:
        info = check(sample)
        msg = deserialize_message(sample.payload.to_bytes(), RosOccupancyGrid)
        grid = np.asarray(msg.data, dtype=np.int8).reshape(msg.info.height, msg.info.width)
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        with lock:
            state["grid"] = grid.copy()
            line = {"kind": "map", "stamp_ns": stamp, "width": int(msg.info.width),
                    "height": int(msg.info.height), "occupied": int((grid == 100).sum()), **info}  # fmt: skip
            print(json.dumps(line), flush=True)

    def on_update(sample: zenoh.Sample) -> None:
        info = check(sample)
        window, cells, _ = decode_occupancy_grid_update(sample.payload.to_bytes())
        with lock:
            if "grid" in state:
                state["grid"][window.row0 : window.row1, window.col0 : window.col1] = cells
            print(json.dumps({"kind": "update", "x": window.col0, "y": window.row0, **info}), flush=True)

    with zenoh.open(client_config([endpoint])) as session:
        sub_map = zenoh.ext.declare_advanced_subscriber(  # rmw: depth 1, RELIABLE: recovery by heartbeat
            session,
            key_map,
            on_map,
            history=zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=1),
            recovery=zenoh.ext.RecoveryConfig(heartbeat=True) if rmw else None,
            subscriber_detection=rmw,
        )
        sub_upd = session.declare_subscriber(key_upd, on_update)
        print(json.dumps({"ready": True, "key": key_map}), flush=True)
        sys.stdin.read()
        with lock:
            if "grid" in state:
                np.save(Path(out) / "map.npy", state["grid"])
        sub_map.undeclare()
        sub_upd.undeclare()
    return 0


if __name__ == "__main__":
    sys.exit(main())
