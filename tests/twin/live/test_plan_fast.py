"""The plan's Python-float path for boxes (placement, its literal, the extent check, a clear move)
decides and writes exactly what the array path does: each test fails if the fast path differs."""

from __future__ import annotations

import datetime
import math
import random

import numpy as np
import pytest

from tests.twin.box_lab import OX, OY
from tests.twin.live_helpers import box_turtle, observe, started
from twin.errors import ObservationError
from twin.live import plan as plan_module
from twin.live.plan import ObservationPlan, plan_observation
from twin.live.same import quantised, quantised_box_values, same_shape
from twin.live.service import TwinService
from twin.maps.shapes import box_mesh, box_placement
from twin.records import ElementReport, ObservedBox
from twin.tolerances import TOLERANCES

ALL_RIGHTS = frozenset({"create", "dynamic", "doors", "static", "zones"})


def _box(rng: random.Random, k: int) -> tuple[float, float, float, float]:
    """Centres and yaws of every kind: anywhere, short decimals, halves of the rounding steps, tiny."""
    if k == 0:
        return rng.uniform(-300, 300), rng.uniform(-300, 300), rng.uniform(-5, 30), rng.uniform(-7, 7)
    if k == 1:
        cx, cy, cz = (round(rng.uniform(-60, 60), rng.randint(0, 7)) for _ in range(3))
        yaw = rng.choice([0.0, -0.0, math.pi, -math.pi, math.pi / 2, 1e-12, -1e-12, rng.uniform(-7, 7)])
        return cx, cy, cz, yaw
    if k == 2:  # on the halves of 1 um and of 1e-9
        cx, cy, cz = (rng.randint(-(10**8), 10**8) / 2e6 for _ in range(3))
        return cx, cy, cz, rng.randint(-(10**9), 10**9) / 2e9 * math.pi
    cx, cy, cz = (rng.choice([-1, 1]) * rng.random() * 10.0 ** rng.randint(-9, 9) for _ in range(3))
    return cx, cy, cz, rng.uniform(-1e-8, 1e-8)


def test_a_box_placement_in_python_floats_is_the_array_path_bit_for_bit() -> None:
    rng = random.Random(42)
    for i in range(40_000):
        cx, cy, cz, yaw = _box(rng, i % 4)
        values = quantised_box_values(cx, cy, cz, yaw)
        assert values is not None
        expected = quantised(box_placement(cx, cy, cz, yaw=yaw))
        assert np.array(values).reshape(4, 4).tobytes() == expected.tobytes(), (cx, cy, cz, yaw)
        assert " ".join(map(repr, values)) == " ".join(map(repr, expected.ravel().tolist()))


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, 1e300])
def test_a_box_placement_not_finite_or_far_out_is_left_to_the_array_path(bad: float) -> None:
    assert quantised_box_values(bad, 1.0, 1.0, 0.0) is None
    assert quantised_box_values(1.0, bad, 1.0, 0.0) is None
    if not math.isfinite(bad):
        assert quantised_box_values(1.0, 1.0, 1.0, bad) is None


def test_a_clear_move_is_never_a_box_the_array_path_calls_the_same() -> None:
    rng = random.Random(7)
    mesh = box_mesh(0.8, 0.6, 0.75)
    tol = TOLERANCES.same_position_m
    moved = 0
    for _ in range(20_000):
        cx, cy = rng.uniform(-100, 100), rng.uniform(-100, 100)
        cz, yaw = rng.uniform(0, 3), rng.uniform(-4, 4)
        step = rng.choice([0.5, 2 * tol, tol, tol + 2e-6, tol + 1e-6, tol - 1e-6, 1e-5])
        held = (mesh, quantised(box_placement(cx, cy, cz, yaw=yaw)))
        new = (
            mesh,
            quantised(
                box_placement(
                    cx + rng.choice([-1, 1]) * step * rng.random() ** 0.1,
                    cy + rng.uniform(-tol, tol),
                    cz,
                    yaw=yaw + rng.choice([0.0, 1e-5, -1e-4, 0.3]),
                )
            ),
        )
        if plan_module._box_moved(new, held):
            moved += 1
            assert not same_shape(new, held)
    assert moved > 1000  # the fast path did decide


def _reference(monkeypatch: pytest.MonkeyPatch) -> None:
    """The array path alone: no Python-float placement, no fast extent check, no fast move."""
    monkeypatch.setattr(plan_module, "quantised_box_values", lambda *a: None)
    monkeypatch.setattr(plan_module, "_box_inside", lambda *a: False)
    monkeypatch.setattr(plan_module, "_box_moved", lambda *a: False)


def _plan(service: TwinService, report: ElementReport) -> ObservationPlan | str:
    live = service.live
    try:
        return plan_observation(
            [report],
            robot="robot1",
            rights=ALL_RIGHTS,  # type: ignore[arg-type]
            site=live.site,
            states=live.states,
            shapes={report.iri: live.maps.shape_of(report.iri)},
            held=live.held,
            revision=live.revision + 1,
            stamp_ns=1_700_000_000_000_000_000,
        )
    except ObservationError as err:
        return str(err)


def test_the_plans_of_boxes_moved_turned_and_at_the_sites_edge_equal_the_array_paths(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    service, _ = started()
    assert observe(service, "robot1", box_turtle("urn:r:t1", 5.0, 2.0)).ok
    site = service.live.site.site_box
    rng = random.Random(3)
    tol = TOLERANCES.same_position_m
    reports = []
    for i in range(600):
        if i % 3 == 0:  # near the held table: moves about the tolerance, turns
            x = OX + 5.0 + rng.choice([0.0, tol / 2, tol, tol + 1e-6, tol + 3e-6, 0.3]) * rng.choice([-1, 1])
            y, yaw = OY + 2.0 + rng.uniform(-tol, tol), rng.choice([0.0, 5e-5, 1e-4, 2e-4, 0.5])
            iri, z = "urn:r:t1", 0.375
        else:  # a new box about the site's edges (inside, on, outside by a hair)
            edge = rng.choice([0, 1])
            off = rng.choice([0.4, 0.4 + 1e-7, 0.4 - 1e-7, 0.3, 0.5])  # the half size is 0.4
            x = site[0 if edge else 3] + rng.choice([-1, 1]) * off
            y, yaw = rng.uniform(site[1] + 1, site[4] - 1), rng.choice([0.0, 0.3, math.pi / 2])
            iri, z = f"urn:r:n{i}", rng.choice([0.375, site[5] - 0.3, -0.2])
        box = ObservedBox(x, y, z, 0.8, 0.6, 0.75, yaw)
        reports.append(ElementReport(iri, ifc_class="IfcFurniture", storey="ground-floor", box=box))
    fast = [_plan(service, r) for r in reports]
    with monkeypatch.context() as m:
        _reference(m)
        slow = [_plan(service, r) for r in reports]
    kinds = set()
    for r, a, b in zip(reports, fast, slow, strict=True):
        if isinstance(a, str) or isinstance(b, str):
            assert a == b, r
            kinds.add("refused")
            continue
        assert a.changes == b.changes, r
        assert [(g.iri, None if g.new is None else g.new[1].tobytes()) for g in a.geometry] == [
            (g.iri, None if g.new is None else g.new[1].tobytes()) for g in b.geometry
        ]
        assert a.states == b.states
        kinds.add("unchanged" if a.unchanged else "changed")
    assert kinds == {"refused", "unchanged", "changed"}


def test_the_provenance_times_are_the_datetime_modules_text_to_the_microsecond_and_nanosecond() -> None:
    rng = random.Random(11)
    edges = [0, 1, 499, 500, 501, 999_499, 999_500, 999_501, 999_999_499, 999_999_500, 999_999_999]
    for i in range(30_000):
        second = rng.randint(0, 4_000_000_000) if i % 2 else rng.randint(1_700_000_000, 1_800_000_000)
        ns = second * 10**9 + (rng.choice(edges) if i % 3 == 0 else rng.randint(0, 10**9 - 1))
        expected = datetime.datetime.fromtimestamp(ns / 1e9, tz=datetime.UTC).isoformat()
        assert plan_module._observed_at(ns) == expected, ns
        moment = datetime.datetime.fromtimestamp(second, tz=datetime.UTC).strftime("%Y-%m-%dT%H:%M:%S")
        assert plan_module._iso(ns) == f"{moment}.{ns % 10**9:09d}Z"
    for ns in (-1, -1_500_000_000, -(10**9)):  # before 1970: the datetime module itself
        assert (
            plan_module._observed_at(ns)
            == datetime.datetime.fromtimestamp(ns / 1e9, tz=datetime.UTC).isoformat()
        )
