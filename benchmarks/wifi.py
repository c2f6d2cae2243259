"""Robots on Wi-Fi: bytes per second per map topic under a steady move rate, and a late joiner's time to
the map over a slow link.

Per model (the generated lab, Janesville): ``twin serve`` as a process with one ROS 2 robot
(``[robots.robot1] namespace = "/robot1"``, both layouts); in this process a plain Zenoh session counts
every sample on the daemon's keys (``twin/**``, ``robot1/**``, ``0/robot1/**``: native, bridge and
rmw_zenoh layouts), and a robot moves a table around the busiest storey at ``--rate`` acked
observations a second for ``--duration`` s. Per map topic: full maps received, their bytes, update bytes,
and KB/s over the run. Half-way through, a robot joins late through an emulated link
(:mod:`tests.integration.throttle`, ``--link-mbit`` and ``--link-ms``): the time from its session's
open to its first ``/robot1/navigation_map`` (rmw_zenoh layout), and whether every later update came
in order.

``--code DIR`` runs the daemon from another checkout (e.g. the commit before the change, exported with
``git archive``), for the "before" row.

Usage::

    python benchmarks/wifi.py [--models lab janesville] [--rate 20] [--duration 10] [--json OUT.json]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import subprocess
import sys
import tempfile
import threading
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
import live  # benchmarks/ is not a package

ROOT = live.ROOT
sys.path.insert(0, str(ROOT))


def _kind(key: str) -> str | None:
    """'update', 'full' or None (heartbeats, storeys, filter info: not counted) for a sample's key."""
    parts = key.split("/")
    if "@adv" in parts or len(parts) < 2:
        return None
    if parts[0] == "twin":  # twin/<site>/map[_updates]/<storey>/<skill>
        return {"map": "full", "map_updates": "update"}.get(parts[2]) if len(parts) == 5 else None
    topic = parts[2] if parts[0].isdigit() else parts[1]  # rmw: <domain>/<ns>/<topic>/..; bridge: <ns>/<topic>
    if topic.endswith("_updates"):
        return "update"
    return None if topic in ("storey",) or topic.endswith("_info") else "full"


def _topic(key: str) -> str:
    """The topic a key belongs to, updates with their map: native, bridge or rmw key without type."""
    parts = key.split("/")
    if parts[0] == "twin":  # twin/<site>/map[_updates]/<storey>/<skill>
        return f"native {parts[3]}/{parts[4]}"
    if parts[0].isdigit():  # rmw_zenoh: <domain>/robot1/<topic>/<type>/<hash>
        return f"rmw /{parts[1]}/{parts[2].removesuffix('_updates')}"
    return f"bridge /{parts[0]}/{parts[1].removesuffix('_updates')}"


def run_model(name: str, rate: float, duration: float, link_mbit: float, link_ms: float,
              code: Path | None) -> dict[str, Any]:  # fmt: skip
    import numpy as np
    import zenoh
    import zenoh.ext

    from adapters.ros import decode_occupancy_grid_update
    from adapters.ros.cdr import OCCUPANCY_GRID, OCCUPANCY_GRID_UPDATE
    from adapters.ros.rmw_zenoh import RosTopic
    from adapters.zenoh.client import TwinClient
    from adapters.zenoh.session import client_config
    from tests.integration.throttle import ThrottlingProxy

    work = Path(tempfile.mkdtemp(prefix="twin-wifi-"))
    store = live.prepare_store(name, work)
    storey, (x0, y0, x1, y1), _ = live.busiest(store)
    config = work / "robot.toml"
    config.write_text(f'[robots.robot1]\nnamespace = "/robot1"\nstorey = "{storey}"\n')
    port = live._free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    env = dict(os.environ)
    cwd = ROOT
    if code is not None:
        env["PYTHONPATH"], cwd = str(code), code
    daemon = subprocess.Popen(
        [sys.executable, "-m", "adapters.cli", "--config", str(config), "serve", "--store", str(store),
         "--listen", endpoint, "--no-record", "--no-snapshot"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=cwd,
        env={**env, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    assert daemon.stdout is not None
    line = ""
    while "serving site" not in line:
        line = daemon.stdout.readline()
        if not line:
            raise RuntimeError(f"the daemon did not start: exit code {daemon.wait()}")
    threading.Thread(target=lambda: [None for _ in daemon.stdout or []], daemon=True).start()
    counts: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    lock = threading.Lock()
    counting = threading.Event()

    def on_sample(sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        kind = _kind(key)
        if kind is None or not counting.is_set():
            return
        with lock:
            c = counts[_topic(key)]
            c[f"{kind}_messages"] += 1
            c[f"{kind}_bytes"] += len(sample.payload)

    session = zenoh.open(client_config([endpoint]))
    subs = [session.declare_subscriber(k, on_sample) for k in ("twin/**", "robot1/**", "0/robot1/**")]
    time.sleep(1.0)
    rng = random.Random(7)
    slow: dict[str, Any] = {}
    w, h = x1 - x0, y1 - y0
    try:
        with TwinClient.connect([endpoint], timeout_s=10.0) as twin:
            counting.set()
            t0 = time.monotonic()
            sent = 0
            joiner: threading.Thread | None = None
            while (now := time.monotonic()) < t0 + duration:
                due = t0 + sent / rate
                time.sleep(max(0.0, due - now))
                x, y = x0 + w * (0.3 + 0.4 * rng.random()), y0 + h * (0.3 + 0.4 * rng.random())
                twin.observe("robot1", live._table(storey, round(x, 3), round(y, 3), sent))
                sent += 1
                if joiner is None and time.monotonic() - t0 >= duration / 2:
                    joiner = threading.Thread(
                        target=_slow_joiner,
                        args=(port, link_mbit, link_ms, slow, np, zenoh, client_config, ThrottlingProxy,
                              RosTopic, OCCUPANCY_GRID, OCCUPANCY_GRID_UPDATE, decode_occupancy_grid_update,
                              t0 + duration + 3.0),
                        daemon=True,
                    )  # fmt: skip
                    joiner.start()
            elapsed = time.monotonic() - t0
            time.sleep(1.0)  # the last samples
            counting.clear()
            if joiner is not None:
                joiner.join(timeout=30)
    finally:
        for s in subs:
            s.undeclare()
        session.close()
        daemon.terminate()
        daemon.wait(timeout=30)
    window = elapsed + 1.0
    topics = {}
    for topic, c in sorted(counts.items()):
        total = c["full_bytes"] + c["update_bytes"]
        topics[topic] = {
            "full_maps": c["full_messages"],
            "full_kb": round(c["full_bytes"] / 1024, 1),
            "updates": c["update_messages"],
            "update_kb": round(c["update_bytes"] / 1024, 1),
            "kb_per_s": round(total / 1024 / window, 1),
        }
    return {"model": live.model_label(name), "storey": storey, "moves": sent, "seconds": round(elapsed, 2),
            "rate": round(sent / elapsed, 1), "topics": topics, "slow_link": slow}  # fmt: skip


def _slow_joiner(port: int, mbit: float, ms: float, out: dict[str, Any], np: Any, zenoh: Any,
                 client_config: Any, proxy_type: Any, topic_type: Any, grid_type: str, update_type: str,
                 decode_update: Any, until: float) -> None:  # fmt: skip
    """Join late through the emulated link: time to the navigation map, updates in order after it."""
    maps = topic_type(0, "/robot1", "navigation_map", grid_type)
    updates = topic_type(0, "/robot1", "navigation_map_updates", update_type)
    got: dict[str, Any] = {"map_at": None, "maps": 0, "updates": 0, "seqs": []}
    with proxy_type(("127.0.0.1", port), rate_bps=mbit * 1e6, latency_s=ms / 1000) as proxy:
        t0 = time.monotonic()
        session = zenoh.open(client_config([f"tcp/127.0.0.1:{proxy.port}"]))

        def on_map(sample: Any) -> None:
            got["maps"] += 1
            if got["map_at"] is None:
                got["map_at"] = time.monotonic() - t0
                got["map_bytes"] = len(sample.payload)

        def on_update(sample: Any) -> None:
            if got["map_at"] is not None:
                got["updates"] += 1
                got["seqs"].append(int.from_bytes(sample.attachment.to_bytes()[:8], "little"))

        up = session.declare_subscriber(updates.data_key, on_update)
        sub = zenoh.ext.declare_advanced_subscriber(
            session, maps.data_key, on_map, history=zenoh.ext.HistoryConfig(detect_late_publishers=True)
        )
        time.sleep(max(0.0, until - time.monotonic()))
        sub.undeclare()
        up.undeclare()
        session.close()
        seqs = got.pop("seqs")
        out.update(got, link=f"{mbit:g} Mbit/s, {ms:g} ms", connections=proxy.accepted,
                   updates_in_order=seqs == sorted(seqs) and len(set(seqs)) == len(seqs))  # fmt: skip


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", nargs="+", default=["lab", "janesville"])
    ap.add_argument("--rate", type=float, default=20.0)
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--link-mbit", type=float, default=20.0)
    ap.add_argument("--link-ms", type=float, default=20.0)
    ap.add_argument("--code", type=Path, help="run the daemon from this checkout (the 'before' row)")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    rows = []
    for name in args.models:
        if name == "janesville" and not live.MODELS["janesville"].exists():  # type: ignore[union-attr]
            print("Janesville is not in the shared corpus here: skipped", file=sys.stderr)
            continue
        print(f"{name}: measuring ...", file=sys.stderr, flush=True)
        rows.append(run_model(name, args.rate, args.duration, args.link_mbit, args.link_ms, args.code))
    print("| model | topic | full maps | full KB | updates | update KB | KB/s |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        for topic, t in r["topics"].items():
            print(f"| {r['model']} | {topic} | {t['full_maps']} | {t['full_kb']} | {t['updates']} | "
                  f"{t['update_kb']} | {t['kb_per_s']} |")  # fmt: skip
    for r in rows:
        print(f"{r['model']}: {r['moves']} moves in {r['seconds']} s ({r['rate']}/s); slow link: {r['slow_link']}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
