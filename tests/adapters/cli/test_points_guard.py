"""``twin map`` refuses a points cloud estimated over ``[maps] max_points_per_storey`` in one line naming
the skill, the estimate and the limit, unless given ``--force``."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # processes


def test_twin_map_refuses_a_cloud_over_the_limit_in_one_line_and_builds_it_with_force(tmp_path: Path) -> None:
    cfg = tmp_path / "points.toml"
    cfg.write_text('[maps]\nmax_points_per_storey = 2000\n\n[skills.lidar3d]\nkind = "points"\n')

    def twin(*args: str | Path) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "adapters.cli", "--config", str(cfg), *map(str, args)],
            capture_output=True, text=True, check=False, timeout=300,
        )  # fmt: skip

    store, ifc, out = tmp_path / "store", tmp_path / "lab.ifc", tmp_path / "maps"
    assert twin("sample", "lab", ifc).returncode == 0
    assert twin("import", "--store", store, ifc).returncode == 0
    r = twin("map", "--store", store, "--skill", "lidar3d", "--out", out)
    assert r.returncode == 1
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "'lidar3d'" in r.stderr and "about " in r.stderr and "2,000" in r.stderr
    assert "max_points_per_storey" in r.stderr and "--force" in r.stderr
    assert not list(out.glob("*.pcd")) if out.exists() else True
    r = twin("map", "--store", store, "--skill", "lidar3d", "--out", out, "--force")
    assert r.returncode == 0, r.stderr
    assert len(list(out.glob("*__lidar3d.pcd"))) == 2
