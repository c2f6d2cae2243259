"""The windows a change dirties, worked in Python numbers, are those of the Window-object reference."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.twin.live_helpers import started
from twin.live.overlay import dirty_windows, grow, in_band
from twin.maps.grid import GridFrame, Window
from twin.maps.render import MapPlan
from twin.records import FloatArray

_PLAN = next(iter(started()[0].live.maps.skill_maps.values())).plan


def _reference(plan: MapPlan, boxes: Sequence[FloatArray], pad: int) -> list[Window]:
    """The implementation before (Window objects, numpy scalars), kept as the reference."""
    windows = []
    for b in boxes:
        if not in_band(b, plan):
            continue
        grown = grow(plan.frame.window_for(b[0], b[1], b[3], b[4]), pad).intersect(plan.frame.full)
        if not grown.empty:
            windows.append(grown)
    merged = True
    while merged and len(windows) > 1:
        merged = False
        for i in range(len(windows)):
            for j in range(i + 1, len(windows)):
                a, c = windows[i], windows[j]
                if a.row0 <= c.row1 and c.row0 <= a.row1 and a.col0 <= c.col1 and c.col0 <= a.col1:
                    windows[i] = Window(
                        min(a.row0, c.row0), min(a.col0, c.col0), max(a.row1, c.row1), max(a.col1, c.col1)
                    )
                    del windows[j]
                    merged = True
                    break
            if merged:
                break
    return windows


_coord = st.floats(-3.0, 13.0, allow_nan=False)
_box = st.tuples(
    _coord, _coord, st.floats(-1.0, 3.0), st.floats(0.0, 2.0), st.floats(0.0, 2.0), st.floats(0.0, 2.0)
)


@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(_box, max_size=12),
    st.integers(0, 6),
    st.sampled_from([0.05, 0.1, 0.25]),
    st.sampled_from([0.0, -0.5, 0.25]) | st.floats(-1.0, 1.0),
    st.floats(0.0, 1.5),
)
def test_dirty_windows_are_the_references_in_the_same_order(
    raw: list[tuple[float, ...]], pad: int, res: float, origin: float, z_lo: float
) -> None:
    frame = GridFrame(origin, origin / 2, res, int(10 / res), int(8 / res))
    plan = replace(_PLAN, frame=frame, z_lo=z_lo, z_hi=z_lo + 0.5)
    boxes = [np.array([x, y, z, x + dx, y + dy, z + dz]) for x, y, z, dx, dy, dz in raw]
    assert dirty_windows(plan, boxes, pad) == _reference(plan, boxes, pad)


def test_boxes_on_the_cell_planes_and_the_bands_ends_dirty_the_references_windows() -> None:
    f = _PLAN.frame
    r, g = f.resolution_m, 1e-6
    x0, y0 = f.origin_x + 10 * r, f.origin_y + 10 * r
    boxes = [
        np.array([x0, y0, _PLAN.z_hi, x0 + 3 * r, y0 + r, _PLAN.z_hi + 1.0]),  # on the band's top
        np.array([x0 + 4 * r, y0, _PLAN.z_lo - 1.0, x0 + 5 * r, y0 + 2 * r, _PLAN.z_lo - g]),  # its bottom
        np.array([x0 + 40 * r, y0 + 40 * r, _PLAN.z_lo, x0 + 41 * r, y0 + 41 * r, _PLAN.z_hi]),
        np.array(
            [f.origin_x - 5.0, f.origin_y - 5.0, _PLAN.z_lo, f.origin_x - 4.0, f.origin_y - 4.0, _PLAN.z_hi]
        ),
    ]
    for pad in (0, 1, 3):
        out = dirty_windows(_PLAN, boxes, pad)
        assert out == _reference(_PLAN, boxes, pad) and len(out) >= 2
