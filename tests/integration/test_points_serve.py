"""``twin serve`` with a points skill: each storey's cloud is latched on ``<prefix>/points/<storey>/<skill>``
as a CDR PointCloud2, and a door opened republishes the cloud without the door's voxels (a real daemon
process on loopback; the subscriber is this process's own Zenoh session)."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import numpy as np

from adapters.ros.pcd import decode_point_cloud2
from adapters.zenoh.client import TwinClient
from adapters.zenoh.latched import declare_latched_subscriber
from adapters.zenoh.points import points_key
from tests.integration.conftest import start_daemon
from tests.integration.test_daemon import TWIN, door_of

CONFIG = """
[skills.lidar3d]
kind = "points"
resolution_m = 0.2
exclude_types = ["IfcOpeningElement", "IfcFurnishingElement"]
exclude_materials = ["glass"]
"""


def test_the_daemon_latches_each_storeys_cloud_and_republishes_it_when_a_door_opens(
    fresh_store: Path, tmp_path: Path
) -> None:
    config = tmp_path / "points.toml"
    config.write_text(CONFIG)
    d = start_daemon(fresh_store, "--no-record", config=config)
    try:
        with TwinClient.connect([d.endpoint]) as client:
            got: list[tuple[np.ndarray, dict[str, int]]] = []
            arrived = threading.Condition()

            def on_sample(sample: object) -> None:
                xyz, _, frame_id = decode_point_cloud2(bytes(sample.payload))  # type: ignore[attr-defined]
                assert frame_id == "map"
                meta = json.loads(bytes(sample.attachment))  # type: ignore[attr-defined]
                with arrived:
                    got.append((xyz, meta))
                    arrived.notify_all()

            def wait_for(n: int) -> None:
                deadline = time.monotonic() + 30
                with arrived:
                    while len(got) < n and time.monotonic() < deadline:
                        arrived.wait(0.5)
                assert len(got) >= n, f"{len(got)} clouds after 30 s"

            key = points_key(client.keys.prefix, "ground-floor", "lidar3d")
            sub = declare_latched_subscriber(client.session, key, on_sample)  # a late joiner: history
            wait_for(1)
            first, meta = got[0]
            assert len(first) > 1000 and meta["version"] == 1
            assert first[:, 2].min() >= -0.05 - 1e-6  # z above the storey, from just below the floor's top
            ack = client.observe("robot1", f"<{door_of(client)}> <{TWIN}isOpen> true .")
            assert ack["ok"]
            wait_for(2)  # within the second the twin bounds republication to
            after, meta2 = got[1]
            assert meta2["version"] == 2 and meta2["revision"] > meta["revision"]
            assert 0 < len(first) - len(after) < len(first) // 10  # voxels only the door touched
            # every point that changed (gone, or the wall's now where the door's was) is at the door
            old, new = {tuple(p) for p in first.tolist()}, {tuple(p) for p in after.tolist()}
            changed = np.array(sorted(old ^ new))
            extent = changed[:, :2].max(axis=0) - changed[:, :2].min(axis=0)
            assert extent.max() < 1.6, extent  # a 0.9 m door, its frame, a voxel around it
            sub.undeclare()
    finally:
        d.process.terminate()
        d.process.wait(timeout=30)
