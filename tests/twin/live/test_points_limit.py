"""``[maps] max_points_per_storey`` in the live twin: a points skill whose cloud is estimated over the
limit is skipped with one warning, and the twin serves on (its 2D maps, its other clouds, observations)."""

from __future__ import annotations

import dataclasses
import logging

import pytest

from tests.conftest import imported
from tests.twin.box_lab import box_lab, element_iri, spec
from tests.twin.live_helpers import TWIN, observe, started
from twin.config import load_config
from twin.selection.skills import parse_skill

DOOR = element_iri(spec("Door A"))


def test_a_cloud_estimated_over_the_limit_is_skipped_with_one_line_and_the_twin_serves_on(
    caplog: pytest.LogCaptureFixture,
) -> None:
    cfg = load_config()
    fine = parse_skill("fine3d", {"kind": "points", "resolution_m": 0.02})
    coarse = parse_skill("coarse3d", {"kind": "points", "resolution_m": 0.25})
    config = dataclasses.replace(
        cfg, skills={**cfg.skills, "fine3d": fine, "coarse3d": coarse}, max_points_per_storey=50_000
    )
    with caplog.at_level(logging.WARNING, logger="twin.live.live_points"):
        service, _ = started(imported(box_lab()), config)
    points = service.live_maps.points
    assert {k[1] for k in points.clouds} == {"coarse3d"}  # the coarse cloud is built, the fine one not
    (line,) = [r.getMessage() for r in caplog.records if "fine3d" in r.getMessage()]
    assert "max_points_per_storey" in line and "50,000" in line and "resolution_m=0.02" in line
    estimate = next(iter(points.skipped.values()))
    assert estimate > 50_000 and f"{estimate:,}" in line
    assert service.live_maps.skill_maps, "the 2D maps are served"
    assert observe(service, "robot1", f"<{DOOR}> <{TWIN}isOpen> true .".encode()).ok
    assert len(next(iter(points.clouds.values())).cloud()) > 100
