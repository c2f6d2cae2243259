"""One-line errors a newcomer meets: each names the value that is wrong and what would do."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path


def twin(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "adapters.cli", *map(str, args)],
        capture_output=True, text=True, cwd=cwd, timeout=120, check=False,
    )  # fmt: skip


def test_a_site_name_that_is_not_one_is_refused_naming_it_and_a_name_that_would_do(tmp_path: Path) -> None:
    expected = (
        "twin: error: --site 'My Site' is not a site name: 1-64 of A-Z a-z 0-9 _ - (it is the key prefix "
        "twin/<site> and part of every IRI); e.g. 'my-site'."
    )
    commands = (("import", "lab.ifc", "--site", "My Site"), ("status", "--site", "My Site", "--timeout", "1"))
    for args in commands:
        r = twin(*args, cwd=tmp_path)
        assert r.returncode == 1
        assert r.stderr.strip().splitlines() == [expected], args


def test_a_file_that_is_not_there_is_named_with_a_colon(tmp_path: Path) -> None:
    r = twin("observe", "--robot", "robot1", "--turtle", "nosuch.ttl", "--timeout", "1", cwd=tmp_path)
    assert r.returncode == 1
    assert r.stderr.strip().splitlines() == ["twin: error: nosuch.ttl: No such file or directory"]
