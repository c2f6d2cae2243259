"""Acknowledged observations survive kill -9 of the daemon; unacknowledged ones are all or nothing."""

from __future__ import annotations

import json
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from adapters.zenoh.client import TwinClient
from tests.integration.conftest import ROOT, Daemon, start_daemon
from twin.config import load_config
from twin.graph.store import EmbeddedStore
from twin.live import TwinService

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

KILLS = 5


def test_acked_observations_survive_repeated_kill_9_and_maps_equal_a_rebuild(fresh_store: Path) -> None:
    rng = random.Random(11)
    daemon = start_daemon(fresh_store, "--no-record")
    endpoint = daemon.endpoint
    robot = subprocess.Popen(
        [sys.executable, "-m", "tests.integration.robot", endpoint, "3"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    lines: list[str] = []
    assert robot.stdout is not None
    reader = threading.Thread(target=lambda: lines.extend(robot.stdout or []), daemon=True)
    reader.start()

    def acks_since(n: int) -> int:
        return sum('"acked": true' in line for line in lines[n:])

    try:
        for _ in range(KILLS):
            # kill while observations flow: wait for the robot to be acked again since the restart
            seen = len(lines)
            deadline = time.monotonic() + 30
            while acks_since(seen) < 2 and time.monotonic() < deadline:
                time.sleep(0.05)
            assert acks_since(seen) >= 2, "the robot is not acked after the daemon's restart"
            time.sleep(rng.uniform(0.05, 0.8))
            daemon.process.send_signal(signal.SIGKILL)
            daemon.process.wait(timeout=10)
            daemon = start_daemon(fresh_store, "--no-record", "--listen", endpoint)
        seen = len(lines)
        deadline = time.monotonic() + 30
        while acks_since(seen) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        assert robot.stdin is not None and robot.stderr is not None
        robot.stdin.close()
        robot.wait(timeout=30)
        reader.join(timeout=10)
        out, err = "".join(lines), robot.stderr.read()
    try:
        check(daemon, fresh_store, out, err)
    finally:
        if daemon.process.poll() is None:  # a failed check must not leave the daemon running
            daemon.process.kill()
            daemon.process.wait(timeout=10)


def check(daemon: Daemon, fresh_store: Path, out: str, err: str) -> None:
    attempts = [json.loads(line) for line in out.splitlines() if line.startswith("{")]
    acked = [a for a in attempts if a["acked"]]
    assert len(acked) >= 2 * (KILLS + 1), err

    with TwinClient.connect([daemon.endpoint]) as client:
        time.sleep(0.5)
        served = {(s, k): client.get_map(s, k)[0].data for s, k in client.list_maps()}
    assert daemon.stop()[0] == 0

    # per element: the states it may be in, "present" or "removed": the one its last acked change left,
    # or one that a later unacknowledged change left (applied in full, its ack lost with the daemon)
    allowed: dict[str, set[str]] = {}
    for a in attempts:
        kind = "removed" if a["op"] == "remove" else "present"
        if a["acked"]:
            allowed[a["iri"]] = {kind}
        elif a["iri"] in allowed:
            allowed[a["iri"]].add(kind)
    with EmbeddedStore.open(fresh_store) as store:
        rows = store.select(
            'SELECT ?e ?removed ?geom ?by WHERE { ?e twin:ifcClass "IfcFurniture" . '
            "FILTER(STRSTARTS(STR(?e), 'urn:robot:')) OPTIONAL { ?e twin:removed ?removed } "
            "OPTIONAL { ?e omg:hasGeometry ?geom } OPTIONAL { ?e twin:observedBy ?by } }"
        )
        present = {r["e"]: r for r in rows}
        for iri, kinds in allowed.items():
            row = present.get(iri)
            assert row is not None, f"acked {iri} lost"
            state = "removed" if row["removed"] == "true" else "present"
            assert state in kinds, f"{iri} is {state}, but its acked change left it {kinds}"
        for row in rows:  # nothing half-applied: an element has its geometry and provenance, or is removed
            assert row["by"] == "robot1"
            assert (row["geom"] is None) == (row["removed"] == "true"), row
        service = TwinService(store, load_config())
        service.start()
        for key, m in service.live_maps.skill_maps.items():
            np.testing.assert_array_equal(served[key], m.data, err_msg=str(key))
    print(f"{len(acked)} acked of {len(attempts)} attempts across {KILLS} kills")
