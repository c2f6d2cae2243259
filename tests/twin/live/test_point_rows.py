"""A live points map's rows (twin/live/point_rows.py): after any sequence of parts replaced, added and
dropped, the winners are the best point per voxel of the parts as they are now, whatever the arena's
compactions and the index's merges did in between."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.conftest import examples
from twin.live.point_rows import PointRows
from twin.maps.points import Voxels, best_per_voxel

NAMES = ["a", "b", "c", "d", "e"]


@st.composite
def parts(draw: st.DrawFn) -> Voxels:
    """A part's voxels: few keys, few distinct distances and points, so that parts tie."""
    keys = sorted(draw(st.sets(st.integers(0, 40), max_size=25)))
    n = len(keys)
    d2 = np.array(draw(st.lists(st.sampled_from([0.0, 0.25, 0.5]), min_size=n, max_size=n)))
    q = np.array(draw(st.lists(st.sampled_from([0.0, 1.0]), min_size=3 * n, max_size=3 * n))).reshape(n, 3)
    return Voxels(np.array(keys, dtype=np.int64), q, d2)


CHANGES = st.dictionaries(st.sampled_from(NAMES), st.none() | parts(), min_size=1, max_size=3)


def _same(a: Voxels, b: Voxels) -> bool:
    return bool(np.array_equal(a.keys, b.keys) and np.array_equal(a.q, b.q) and np.array_equal(a.d2, b.d2))


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
    rows = PointRows.of(names, [start[n] for n in names], **room)
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
    again = PointRows.unpacked(names, arrays)
    assert _same(again.winners(), rows.winners())
    assert again.won() == rows.won()
