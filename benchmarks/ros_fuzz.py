"""Hostile ROS 2 input at a running daemon: ``--payloads`` mutated Detection3DArray, TFMessage,
DoorState and Obstacles payloads on both layouts (``tests/integration/ros_fuzz_publisher.py``, its own
process, congestion control BLOCK, ``--rate`` per second) against ``twin serve`` on the generated lab.

Prints what was sent and what the daemon counted (``received`` includes the queue's ``overflow``),
the revisions against the accepted observations (refused payloads must change nothing), the daemon's
RSS every 10 % of the run, and whether it is still serving.

    nice -n 10 python benchmarks/ros_fuzz.py --payloads 100000 --rate 1500 --json fuzz.json
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
import live  # benchmarks/ is not a package

ROOT = live.ROOT
OWNERS = ("robot1", "doors", "obstacles")


def ingested(status: dict[str, Any], owner: str) -> int:
    """Messages of ``owner`` the daemon accounted for (handled, or dropped by a full queue)."""
    return int(status["ros_ingest"]["counts"][owner]["received"])


def run(payloads: int, rate: float, seed: int) -> dict[str, Any]:
    sys.path.insert(0, str(ROOT))
    from adapters.zenoh.client import TwinClient
    from adapters.zenoh.errors import RemoteError
    from tests.integration.ros_fuzz_publisher import CONFIG

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        store = live.prepare_store("lab", work)
        cfg = work / "robots.toml"
        cfg.write_text(CONFIG)
        endpoint = f"tcp/127.0.0.1:{live._free_port()}"
        serve = ("serve", "--store", str(store), "--listen", endpoint, "--no-record")
        log = work / "daemon.log"  # a file: a pipe nobody reads would stall the daemon's logging
        with log.open("w") as out:
            daemon = subprocess.Popen(
                live._twin("--config", str(cfg), *serve), stdout=out, stderr=subprocess.STDOUT, cwd=ROOT
            )
        while "serving site" not in log.read_text():
            if daemon.poll() is not None:
                raise RuntimeError(f"the daemon did not start: exit code {daemon.wait()}")
            time.sleep(0.1)
        robot: subprocess.Popen[str] | None = None
        try:
            with TwinClient.connect([endpoint], timeout_s=30.0) as client:
                status0 = client.status()  # before the robot starts
            before = {o: ingested(status0, o) for o in OWNERS}
            robot = subprocess.Popen(
                [sys.executable, "-m", "tests.integration.ros_fuzz_publisher", endpoint,
                 *map(str, (payloads, seed, rate))],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=ROOT,
            )  # fmt: skip
            assert robot.stdout is not None and robot.stdin is not None
            assert json.loads(robot.stdout.readline())["ready"]
            rss: list[float] = []
            t0 = time.monotonic()
            timeouts = 0
            with TwinClient.connect([endpoint], timeout_s=30.0) as client:
                mark = 0
                while True:
                    try:
                        status = client.status()
                    except RemoteError:  # counted: the status should answer under any load
                        timeouts += 1
                        continue
                    total = sum(ingested(status, o) - before[o] for o in OWNERS)
                    while total >= mark * payloads / 10 and mark <= 10:
                        rss.append(round(live._proc_mb(daemon.pid, "VmRSS"), 1))
                        mark += 1
                    if (
                        total >= payloads
                        or daemon.poll() is not None
                        or time.monotonic() - t0 > payloads / rate * 3
                    ):
                        break
                    time.sleep(0.5)
                elapsed = time.monotonic() - t0
                sent = json.loads(robot.stdout.readline())
                robot.stdin.close()
                robot.wait(timeout=30)
                time.sleep(1.5)
                status = client.status()
                counts = {o: status["ros_ingest"]["counts"][o] for o in OWNERS}
                accepted = sum(c["accepted"] for c in counts.values()) - sum(
                    status0["ros_ingest"]["counts"][o]["accepted"] for o in OWNERS
                )
                grid, _, _ = client.get_map("ground-floor", "navigation")
            alive = daemon.poll() is None
            daemon.terminate()
            daemon.wait(timeout=60)
            out = log.read_text()
            refused: dict[str, int] = {}
            for c in counts.values():
                for k, v in c["refused"].items():
                    refused[k] = refused.get(k, 0) + v
            return {
                "payloads": payloads,
                "rate_per_s": rate,
                "elapsed_s": round(elapsed, 1),
                "sent": sent["sent"],
                "mutations": sent["mutations"],
                "counted": sum(ingested(status, o) - before[o] for o in OWNERS),
                "counted_per_owner_equals_sent": {o: ingested(status, o) - before[o] for o in OWNERS}
                == sent["owners"],
                "accepted": accepted,
                "revisions": status["revision"] - status0["revision"],
                "refused": dict(sorted(refused.items())),
                "rss_mb_every_10pct": rss,
                "alive_and_serving_maps": alive and grid.data.size > 0,
                "exit_code": daemon.returncode,
                "status_timeouts_30s": timeouts,
                "tracebacks": sum("Traceback" in line for line in out.splitlines()),
            }
        finally:  # nothing left running, whatever failed
            for p in (robot, daemon):
                if p is not None and p.poll() is None:
                    p.kill()
                    p.wait()


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--payloads", type=int, default=100_000)
    p.add_argument("--rate", type=float, default=1500.0)
    p.add_argument("--seed", type=int, default=37)
    p.add_argument("--json", type=Path)
    a = p.parse_args()
    result = run(a.payloads, a.rate, a.seed)
    for key, value in result.items():
        print(f"{key:32} {value}")
    if a.json:
        a.json.write_text(json.dumps(result, indent=1))
    ok = result["counted_per_owner_equals_sent"] and result["accepted"] == result["revisions"]
    return 0 if ok and result["alive_and_serving_maps"] and result["tracebacks"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
