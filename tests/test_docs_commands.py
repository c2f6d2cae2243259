"""Every command block of the README and the docs runs as typed (``tests/readme_commands.py``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.readme_commands import run_readme

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("part", ["readme", "docs"])
def test_every_twin_line_of_the_readme_and_the_docs_runs_as_typed(tmp_path: Path, part: str) -> None:
    outcomes = run_readme(tmp_path, (part,))
    failed = [f"{o.line}\n  {o.detail}" for o in outcomes if o.status == "failed"]
    assert not failed, "\n".join(failed)
    ran = [o.line for o in outcomes if o.status == "ok"]
    assert any(line.startswith("twin sample lab") for line in ran)
    assert any(line.startswith("twin serve") for line in ran)
