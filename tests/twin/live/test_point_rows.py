"""A live points map's rows (twin/live/point_rows.py): after any sequence of parts replaced, added and
dropped, the winners are the best point per voxel of the parts as they are now, whatever the arena's
compactions and the index's merges did in between; an element left out and selected again unchanged
takes back the voxels it had."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.conftest import examples, imported
from tests.twin.box_lab import box_lab, element_iri, spec
from twin.graph.rdf import literal_value
from twin.live.live_maps import LiveMaps
from twin.live.point_rows import PointRows
from twin.maps.points import Voxels, best_per_voxel
from twin.maps.scene import load_scene
from twin.records import GeometryChange
from twin.selection.skill_selection import selection_query
from twin.selection.skills import parse_skill

NAMES = ["a", "b", "c", "d", "e"]
NORMALS = np.array([[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, -1, 0], [0, 0, 0]], dtype=np.float32)


def _distance(keys: npt.NDArray[np.int64], q: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """A stand-in for a plan's distance to the voxel's centre: a function of the key and the point."""
    out: npt.NDArray[np.float64] = ((q - 0.5 * (keys % 3)[:, None]) ** 2).sum(axis=1)
    return out


@st.composite
def parts(draw: st.DrawFn) -> Voxels:
    """A part's voxels: few keys, few distinct points (so few distances) and normals, so that parts tie
    on the point and the normal decides (a zero normal: a degenerate triangle's)."""
    keys = np.array(sorted(draw(st.sets(st.integers(0, 40), max_size=25))), dtype=np.int64)
    n = len(keys)
    q = np.array(draw(st.lists(st.sampled_from([0.0, 0.5, 1.0]), min_size=3 * n, max_size=3 * n))).reshape(
        n, 3
    )
    n_of = draw(st.lists(st.integers(0, len(NORMALS) - 1), min_size=n, max_size=n))
    return Voxels(keys, q, _distance(keys, q), NORMALS[np.array(n_of, dtype=np.int64)])


CHANGES = st.dictionaries(st.sampled_from(NAMES), st.none() | parts(), min_size=1, max_size=3)


def _same(a: Voxels, b: Voxels) -> bool:
    return bool(
        np.array_equal(a.keys, b.keys)
        and np.array_equal(a.q, b.q)
        and np.array_equal(a.d2, b.d2)
        and np.array_equal(a.n, b.n)
    )


@settings(max_examples=examples(200), deadline=None, suppress_health_check=list(HealthCheck))
@given(
    start=st.dictionaries(st.sampled_from(NAMES), parts()),
    changes=st.lists(CHANGES, max_size=8),
    small=st.booleans(),
)
def test_the_winners_after_any_changes_are_the_best_point_per_voxel_of_the_parts_as_they_are(
    start: dict[str, Voxels], changes: list[dict[str, Voxels | None]], small: bool
) -> None:
    room = {"spare": 1, "delta": 1} if small else {}  # small: a compaction and a merge at every change
    names = sorted(start)
    rows = PointRows.of(names, [start[n] for n in names], distance=_distance, **room)
    now = {n: p for n, p in start.items() if len(p)}
    for change in changes:
        before = rows.winners()
        changed = rows.replace(change)
        for n, p in change.items():
            if p is None or not len(p):
                now.pop(n, None)
            else:
                now[n] = p
        expected = best_per_voxel(Voxels.concat([now[n] for n in sorted(now)]))
        assert _same(rows.winners(), expected)
        assert changed == (not _same(before, expected))  # True exactly when a point of the cloud changed
        assert sorted(rows) == sorted(now)
        for n, p in now.items():
            assert _same(rows[n], p)
    names, arrays = rows.packed()
    again = PointRows.unpacked(names, arrays, distance=_distance)
    assert _same(again.winners(), rows.winners())
    assert again.won() == rows.won()


def test_a_door_left_out_and_selected_again_unchanged_takes_back_its_voxels_and_the_same_cloud() -> None:
    store = imported(box_lab())
    scene = load_scene(store)
    skill = parse_skill("lidar3d", {"kind": "points", "resolution_m": 0.2})
    selected = [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]
    live = LiveMaps(scene, margin_m=1.0)
    m = live.points.add_map(skill, scene.storeys[0].key, selected)
    door = element_iri(spec("Door A"))
    start, own = m.cloud(), m.parts[door].keys.copy()
    live.redraw([], {"lidar3d": {door: False}})  # opened: out of the skill, geometry unchanged
    assert door not in m.parts and np.array_equal(m.recent[door].keys, own)
    live.redraw([], {"lidar3d": {door: True}})  # closed again: its voxels come back as they were
    assert door not in m.recent and np.array_equal(m.parts[door].keys, own)
    back, ref = m.cloud(), live.points.rebuild(m)
    assert np.array_equal(back.keys, start.keys) and np.array_equal(back.xyz, start.xyz)
    assert np.array_equal(back.keys, ref.keys) and np.array_equal(back.xyz, ref.xyz)
    assert np.array_equal(back.normals, start.normals) and np.array_equal(back.normals, ref.normals)
    # moved while left out: what it had is stale and forgotten
    live.redraw([], {"lidar3d": {door: False}})
    shape = live.shape_of(door)
    assert shape is not None
    moved = shape[1].copy()
    moved[0, 3] += 0.3
    live.redraw([GeometryChange(door, (shape[0], moved))], {"lidar3d": {door: False}})
    assert door not in m.recent
    live.redraw([], {"lidar3d": {door: True}})
    assert not np.array_equal(m.parts[door].keys, own)
    ref = live.points.rebuild(m)
    assert np.array_equal(m.cloud().keys, ref.keys) and np.array_equal(m.cloud().xyz, ref.xyz)
    assert np.array_equal(m.cloud().normals, ref.normals)
