"""Incremental re-slicing equals a full rebuild from the graph, bit for bit, after any sequence of
adds, moves, door changes and removals (property test on the box lab)."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.conftest import imported
from tests.twin.box_lab import OX, OY, box_lab, element_iri, spec
from tests.twin.live_helpers import TWIN, box_turtle, observe, started

DOOR = element_iri(spec("Door A"))
TABLE = element_iri(spec("Table"))

xs = st.floats(-0.5, 12.5)
ys = st.floats(-0.5, 4.5)


@st.composite
def steps(draw: st.DrawFn) -> bytes:
    kind = draw(st.sampled_from(["add", "add", "move", "door", "remove", "move-imported"]))
    name = f"urn:robot:thing-{draw(st.integers(0, 3))}"
    if kind in ("add", "move"):
        return box_turtle(
            name,
            draw(xs),
            draw(ys),
            sx=draw(st.floats(0.01, 2.0)),
            sy=draw(st.floats(0.01, 2.0)),
            sz=draw(st.floats(0.05, 2.5)),
            yaw=draw(st.floats(-3.2, 3.2)),
        )
    if kind == "door":
        return f"<{DOOR}> <{TWIN}isOpen> {draw(st.sampled_from(['true', 'false']))} .".encode()
    if kind == "move-imported":
        m = np.eye(4)
        m[:3, 3] = (OX + draw(xs), OY + draw(ys), 0.375)
        text = " ".join(repr(float(v)) for v in m.ravel())
        return f'<{TABLE}> <{TWIN}placement> "{text}"^^<{TWIN}Matrix4x4> .'.encode()
    return f"<{name}> <{TWIN}removed> true .".encode()


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sequence=st.lists(steps(), min_size=1, max_size=8))
def test_incremental_maps_equal_a_full_rebuild_from_the_graph(sequence: list[bytes]) -> None:
    store = imported(box_lab())
    service, _ = started(store)
    for payload in sequence:
        observe(service, "robot1", payload)  # some are refused (e.g. removing what is not there)
    fresh, _ = started(store)
    assert fresh.revision == service.revision
    for key, m in service.live_maps.skill_maps.items():
        np.testing.assert_array_equal(
            m.data, service.live_maps.rebuild(m), err_msg=f"{key} vs its own rebuild"
        )
        np.testing.assert_array_equal(
            m.data, fresh.live_maps.skill_maps[key].data, err_msg=f"{key} vs a restart"
        )
