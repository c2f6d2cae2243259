"""The rows of one live points map: every selected element's own voxels in one arena, indexed by voxel.

A points map keeps, per selected element (a *part*), the voxels it touches with its own point (and the
point's normal, float32) in each and whether that point is the voxel's (it *wins*). A change must find,
for the voxels it concerns, every part's row there: the rows live in flat arrays (an arena: each part one
contiguous slice, a dropped part's slice dead until the arena is compacted) and are found by voxel key
through a sorted index (a large sorted base and a small sorted delta of the rows added since the base was
merged, so that a change costs its own rows, not the map's). Winners are decided with whole-array
operations on the rows of the concerned voxels only.

Example::

    rows = PointRows.of(["wall", "slab"], [wall_voxels, slab_voxels], distance=plan.distance)
    changed = rows.replace({"wall": moved_wall_voxels})     # True if a point of the cloud changed
    cloud = rows.winners()                                  # one point per voxel, sorted by key
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence

import numpy as np
import numpy.typing as npt

from twin.maps.points import Voxels, best_rows, sorted_unique
from twin.maps.raster.settings import BoolArray
from twin.maps.voxels import FloatArray, IntArray

__all__ = ["Distance", "PointRows"]

_SPARE = 1 << 16
"""Rows the arena holds beyond its live rows at least (and an eighth of them): room for changes."""
_ROW = np.int32
"""The index's row numbers (4 bytes a row: an arena holds fewer than 2**31 rows)."""
_MAX_ROWS = 2**31 - 1
_DELTA = 1 << 16
"""Index rows kept in the delta before it is merged into the base (at least; or an eighth of the base)."""

RowArray = npt.NDArray[np.int32]
Distance = Callable[[IntArray, FloatArray], FloatArray]
"""``(keys (n,), points (n, 3)) -> (n,)``: each point's squared distance to its voxel's centre."""


def _merge(
    keys_a: IntArray, rows_a: RowArray, keys_b: IntArray, rows_b: RowArray
) -> tuple[IntArray, RowArray]:
    """Two key-sorted index runs as one (``b``'s rows after ``a``'s at equal keys): each ``b`` entry's
    place found by binary search, the rest scattered around them (linear, no sort)."""
    n = len(keys_a) + len(keys_b)
    at = np.searchsorted(keys_a, keys_b, side="right") + np.arange(len(keys_b))
    others = np.ones(n, dtype=np.bool_)
    others[at] = False
    keys, rows = np.empty(n, dtype=np.int64), np.empty(n, dtype=_ROW)
    keys[at], rows[at] = keys_b, rows_b
    keys[others], rows[others] = keys_a, rows_a
    return keys, rows


def _hits(index_keys: IntArray, index_rows: RowArray, keys: IntArray) -> IntArray:
    """The rows an index holds at ``keys`` (sorted; a voxel has a row per part that touches it: few)."""
    out = [np.empty(0, dtype=np.int64)]
    if not len(index_keys) or not len(keys):
        return out[0]
    at = np.searchsorted(index_keys, keys)
    while len(at):
        inside = at < len(index_keys)
        at, keys = at[inside], keys[inside]
        same = index_keys[at] == keys
        at, keys = at[same], keys[same]
        out.append(index_rows[at])
        at = at + 1
    return np.concatenate(out)


class PointRows(Mapping[str, Voxels]):
    """Each part's voxels (``rows[iri]``: a :class:`Voxels`, views into the arena) and who wins where."""

    def __init__(self, distance: Distance, *, spare: int = _SPARE, delta: int = _DELTA) -> None:
        self._distance = distance
        """A point's squared distance to its voxel's centre (from its key): not stored, 8 bytes a row."""
        self._spare_min = spare
        self._delta_min = delta
        self._keys = np.empty(0, dtype=np.int64)
        self._q = np.empty((0, 3))
        self._n = np.empty((0, 3), dtype=np.float32)
        """Each row's normal (12 bytes: what the files carry, so no rounding between map and file)."""
        self._own = np.empty(0, dtype=np.int32)
        """Each row's part (slot), -1 once the part is dropped."""
        self._wins = np.empty(0, dtype=np.bool_)
        self._end = 0
        self._dead = 0
        self._slot: dict[str, int] = {}
        self._names: list[str | None] = []
        self._free: list[int] = []
        self._start: list[int] = []
        self._stop: list[int] = []
        """Per slot: its rows ``[start, stop)`` in the arena."""
        self._base: tuple[IntArray, RowArray] = (np.empty(0, dtype=np.int64), np.empty(0, dtype=_ROW))
        self._delta: tuple[IntArray, RowArray] = (np.empty(0, dtype=np.int64), np.empty(0, dtype=_ROW))

    # --- building ------------------------------------------------------------------------------------
    @classmethod
    def of(
        cls,
        names: Sequence[str],
        parts: Sequence[Voxels],
        wins: Sequence[BoolArray] | None = None,
        *,
        distance: Distance,
        spare: int = _SPARE,
        delta: int = _DELTA,
    ) -> PointRows:
        """The rows of ``parts`` (each sorted by key, one row per key), winners decided (or as given).
        ``spare``, ``delta``: the arena's spare rows and the index's delta before a merge (at least)."""
        out = cls(distance, spare=spare, delta=delta)
        keep = [i for i, p in enumerate(parts) if len(p)]
        n = sum(len(parts[i]) for i in keep)
        out._alloc(n)
        start = 0
        for slot, i in enumerate(keep):  # each part straight into the arena (no flat copy first)
            part = parts[i]
            stop = start + len(part)
            out._keys[start:stop], out._q[start:stop], out._n[start:stop] = part.keys, part.q, part.n
            out._slot[names[i]] = slot
            out._names.append(names[i])
            out._start.append(start)
            out._stop.append(stop)
            out._own[start:stop] = slot
            start = stop
        out._end = n
        order = np.argsort(out._keys[:n], kind="stable")
        out._base = (out._keys[:n][order], order.astype(_ROW))
        if wins is None:
            out._decide(np.arange(n, dtype=np.int64))
        else:
            out._wins[:n] = np.concatenate([wins[i] for i in keep]) if keep else np.zeros(0, dtype=np.bool_)
        return out

    def _alloc(self, live: int) -> None:
        cap = live + max(self._spare_min, live // 8)
        if cap >= _MAX_ROWS:
            msg = f"a points map of {live} rows: more than an arena holds ({_MAX_ROWS})"
            raise ValueError(msg)
        self._keys = np.empty(cap, dtype=np.int64)
        self._q = np.empty((cap, 3))
        self._n = np.empty((cap, 3), dtype=np.float32)
        self._own = np.full(cap, -1, dtype=np.int32)
        self._wins = np.zeros(cap, dtype=np.bool_)

    # --- the mapping of parts ------------------------------------------------------------------------
    def __getitem__(self, iri: str) -> Voxels:
        slot = self._slot[iri]
        start, stop = self._start[slot], self._stop[slot]
        keys, q = self._keys[start:stop], self._q[start:stop]
        return Voxels(keys, q, self._distance(keys, q), self._n[start:stop])

    def __iter__(self) -> Iterator[str]:
        return iter(self._slot)

    def __len__(self) -> int:
        return len(self._slot)

    def _keys_of(self, iri: str) -> IntArray:
        slot = self._slot[iri]
        return self._keys[self._start[slot] : self._stop[slot]]

    def wins_of(self, iri: str) -> BoolArray:
        """Which of the part's voxels hold its point (a copy)."""
        slot = self._slot[iri]
        return self._wins[self._start[slot] : self._stop[slot]].copy()

    @property
    def rows(self) -> int:
        """Live rows (every part's voxels)."""
        return self._end - self._dead

    def won(self) -> int:
        """Rows that hold their voxel's point (a voxel tied between parts counts once per part)."""
        return int(np.count_nonzero(self._wins[: self._end]))

    # --- queries -------------------------------------------------------------------------------------
    def _at(self, keys: IntArray) -> IntArray:
        """Every live row at ``keys`` (sorted, unique)."""
        rows = np.concatenate([_hits(*self._base, keys), _hits(*self._delta, keys)])
        live: IntArray = rows[self._own[rows] >= 0]
        return live

    def _best(self, rows: IntArray) -> Voxels:
        """One point per key among ``rows`` that win (tied parts hold the same point), sorted by key."""
        won = rows[self._wins[rows]]
        keys = self._keys[won]
        order = np.argsort(keys, kind="stable")
        won, keys = won[order], keys[order]
        first = np.ones(len(keys), dtype=np.bool_)
        first[1:] = keys[1:] != keys[:-1]
        won = won[first]
        # (compared by key, point and normal)
        return Voxels(self._keys[won], self._q[won], np.zeros(len(won)), self._n[won])

    def winners(self) -> Voxels:
        """Every winning voxel, one point per key, sorted by key."""
        runs = []
        for index_keys, index_rows in (self._base, self._delta):
            won = self._wins[index_rows]  # dead rows never win
            runs.append((index_keys[won], index_rows[won]))
        keys = np.concatenate([runs[0][0], runs[1][0]])
        rows = np.concatenate([runs[0][1], runs[1][1]])
        order = np.argsort(keys, kind="stable")  # two sorted runs: a merge
        keys, rows = keys[order], rows[order]
        first = np.ones(len(keys), dtype=np.bool_)
        first[1:] = keys[1:] != keys[:-1]
        rows = rows[first]
        keys, q = self._keys[rows], self._q[rows]
        return Voxels(keys, q, self._distance(keys, q), self._n[rows])

    def _decide(self, rows: IntArray) -> None:
        """Decide the winners among ``rows`` (every live row of their keys)."""
        if not len(rows):
            return
        keys, q, n = self._keys[rows], self._q[rows], self._n[rows]
        d2 = self._distance(keys, q)
        best = best_rows(keys, q, d2, n)  # sorted by key
        at = np.searchsorted(keys[best], keys)
        b = best[at]
        self._wins[rows] = (d2 == d2[b]) & (q == q[b]).all(axis=1) & (n == n[b]).all(axis=1)

    # --- changes -------------------------------------------------------------------------------------
    def replace(self, changes: Mapping[str, Voxels | None]) -> bool:
        """Give each named part its new voxels (None or empty: the part is gone) and decide the winners of
        the voxels they touched before or touch now; True if the cloud's points there changed."""
        fresh = {i: p for i, p in changes.items() if p is not None and len(p)}
        touched = [self._keys_of(i) for i in changes if i in self._slot] + [p.keys for p in fresh.values()]
        if not touched:
            return False
        keys = sorted_unique(np.concatenate(touched))
        rows = self._at(keys)
        before = self._best(rows)
        for iri in changes:
            self._drop(iri)
        n_new = sum(len(p) for p in fresh.values())
        if self._end + n_new > len(self._keys):
            self._compact(n_new)
            rows = self._at(keys)
        else:
            rows = rows[self._own[rows] >= 0]
        start = self._end
        for iri, part in fresh.items():
            self._add(iri, part)
        rows = np.concatenate([rows, np.arange(start, self._end, dtype=np.int64)])
        self._decide(rows)
        after = self._best(rows)
        if len(self._delta[0]) > max(self._delta_min, len(self._base[0]) // 8):
            self._merge_index()
        return not (
            np.array_equal(before.keys, after.keys)
            and np.array_equal(before.q, after.q)
            and np.array_equal(before.n, after.n)
        )

    def _drop(self, iri: str) -> None:
        slot = self._slot.pop(iri, None)
        if slot is None:
            return
        start, stop = self._start[slot], self._stop[slot]
        self._own[start:stop] = -1
        self._wins[start:stop] = False
        self._dead += stop - start
        self._names[slot] = None
        self._start[slot] = self._stop[slot] = 0
        self._free.append(slot)

    def _add(self, iri: str, part: Voxels) -> None:
        """Append a part (the arena has room: see :meth:`replace`)."""
        n = len(part)
        start, stop = self._end, self._end + n
        self._keys[start:stop], self._q[start:stop], self._n[start:stop] = part.keys, part.q, part.n
        self._wins[start:stop] = False
        if self._free:
            slot = self._free.pop()
            self._names[slot] = iri
            self._start[slot], self._stop[slot] = start, stop
        else:
            slot = len(self._names)
            self._names.append(iri)
            self._start.append(start)
            self._stop.append(stop)
        self._slot[iri] = slot
        self._own[start:stop] = slot
        self._end = stop
        self._delta = _merge(*self._delta, part.keys, np.arange(start, stop, dtype=_ROW))

    def _merge_index(self) -> None:
        """Fold the delta into the base, leaving dead rows out."""
        (bk, br), (dk, dr) = self._base, self._delta
        alive_b, alive_d = self._own[br] >= 0, self._own[dr] >= 0
        self._base = _merge(bk[alive_b], br[alive_b], dk[alive_d], dr[alive_d])
        self._delta = (np.empty(0, dtype=np.int64), np.empty(0, dtype=_ROW))

    def _compact(self, extra: int) -> None:
        """A new arena of the live rows (in the same order), with room for ``extra`` more."""
        end = self._end
        keep = self._own[:end] >= 0
        live = int(keep.sum())
        new_row = (np.cumsum(keep) - 1).astype(_ROW)
        old_own = self._own
        old: tuple[npt.NDArray[np.generic], ...] = (self._keys, self._q, self._n, self._own, self._wins)
        self._alloc(live + extra)
        fresh: tuple[npt.NDArray[np.generic], ...] = (self._keys, self._q, self._n, self._own, self._wins)
        for new, was in zip(fresh, old, strict=True):
            np.compress(keep, was[:end], axis=0, out=new[:live])
        if self._start:
            start, stop = np.array(self._start, dtype=np.int64), np.array(self._stop, dtype=np.int64)
            used = stop > start
            moved = np.where(used, new_row[np.where(used, start, 0)], 0) if end else np.zeros_like(start)
            self._start = moved.tolist()
            self._stop = (moved + stop - start).tolist()
        (bk, br), (dk, dr) = self._base, self._delta
        alive_b, alive_d = old_own[br] >= 0, old_own[dr] >= 0
        self._base = _merge(bk[alive_b], new_row[br[alive_b]], dk[alive_d], new_row[dr[alive_d]])
        self._delta = (np.empty(0, dtype=np.int64), np.empty(0, dtype=_ROW))
        self._end, self._dead = live, 0

    # --- snapshots -----------------------------------------------------------------------------------
    def packed(self) -> tuple[list[str], dict[str, npt.NDArray[np.generic]]]:
        """The parts by name as flat arrays: ``keys, q, d2, n, wins`` per row, ``counts`` per part."""
        names = sorted(self._slot)
        spans = [(self._start[self._slot[n]], self._stop[self._slot[n]]) for n in names]
        counts = np.array([stop - start for start, stop in spans], dtype=np.int64)
        rows = (
            np.concatenate([np.arange(start, stop) for start, stop in spans])
            if spans
            else np.empty(0, dtype=np.int64)
        )
        arrays: dict[str, npt.NDArray[np.generic]] = {
            "keys": self._keys[rows],
            "q": self._q[rows],
            "d2": self._distance(self._keys[rows], self._q[rows]),
            "n": self._n[rows],
            "wins": self._wins[rows],
            "counts": counts,
        }
        return names, arrays

    @classmethod
    def unpacked(
        cls, names: Sequence[str], arrays: Mapping[str, npt.NDArray[np.generic]], *, distance: Distance
    ) -> PointRows:
        """Rows from :meth:`packed`'s arrays (ValueError if they disagree; distances are recomputed)."""
        counts = np.asarray(arrays["counts"], dtype=np.int64)
        n = len(arrays["keys"])
        if len(counts) != len(names) or int(counts.sum()) != n or (counts < 0).any():
            msg = f"{len(names)} parts and {len(counts)} counts of {n} rows"
            raise ValueError(msg)
        start = np.concatenate([[0], np.cumsum(counts)])
        keys = np.asarray(arrays["keys"], dtype=np.int64)
        q = np.asarray(arrays["q"], dtype=np.float64).reshape(n, 3)
        normals = np.asarray(arrays["n"], dtype=np.float32).reshape(n, 3)
        wins = np.asarray(arrays["wins"], dtype=np.bool_)
        parts, won = [], []
        for i in range(len(names)):
            rows = slice(int(start[i]), int(start[i + 1]))
            parts.append(Voxels(keys[rows], q[rows], np.empty(0), normals[rows]))  # (d2 unused by of())
            won.append(wins[rows])
        return cls.of(names, parts, won, distance=distance)
