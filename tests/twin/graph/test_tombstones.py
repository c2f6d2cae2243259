"""A removed element stays in the graph as a tombstone (``twin:removed true``, no geometry), so that the
removal and its time stay known; every count, selection and map of the twin's current state leaves it out."""

from __future__ import annotations

from tests.conftest import imported
from tests.twin.box_lab import box_lab
from tests.twin.live_helpers import TWIN, box_turtle, observe, started
from twin.graph.rdf import literal_value
from twin.graph.stats import model_stats
from twin.selection.skill_selection import selection_query

TABLE = "urn:robot1:tombstone-table"


def test_a_removed_element_stays_as_a_tombstone_but_no_count_or_selection_includes_it() -> None:
    store = imported(box_lab())
    service, _ = started(store)
    before = model_stats(store, turtle=False)
    assert observe(service, "robot1", box_turtle(TABLE, 6.6, 2.0)).ok
    added = model_stats(store, turtle=False)
    assert added.elements == before.elements + 1
    assert service.status()["elements"] == added.elements

    assert observe(service, "robot1", f"<{TABLE}> <{TWIN}removed> true .".encode()).ok
    rows = store.select(
        f"SELECT ?cls WHERE {{ <{TABLE}> a bot:Element ; twin:removed true ; twin:ifcClass ?cls }}"
    )
    assert [literal_value(r["cls"]) for r in rows] == ["IfcFurniture"], "the tombstone is kept"

    after = model_stats(store, turtle=False)
    assert after.removed == 1
    assert after.elements == before.elements == service.status()["elements"]
    assert after.elements_per_class == before.elements_per_class
    assert [s.elements for s in after.storeys] == [s.elements for s in before.storeys]
    assert (after.meshes, after.triangles) == (before.meshes, before.triangles)
    for name, skill in service.skills.items():
        selected = {literal_value(r["element"]) for r in store.select(selection_query(skill))}
        assert TABLE not in selected, name
