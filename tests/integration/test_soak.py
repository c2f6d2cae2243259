"""A short soak (the benchmark's hour: ``benchmarks/soak.py``): the daemon must not grow per observation."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.integration.conftest import ROOT

pytestmark = pytest.mark.slow


def test_a_fleet_re_reporting_and_moving_tables_grows_neither_memory_nor_store_per_observation(
    tmp_path: Path,
) -> None:
    out = tmp_path / "soak.json"
    run = subprocess.run(
        [sys.executable, "benchmarks/soak.py", "--robots", "3", "--rate", "90", "--reconfirm", "0.5",
         "--duration", "40", "--subscribers", "1", "--sample", "2", "--warmup", "10", "--flush-every", "5",
         "--max-rss-growth", "1000", "--max-store-growth", "1000", "--json", str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert out.exists(), run.stderr[-3000:]
    result = json.loads(out.read_text())
    assert run.returncode == 0, {k: v for k, v in result.items() if k != "samples"}
    assert result["lost_acks"] == 0 and result["subscribers_behind"] == 0, result["problems"]
    assert result["unchanged"] > 0.2 * result["observations_acked"]  # re-confirmations were acked as such
    per_thousand = 1000 / max(result["observations_after_warmup"], 1)
    # Before the fleet-day work the daemon grew 7 MB of RSS and 5 MB of store per 1,000 observations.
    assert result["rss_growth_mb"] * per_thousand < 2.0, result["samples"]
    assert result["store_growth_mb"] * per_thousand < 1.0, result["samples"]
