"""``twin record --from``: a file that is not a readable recording is one line; the output is not
swallowed by ``--from``'s list of files."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # processes that import Rerun: seconds each


def twin(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "adapters.cli", *map(str, args)],
        capture_output=True, text=True, cwd=cwd, timeout=300, check=False,
    )  # fmt: skip


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("record")
    assert twin("sample", "lab", "lab.ifc", "--storeys", "1", cwd=root).returncode == 0
    assert twin("import", "lab.ifc", "--store", "lab.store", cwd=root).returncode == 0
    r = twin("record", "--store", "lab.store", "lab.rrd", cwd=root)
    assert r.returncode == 0, r.stderr
    return root / "lab.rrd"


def test_record_from_takes_the_last_name_as_the_output_when_none_comes_first(recording: Path) -> None:
    root = recording.parent
    r = twin("record", "--from", recording.name, "cut.rrd", cwd=root)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("wrote cut.rrd (")
    assert (root / "cut.rrd").stat().st_size > 0


def test_record_from_refuses_to_guess_an_output_that_exists(recording: Path) -> None:
    root = recording.parent
    (root / "other.rrd").write_bytes(recording.read_bytes())
    r = twin("record", "--from", recording.name, "other.rrd", cwd=root)
    assert r.returncode == 1
    assert r.stderr.strip().splitlines() == [
        "twin: error: Which file is the output? other.rrd exists (a recording to cut?): give it first, "
        "twin record OUT.rrd --from lab.rrd other.rrd."
    ]
    assert (root / "other.rrd").read_bytes() == recording.read_bytes()


@pytest.mark.parametrize(
    ("name", "content", "reason"),
    [
        ("empty.rrd", b"", "(the file is empty)."),
        ("model.rrd", b"ISO-10303-21;\nHEADER;\n" * 20, '(Not an RRD file: expected FourCC header "RRF2"'),
        ("short.rrd", None, "(it ends early, cut short: "),
    ],
)
def test_record_from_a_file_that_is_not_a_readable_recording_is_one_line(
    recording: Path, tmp_path: Path, name: str, content: bytes | None, reason: str
) -> None:
    data = recording.read_bytes()
    (tmp_path / name).write_bytes(content if content is not None else data[: len(data) // 2])
    r = twin("record", "out.rrd", "--from", name, cwd=tmp_path)
    assert r.returncode == 1 and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith(f"twin: error: {name} is not a Rerun recording that can be read {reason}")
    assert not (tmp_path / "out.rrd").exists()
