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
    topic = (
        parts[2] if parts[0].isdigit() else parts[1]
    )  # rmw: <domain>/<ns>/<topic>/..; bridge: <ns>/<topic>
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


def run_model(name: str, args: argparse.Namespace) -> dict[str, Any]:
    rate, duration, code = args.rate, args.duration, args.code
    import zenoh
    import zenoh.ext

    from adapters.zenoh.client import TwinClient
    from adapters.zenoh.session import client_config

    work = Path(tempfile.mkdtemp(prefix="twin-wifi-"))
    store = live.prepare_store(name, work)
    storey, (x0, y0, x1, y1), _ = live.busiest(store)
    config = work / "robot.toml"
    config.write_text(
        f'[robots.robot1]\nnamespace = "/robot1"\nstorey = "{storey}"\n'
        f'[robots.robot2]\nnamespace = "/robot2"\nstorey = "{storey}"\nros = ["rmw_zenoh"]\n'
        '[robots.robot2.maps]\nnavigation_map = "navigation"\n'
    )
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

    delays: list[tuple[float, float]] = []  # robot2's updates: (arrival, arrival - commit stamp in ms)

    def on_robot2(sample: zenoh.Sample) -> None:
        if counting.is_set() and _kind(str(sample.key_expr)) == "update" and sample.attachment is not None:
            stamp = int.from_bytes(sample.attachment.to_bytes()[8:16], "little")
            delays.append((time.monotonic(), (time.time_ns() - stamp) / 1e6))

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
    subs.append(session.declare_subscriber("0/robot2/**", on_robot2))
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
                        target=_slow_joiner, args=(port, args, slow, t0 + duration + 3.0), daemon=True
                    )
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
    joined = slow.pop("joined", None)
    during = [d for t, d in delays if joined is not None and joined[0] <= t <= joined[1]]
    others = [d for t, d in delays if joined is None or not joined[0] <= t <= joined[1]]
    slow["robot2_update_ms"] = {
        "while_joining": [len(during), round(max(during, default=float("nan")), 1)],
        "otherwise_p50_p99_max": [round(live._pct(others, 50), 1), round(live._pct(others, 99), 1),
                                  round(max(others, default=float("nan")), 1)],
    }  # fmt: skip
    return {"model": live.model_label(name), "storey": storey, "moves": sent, "seconds": round(elapsed, 2),
            "rate": round(sent / elapsed, 1), "topics": topics, "slow_link": slow}  # fmt: skip


def _slow_joiner(port: int, args: argparse.Namespace, out: dict[str, Any], until: float) -> None:
    """Join late through the emulated link: time to the navigation map, updates in order after it."""
    import zenoh
    import zenoh.ext

    from adapters.ros.cdr import OCCUPANCY_GRID, OCCUPANCY_GRID_UPDATE
    from adapters.ros.rmw_zenoh import RosTopic
    from adapters.zenoh.session import client_config
    from tests.integration.throttle import ThrottlingProxy

    mbit, ms = args.link_mbit, args.link_ms
    maps = RosTopic(0, "/robot1", "navigation_map", OCCUPANCY_GRID)
    updates = RosTopic(0, "/robot1", "navigation_map_updates", OCCUPANCY_GRID_UPDATE)
    got: dict[str, Any] = {"map_at": None, "maps": 0, "updates": 0, "seqs": []}
    with ThrottlingProxy(("127.0.0.1", port), rate_bps=mbit * 1e6, latency_s=ms / 1000) as proxy:
        t0 = time.monotonic()
        session = zenoh.open(client_config([f"tcp/127.0.0.1:{proxy.port}"]))

        def on_map(sample: Any) -> None:
            got["maps"] += 1
            if got["map_at"] is None:
                got["map_at"] = time.monotonic() - t0
                out["joined"] = (t0, time.monotonic())
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
        rows.append(run_model(name, args))
    print("| model | topic | full maps | full KB | updates | update KB | KB/s |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        for topic, t in r["topics"].items():
            print(f"| {r['model']} | {topic} | {t['full_maps']} | {t['full_kb']} | {t['updates']} | "
                  f"{t['update_kb']} | {t['kb_per_s']} |")  # fmt: skip
    for r in rows:
        moves = f"{r['moves']} moves in {r['seconds']} s ({r['rate']}/s)"
        print(f"{r['model']}: {moves}; slow link: {r['slow_link']}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
