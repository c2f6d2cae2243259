"""A started service is ready: what the first request would build lazily is built by ``start``."""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.conftest import imported
from tests.twin.box_lab import box_lab
from tests.twin.live.snapshots.test_snapshot import start, stop_cleanly
from tests.twin.live_helpers import box_turtle, observe
from twin.config import load_config
from twin.live import TwinService
from twin.live.state import LiveState


def test_a_start_from_the_snapshot_computes_the_scenes_triangles_before_it_returns(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    store, path = imported(box_lab()), tmp_path / "store.snapshot"
    stop_cleanly(start(store, path))
    with caplog.at_level(logging.INFO, logger="twin.live.service"):
        again = start(store, path)
        assert again.restored_from is not None
        at_start = [r.message for r in caplog.records if "triangles computed" in r.message]
        caplog.clear()
        assert observe(again, "robot1", box_turtle("urn:robot1:crate", 2.0, 1.0)).ok
        later = [r.message for r in caplog.records if "triangles computed" in r.message]
    assert len(at_start) == 1 and later == []  # the first observation found nothing left to build


def test_warm_up_steps_run_in_order_on_the_live_state_before_start_returns() -> None:
    ran: list[tuple[str, int]] = []

    def step(name: str) -> tuple[str, Callable[[LiveState], None]]:
        def run(live: LiveState) -> None:
            ran.append((name, len(live.states)))

        return name, run

    service = TwinService(imported(box_lab()), load_config(), warm_ups=[step("poses"), step("index")])
    service.start()
    assert [name for name, _ in ran] == ["poses", "index"]
    assert all(n == len(service.live.states) > 0 for _, n in ran)


def test_fusions_poses_are_indexed_before_start_returns_from_the_store_and_from_the_snapshot(
    tmp_path: Path,
) -> None:
    store, path = imported(box_lab()), tmp_path / "store.snapshot"
    first = start(store, path)
    assert observe(first, "robot1", box_turtle("urn:robot1:crate", 2.0, 1.0)).ok  # a dynamic element
    stop_cleanly(first)
    for service in (TwinService(store, load_config()), start(store, path)):
        if service.restored_from is None:
            service.start()
        assert service.live.fusion.poses is not None  # not left to the first associated observation
        assert "urn:robot1:crate" in service.live.fusion.poses.get("ground-floor", {})
        poses = service.live.fusion.poses
        ack = observe(service, "robot2", box_turtle("urn:robot2:box-9", 2.02, 1.0)).body
        assert ack["resolved"] == {"urn:robot2:box-9": "urn:robot1:crate"}  # fusion matched it
        assert service.live.fusion.poses is poses  # found built, not built again
