"""How ``twin serve`` stops: a signal during start-up ends it at once with 130; a stop that cannot wait
for a SPARQL query in flight ends by ``[serve] stop_timeout_s`` with 124 and one line, after closing the
store, so every acked observation is kept."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from adapters.zenoh.client import TwinClient
from adapters.zenoh.errors import RemoteError
from tests.integration.conftest import ROOT, free_port, start_daemon

pytestmark = pytest.mark.slow

TWIN = "https://w3id.org/building-twin#"
ENDLESS = "SELECT (COUNT(*) AS ?n) WHERE { ?a ?p ?o . ?b ?q ?v . ?c ?r ?w . ?d ?s ?x }"
"""A query that runs for hours on the lab (every triple four times over: 2e11 rows)."""
SECONDS = f"SELECT (COUNT(*) AS ?n) WHERE {{ ?a ?p ?o . ?b ?q ?v . ?c <{TWIN}ifcClass> ?w }}"
"""A query that runs for about a second on the lab (1e7 rows)."""


def _table(x: float) -> str:
    return (f'<urn:stop:table> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "ground-floor" ; '
            f'<{TWIN}box> "{x} 7.0 0.375 0.6 0.6 0.75 0.0" .')  # fmt: skip


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_during_start_up_ends_it_within_a_second_with_130(fresh_store: Path, sig: int) -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "adapters.cli", "serve", "--store", str(fresh_store), "--no-record",
         "--no-snapshot", "--listen", f"tcp/127.0.0.1:{free_port()}"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    assert process.stdout is not None
    while (line := process.stdout.readline()) and "loading site" not in line:
        pass
    assert line, "the daemon ended before it began loading"
    t0 = time.monotonic()
    process.send_signal(sig)
    out, _ = process.communicate(timeout=30)
    seconds = time.monotonic() - t0
    assert "serving site" not in out, "the start-up finished before the signal: nothing was tested"
    assert process.returncode == 130, out
    assert "twin: interrupted" in out and "FATAL" not in out and "Traceback" not in out
    assert seconds < 1.0, f"{seconds:.2f} s"


def test_a_stop_past_stop_timeout_exits_124_naming_the_query_and_keeps_every_ack(
    fresh_store: Path, tmp_path: Path
) -> None:
    config = tmp_path / "stop.toml"
    config.write_text("[serve]\nstop_timeout_s = 1.0\n[limits]\nsparql_timeout_s = 60.0\n")
    d = start_daemon(fresh_store, "--no-record", config=config)
    asked = threading.Event()

    def ask_forever() -> None:
        try:
            with TwinClient.connect([d.endpoint], prefix="twin/lab", timeout_s=30) as asker:
                asked.set()
                asker.sparql(ENDLESS)
        except Exception:  # the daemon went away under the query: expected
            pass

    try:
        with TwinClient.connect([d.endpoint], prefix="twin/lab") as robot:
            ack = robot.observe("robot1", _table(16.6))
            assert ack["ok"] and ack["revision"] == 1
        asker = threading.Thread(target=ask_forever)
        asker.start()
        assert asked.wait(10)
        time.sleep(1.0)  # the query runs
        code, seconds = d.stop(signal.SIGTERM, timeout=30)
        asker.join(60)
    finally:
        if d.process.poll() is None:
            d.process.kill()
    assert code == 124, "\n".join(d.log)
    reason = [line for line in d.log if line.startswith("twin: stop:")]
    assert len(reason) == 1 and "SPARQL query" in reason[0] and "stop_timeout_s" in reason[0], d.log
    assert not any("FATAL" in line for line in d.log)
    assert 1.0 <= seconds < 10.0
    again = start_daemon(fresh_store, "--no-record")  # the store was closed: it opens, the ack is there
    try:
        with TwinClient.connect([again.endpoint], prefix="twin/lab") as robot:
            assert robot.status()["revision"] == 1
    finally:
        again.stop_cleanly()


def test_a_stop_waits_for_an_abandoned_query_that_ends_in_time_and_exits_0(
    fresh_store: Path, tmp_path: Path
) -> None:
    config = tmp_path / "stop.toml"
    config.write_text("[serve]\nstop_timeout_s = 30.0\n[limits]\nsparql_timeout_s = 0.3\n")
    d = start_daemon(fresh_store, "--no-record", config=config)
    with (
        TwinClient.connect([d.endpoint], prefix="twin/lab", timeout_s=30) as asker,
        pytest.raises(RemoteError, match=r"longer than 0.3 s and was abandoned"),
    ):
        asker.sparql(SECONDS)  # its worker runs on in the daemon for most of a second
    code, seconds = d.stop(signal.SIGINT, timeout=60)
    assert code == 0 and any("stopped cleanly" in line for line in d.log), d.log
    assert seconds >= 0.4  # it waited for the query's worker


def test_sigusr1_writes_every_threads_stack_and_the_daemon_serves_on_and_stops_cleanly(
    fresh_store: Path,
) -> None:
    from tests.integration.conftest import lines_until

    d = start_daemon(fresh_store, "--no-record", "--no-snapshot")
    try:
        d.process.send_signal(signal.SIGUSR1)
        lines = lines_until(d, lambda line: "serve_forever" in line, timeout_s=10)
        threads = [line for line in lines if line.startswith(("Thread 0x", "Current thread 0x"))]
        assert len(threads) >= 2 and any("serve_forever" in line for line in lines), "\n".join(lines)
        with TwinClient.connect([d.endpoint]) as client:
            assert client.status()["revision"] == 0
    finally:
        d.stop_cleanly()
