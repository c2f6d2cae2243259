"""A supervisor that pipes the daemon's output and never reads it: the pipe (64 KiB) fills with log
lines, and the daemon goes on acking observations (its output is written by a thread of its own:
``adapters/cli/log_outlet.py``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from adapters.zenoh.client import TwinClient
from adapters.zenoh.errors import RemoteError
from tests.integration.conftest import start_daemon

pytestmark = pytest.mark.slow

TWIN = "https://w3id.org/building-twin#"
LONG = "x" * 1500  # each refusal logs a warning naming the IRI: about 1.6 KB a line


def test_a_daemon_whose_output_is_never_read_acks_observations_after_far_more_than_a_pipe_of_log_lines(
    fresh_store: Path,
) -> None:
    d = start_daemon(fresh_store, "--no-record")  # reads up to "serving site", then never again
    try:
        with TwinClient.connect([d.endpoint], prefix="twin/lab", timeout_s=20) as robot:
            for i in range(400):  # about 640 KB of warnings: ten pipes' worth
                with pytest.raises(RemoteError, match="is not an IFC element class"):
                    robot.observe("robot1", f'<urn:{LONG}:{i}> <{TWIN}ifcClass> "IfcNothing" .')
            ack = robot.observe(
                "robot1",
                f'<urn:twin:robot1:t> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "ground-floor" ; '
                f'<{TWIN}box> "16.0 7.0 0.375 0.6 0.6 0.75 0.0" .',
            )
            assert ack["ok"] and ack["revision"] == 1
            log = robot.status()["log"]
            assert isinstance(log, dict)
            assert log["queued"] + log["dropped"] > 300, log  # held or dropped, never blocking
        d.stop_cleanly()  # its output is read now: the lines held come out, in order
        warnings = [line for line in d.log if "is not an IFC element class" in line]
        assert len(warnings) == 400 - log["dropped"]
        assert d.log[-1].startswith("stopped cleanly")
    finally:
        d.stop_cleanly()
