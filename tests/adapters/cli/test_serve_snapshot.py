"""Where ``twin serve`` keeps its snapshot, and when it keeps none."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import pytest

from adapters.cli.serve_cmd import _snapshots
from twin.config import load_config


def args(**kw: object) -> argparse.Namespace:
    return argparse.Namespace(**{"store": None, "store_url": None, "no_snapshot": False, **kw})


def test_the_snapshot_lives_next_to_the_embedded_store(tmp_path: Path) -> None:
    snap = _snapshots(args(store=str(tmp_path / "store")), load_config())
    assert snap is not None and snap.path == tmp_path / "store.snapshot"
    assert snap.every_s == 300.0


def test_no_snapshot_with_a_sparql_server_and_the_log_says_so(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level("INFO", logger="adapters.cli.serve_cmd"):
        assert _snapshots(args(store_url="http://127.0.0.1:7878"), load_config()) is None
    assert "SPARQL server" in caplog.text


def test_no_snapshot_when_turned_off_by_flag_or_configuration(tmp_path: Path) -> None:
    assert _snapshots(args(store=str(tmp_path), no_snapshot=True), load_config()) is None
    off = dataclasses.replace(load_config(), store_snapshot=False)
    assert _snapshots(args(store=str(tmp_path)), off) is None
