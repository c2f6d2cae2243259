"""A worker's translator reuses a robot's march while the robot stands still on the same map: after a
map update or a move, the next array's view is what a translator without that memory makes."""

from __future__ import annotations

import numpy as np

from adapters.ros.detections import DetectionSettings
from adapters.zenoh.ros_workers import RobotSpec, RobotTranslator, Translated
from tests.adapters.ros_reports import Det, Tf, cdr_detections, cdr_tf
from twin.maps.grid import GridFrame, OccupancyGrid
from twin.records import Observation

NOW = 1_700_000_000_000_000_000
FRAME = GridFrame(0.0, 0.0, 0.05, 200, 120)  # 10 x 6 m


def _grid(wall_at_col: int | None = None) -> OccupancyGrid:
    data = np.zeros((FRAME.height, FRAME.width), dtype=np.int8)
    if wall_at_col is not None:
        data[:, wall_at_col] = 100
    return OccupancyGrid(FRAME, data, "g", "localization", 0.0)


def _translator(grid: OccupancyGrid) -> RobotTranslator:
    spec = RobotSpec("r", DetectionSettings(robot="r", classes={"table": "IfcFurniture"}), "localization")
    t = RobotTranslator([spec], fusion_terms=True, typed=True, clock=lambda: NOW)
    t.set_storey("r", "g")
    t.set_elevations({"g": 0.0})
    t.set_grid(grid)
    return t


def _view(t: RobotTranslator, k: int, x: float) -> list[bytes]:
    """The rings of the view of array ``k`` with the robot at ``(x, 3)`` facing +x (a table 2 m ahead)."""
    stamp = NOW - 10**9 + k * 10**8
    t.handle("r", "tf", cdr_tf([Tf("map", "base_link", (x, 3.0, 0.0), stamp_ns=stamp)]), 0)
    table = Det((("table", 0.9),), (2.0, 0.3, 0.375), (0.3, 0.3, 0.75), id="1")
    (out,) = t.handle("r", "detections", cdr_detections(stamp, "base_link", [table]), 0)
    assert isinstance(out, Translated) and isinstance(out.translation.document, Observation)
    view = out.translation.document.view
    assert view is not None
    return [ring.tobytes() for ring in view.polygons]


def test_a_robot_s_view_follows_a_map_update_and_a_move_as_a_fresh_translator_sees_them() -> None:
    t = _translator(_grid())
    first = _view(t, 0, 1.0)
    assert _view(t, 1, 1.0) == first  # standing still: its march reused, the same view
    walled = _grid(wall_at_col=90)  # a wall across the view at x = 4.5 m
    t.set_grid(walled)
    behind_wall = _view(t, 2, 1.0)
    assert behind_wall != first and behind_wall == _view(_translator(walled), 2, 1.0)
    moved = _view(t, 3, 1.05)
    assert moved != behind_wall and moved == _view(_translator(walled), 3, 1.05)
