"""Hostile ROS 2 input at a running daemon: 10,000 mutated Detection3DArray, TFMessage, DoorState and
Obstacles payloads on both layouts (``ros_fuzz_publisher``, its own process, congestion control BLOCK)
leave the daemon serving; every payload is counted; the graph changes only by what the daemon accepted
(the few valid or still-valid ones); memory stays flat. ``benchmarks/ros_fuzz.py`` runs 100,000.

The daemon is a black box here: its status JSON, its maps and SPARQL. The ingestion's counters are read
by :func:`ingested` and :func:`accepted` alone, so that a change of their names touches only those.
"""

from __future__ import annotations

import json
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from adapters.zenoh.client import TwinClient
from tests.integration.conftest import Daemon, JsonLinesProcess, start_daemon
from tests.integration.ros_fuzz_publisher import CONFIG

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

PAYLOADS = 10_000
RATE = 1500
"""Payloads per second: about a third more than the ingestion handles here, so the queue overflows too."""
OWNERS = ("robot1", "doors", "obstacles")
RSS_GROWTH_MAX_KIB = 32 * 1024


def ingested(status: dict[str, Any], owner: str) -> int:
    """Messages of ``owner`` the daemon accounted for: handled, or dropped because its ingestion queue
    was full (``overflow``; this daemon counts those in ``received`` too)."""
    c = status["ros_ingest"]["counts"][owner]
    return int(c["received"])


def accepted(status: dict[str, Any], owner: str) -> int:
    """Observations of ``owner`` that changed the twin (one revision each)."""
    return int(status["ros_ingest"]["counts"][owner]["accepted"])


def rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise AssertionError(f"no VmRSS for process {pid}")


def drain(d: Daemon) -> threading.Thread:
    """Read the daemon's output as it comes (into ``d.log``): each refusal by the core is a warning, and a
    pipe nobody reads would stall the daemon's logging once full."""
    stream = d.process.stdout
    assert stream is not None
    reader = threading.Thread(target=lambda: d.log.extend(line.rstrip() for line in stream), daemon=True)
    reader.start()
    return reader


@pytest.fixture
def hostile_daemon(fresh_store: Path, tmp_path: Path) -> Iterator[Daemon]:
    path = tmp_path / "robots.toml"
    path.write_text(CONFIG)
    d = start_daemon(fresh_store, "--no-record", config=path)
    yield d
    d.stop_cleanly()


def test_ten_thousand_hostile_ros_payloads_are_counted_and_change_only_what_was_accepted(
    hostile_daemon: Daemon,
) -> None:
    d = hostile_daemon
    reader = drain(d)
    with TwinClient.connect([d.endpoint]) as client:
        status0 = client.status()
        revision0 = status0["revision"]
        before = {o: ingested(status0, o) for o in OWNERS}
        robot = JsonLinesProcess(
            "tests.integration.ros_fuzz_publisher", d.endpoint, str(PAYLOADS), "37", str(RATE)
        )
        while "ready" not in robot.next():  # a line may come first: it starts before "ready"
            pass
        rss: list[int] = []
        deadline = time.monotonic() + 90
        while True:
            status = client.status()
            total = sum(ingested(status, o) - before[o] for o in OWNERS)
            if not rss and total >= PAYLOADS // 5:
                rss.append(rss_kib(d.process.pid))  # after the warm-up: caches and queues filled
            if total >= PAYLOADS:
                break
            assert d.process.poll() is None, "the daemon died"
            assert time.monotonic() < deadline, json.dumps(status["ros_ingest"], indent=1)
            time.sleep(0.2)
        sent = robot.next()
        assert sent["sent"] == PAYLOADS
        robot.close_stdin_and_wait()
        status = client.status()
        assert {o: ingested(status, o) - before[o] for o in OWNERS} == sent["owners"]

        def changed(status: dict[str, Any]) -> int:
            return sum(accepted(status, o) - accepted(status0, o) for o in OWNERS)

        # refused payloads changed nothing: one revision per accepted observation, once none is in flight
        # (valid obstacles live 1 s: their removals are accepted observations too, whenever they come)
        deadline = time.monotonic() + 30
        while status["ros_ingest"]["queue_depth"] or status["revision"] - revision0 != changed(status):
            assert time.monotonic() < deadline, (status["revision"] - revision0, changed(status))
            time.sleep(0.2)
            status = client.status()
        grid, _, _ = client.get_map("ground-floor", "navigation")  # still serving maps
        assert grid.data.size > 0
        rows = client.sparql("SELECT (COUNT(*) AS ?n) WHERE { ?s ?p ?o }")
        assert isinstance(rows, dict) and int(rows["results"]["bindings"][0]["n"]["value"]) > 0
        rss.append(rss_kib(d.process.pid))
    assert rss[1] - rss[0] < RSS_GROWTH_MAX_KIB, f"RSS grew from {rss[0]} to {rss[1]} KiB"
    d.process.send_signal(signal.SIGTERM)
    code = d.process.wait(timeout=30)
    reader.join(timeout=10)
    assert code == 0 and not [line for line in d.log if "FATAL" in line], "\n".join(d.log[-30:])
    failures = [line for line in d.log if "Traceback" in line or "ingestion failed" in line]
    assert not failures, "\n".join(d.log[-40:])
