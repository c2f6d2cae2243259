"""A short load run (the benchmark's full one: ``benchmarks/load.py``): robot and subscriber processes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.integration.conftest import ROOT

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast


def test_under_load_no_acked_observation_is_lost_and_every_subscriber_ends_with_the_daemons_maps(
    tmp_path: Path,
) -> None:
    out = tmp_path / "load.json"
    run = subprocess.run(
        [sys.executable, "benchmarks/load.py", "--robots", "4", "--rate", "10", "--duration", "5",
         "--subscribers", "3", "--json", str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=240, check=False,
    )  # fmt: skip
    assert out.exists(), run.stderr[-3000:]
    result = json.loads(out.read_text())
    assert run.returncode == 0, result
    assert result["observations_acked"] >= 0.5 * 4 * 10 * 5, result  # a loaded 2-core machine still acks half
    assert result["refused_or_timed_out"] == 0, result["robot_errors"]
    assert result["acked_changes_checked"] >= 4
    assert result["lost_acks"] == 0, result["problems"]
    assert result["subscribers_behind"] == 0
    assert result["update_latencies"] > 0 and result["update_latency_p99_ms"] > 0
