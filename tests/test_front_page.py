"""The Makefile's and the README's promises to a newcomer."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")
def test_make_demo_ends_by_saying_how_to_reach_the_twin_command() -> None:
    # -n: print the recipes (the install's too, when the venv is missing) without running them
    # as a user types it: not inside another make (CI runs the suite from `make test`, whose MAKELEVEL
    # and MAKEFLAGS would make this one print "Leaving directory" lines)
    env = {k: v for k, v in os.environ.items() if k not in ("MAKELEVEL", "MAKEFLAGS", "MFLAGS")}
    dry = subprocess.run(
        ["make", "--no-print-directory", "-n", "demo"],
        cwd=ROOT, capture_output=True, text=True, check=True, env=env,
    )  # fmt: skip
    last = dry.stdout.strip().splitlines()[-2:]
    assert any(". .venv/bin/activate" in line and ".venv/bin/twin" in line for line in last), last


def test_the_docs_build_runs_strict_and_not_quiet_so_that_a_broken_link_fails() -> None:
    recipe = (ROOT / "Makefile").read_text().split("\ndocs:")[1].split("\n\n")[0]
    assert "mkdocs build --strict" in recipe
    assert "--quiet" not in recipe.split("#")[0]  # --quiet hides the warnings that --strict counts
    assert "make docs" in (ROOT / ".ci" / "run").read_text()


def test_the_readme_is_a_front_page_that_links_every_docs_page() -> None:
    import re

    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 250
    linked = set(re.findall(r"\]\(docs/([\w-]+\.md)\)", readme))
    pages = {p.name for p in (ROOT / "docs").glob("*.md")}
    assert pages <= linked, f"docs pages the README does not link: {sorted(pages - linked)}"
