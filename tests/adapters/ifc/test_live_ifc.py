"""The live twin on real IFC models: incremental maps equal a rebuild from the graph, bit for bit."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.conftest import imported, shared_model
from tests.twin.live_helpers import TWIN, observe, started
from twin.records import BuildingModel

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast


def _box(iri: str, storey: str, *, x: float, y: float, yaw: float, size: float) -> bytes:
    return (
        f'<{iri}> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "{storey}" ; '
        f'<{TWIN}box> "{x} {y} 0.4 {size} {size * 0.7} 0.8 {yaw}" .'
    ).encode()


@settings(
    max_examples=8,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(data=st.data())
def test_changes_on_a_shared_model_match_a_rebuild(
    data: st.DataObject, read_cached: Callable[[Path], BuildingModel]
) -> None:
    model = read_cached(shared_model("AC20-FZK-Haus.ifc"))
    store = imported(model)
    service, _ = started(store)
    storeys = {s.key: s.extent for s in service.live_maps.scene.storeys}
    doors = sorted(e.iri for e in service.element_shapes() if "door" in e.ifc_class.lower())
    assert doors
    for _ in range(data.draw(st.integers(1, 6))):
        kind = data.draw(st.sampled_from(["add", "add", "remove", "door"]))
        iri = f"urn:robot:thing-{data.draw(st.integers(0, 2))}"
        if kind == "add":
            key = data.draw(st.sampled_from(sorted(storeys)))
            x0, y0, x1, y1 = storeys[key]
            x, y = data.draw(st.floats(x0, x1)), data.draw(st.floats(y0, y1))
            yaw, size = data.draw(st.floats(-3.2, 3.2)), data.draw(st.floats(0.05, 2.0))
            assert observe(service, "robot1", _box(iri, key, x=x, y=y, yaw=yaw, size=size)).ok
            continue
        elif kind == "door" and doors:
            flag = data.draw(st.sampled_from(["true", "false"]))
            payload = f"<{data.draw(st.sampled_from(doors))}> <{TWIN}isOpen> {flag} .".encode()
        else:
            payload = f"<{iri}> <{TWIN}removed> true .".encode()
        observe(service, "robot1", payload)
    fresh, _ = started(store)
    for key, m in service.live_maps.skill_maps.items():
        np.testing.assert_array_equal(m.data, fresh.live_maps.skill_maps[key].data, err_msg=str(key))
