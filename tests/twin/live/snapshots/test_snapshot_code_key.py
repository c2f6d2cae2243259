"""The snapshot is keyed by the whole core's code: a change to any module that could shape a map
(drawing, selection, raster, ...) makes an old snapshot unusable."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

import twin
from twin.live.snapshots import code_digest

CORE = Path(twin.__file__).resolve().parent


@pytest.fixture
def core_copy(tmp_path: Path) -> Path:
    dst = tmp_path / "twin"
    shutil.copytree(CORE, dst, ignore=shutil.ignore_patterns("__pycache__"))
    return dst


def test_the_digest_of_an_unchanged_copy_of_the_core_equals_the_running_code(core_copy: Path) -> None:
    assert code_digest(core_copy) == code_digest()


@pytest.mark.parametrize(
    "module",
    [
        "live/drawing.py",
        "live/membership.py",
        "selection/skill_selection.py",
        "maps/raster/clip.py",
        "maps/render.py",
        "live/plan.py",
    ],
)
def test_a_change_to_any_core_module_changes_the_snapshot_key(core_copy: Path, module: str) -> None:
    path = core_copy / module
    assert path.exists(), f"{module} moved: name a module that exists"
    before = code_digest(core_copy)
    path.write_text(path.read_text() + "\n# one more line\n")
    assert code_digest(core_copy) != before


def test_a_new_module_in_the_core_changes_the_snapshot_key(core_copy: Path) -> None:
    before = code_digest(core_copy)
    (core_copy / "live" / "new_drawing_rule.py").write_text("X = 1\n")
    assert code_digest(core_copy) != before
