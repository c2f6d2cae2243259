"""What an operator runs: `twin backup`, `twin --version`, `twin acl` (real processes, real stores)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest


def twin(*args: str | Path, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "adapters.cli", *map(str, args)],
        capture_output=True, text=True, cwd=cwd, timeout=300, check=False,
    )  # fmt: skip


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("backup")
    assert twin("sample", "lab", root / "lab.ifc").returncode == 0
    r = twin("import", root / "lab.ifc", "--store", root / "lab.store")
    assert r.returncode == 0, r.stderr
    return root / "lab.store"


def test_backup_copies_the_store_into_a_store_with_the_same_triples(store: Path, tmp_path: Path) -> None:
    original = twin("stats", "--store", store, "--json")
    assert original.returncode == 0, original.stderr
    triples = json.loads(original.stdout)["triples"]
    assert triples > 600  # the lab, imported
    r = twin("backup", "--store", store, tmp_path / "copies" / "monday.store")
    assert r.returncode == 0, r.stderr
    assert f"({triples} triples" in r.stdout
    stats = twin("stats", "--store", tmp_path / "copies" / "monday.store", "--json")
    assert stats.returncode == 0, stats.stderr
    assert json.loads(stats.stdout)["triples"] == triples


def test_backup_refuses_a_target_that_exists_in_one_line(store: Path, tmp_path: Path) -> None:
    (tmp_path / "old.store").mkdir()
    r = twin("backup", "--store", store, tmp_path / "old.store")
    assert r.returncode == 1
    assert r.stderr.strip().splitlines() == [
        f"twin: error: Backup target {tmp_path / 'old.store'} exists: give a new directory."
    ]


def test_version_prints_the_installed_version_and_exits_0() -> None:
    from importlib.metadata import version

    r = twin("--version")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == f"twin {version('building-twin')}"


def test_acl_without_a_site_takes_the_one_its_store_was_imported_as(store: Path, tmp_path: Path) -> None:
    (tmp_path / "users.txt").write_text("robot1:secret\n")
    config = tmp_path / "site.toml"
    config.write_text(f'[zenoh.auth]\nusers_file = "{tmp_path / "users.txt"}"\n[robots.robot1]\n')
    r = twin("acl", "--config", config, "--store", store)
    assert r.returncode == 0, r.stderr
    assert '"twin/lab/observe/robot1"' in r.stdout  # the store's site, lab


def test_acl_and_router_acl_without_site_or_store_are_refused_saying_how_to_give_one(tmp_path: Path) -> None:
    (tmp_path / "users.txt").write_text("robot1:secret\n")
    config = tmp_path / "site.toml"
    config.write_text(f'[zenoh.auth]\nusers_file = "{tmp_path / "users.txt"}"\n[robots.robot1]\n')
    acl = twin("acl", "--config", config, cwd=tmp_path)
    router = twin("router", "--acl", "--listen", "tcp/127.0.0.1:0", "--config", config, cwd=tmp_path)
    assert acl.returncode == router.returncode == 1
    assert acl.stderr.strip().splitlines() == [
        "twin: error: twin acl guards one site's keys: give --site NAME, site.name or --store DIR of the "
        "site (there is no store at var/store)."
    ]
    assert router.stderr.startswith("twin: error: twin router --acl guards one site's keys: give --site")
