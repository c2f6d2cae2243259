"""Read the twin's maps back from a recording (``.rrd``), at any revision.

The recorder logs each map as tiles (``maps/<storey>/<skill>/tiles/r<i>_c<j>``: a static placement,
then the cells when the map appears and again at every revision that changed one of them).
:func:`map_history` replays those logs in revision order and gives the whole map after each revision
that changed it: exactly what the daemon served then.

Example::

    history = map_history(Path("var/recordings/lab.rrd"), "ground-floor", "navigation")
    revision, cells = history[-1]          # (h, w) int8, row 0 = the lowest y
    at_3 = map_at(history, 3)              # the map as served at revision 3
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt
import rerun.chunk as rc

from adapters.rerun.tiles import TILE

GridCells = npt.NDArray[np.int8]
_TILE = re.compile(r"/tiles(?:_(\d+))?/r(\d+)_c(\d+)$")


def _column(batch: object, name: str) -> list[object] | None:
    schema = batch.schema  # type: ignore[attr-defined]
    index = schema.get_field_index(name)
    if index < 0:
        return None
    values: list[object] = batch.column(index).to_pylist()  # type: ignore[attr-defined]
    return values


TileLog = tuple[int, int, int, int, bytes]
"""``(revision, generation, i, j, cells)`` of one logged tile."""
TileKey = tuple[int, int, int]
"""``(generation, i, j)``."""


def _tile_logs(path: Path, storey: str, skill: str) -> tuple[list[TileLog], dict[TileKey, tuple[int, int]]]:
    """``(revision, generation, i, j, cells)`` of every tile log of one map, in written order, and
    each tile's ``(height, width)`` from its static placement."""
    prefix = f"/maps/{storey}/{skill}/tiles"
    out: list[TileLog] = []
    shapes: dict[TileKey, tuple[int, int]] = {}
    with warnings.catch_warnings():  # the recorder writes no footer (it grows with every chunk)
        warnings.simplefilter("ignore")
        reader = rc.RrdReader(str(path))
    for chunk in reader.stream().to_chunks():
        entity = str(chunk.entity_path)
        m = _TILE.search(entity)
        if not entity.startswith(prefix) or m is None:
            continue
        tile = (int(m[1] or 0), int(m[2]), int(m[3]))
        batch = chunk.to_record_batch()
        formats = _column(batch, "GridMap:format")
        for fmt in formats or []:
            if fmt is not None:
                f = fmt[0]  # type: ignore[index]
                shapes[tile] = (int(f["height"]), int(f["width"]))
        revisions, datas = _column(batch, "revision"), _column(batch, "GridMap:data")
        if revisions is None or datas is None:
            continue
        for rev, data in zip(revisions, datas, strict=True):
            if data is not None:
                out.append((int(rev or 0), *tile, bytes(data[0])))  # type: ignore[call-overload,index]
    return out, shapes


def map_history(path: Path, storey: str, skill: str) -> list[tuple[int, GridCells]]:
    """Every version of one map in a recording: ``(revision, cells)`` after each revision that logged
    one of its tiles, in revision order. Empty if the recording has no such map. A map whose frame
    changed (a new generation of tiles) starts over from its new tiles."""
    written, shapes = _tile_logs(path, storey, skill)
    logs = sorted(written, key=lambda t: t[0])  # stable: written order kept
    history: list[tuple[int, GridCells]] = []
    cells: GridCells = np.zeros((0, 0), dtype=np.int8)
    generation = -1
    for k, (rev, g, i, j, data) in enumerate(logs):
        if g != generation:  # the map's extent from its tiles' placements
            generation = g
            mine = [(ti, tj, hw) for (tg, ti, tj), hw in shapes.items() if tg == g]
            height = max(ti * TILE + hw[0] for ti, _, hw in mine)
            width = max(tj * TILE + hw[1] for _, tj, hw in mine)
            cells = np.full((height, width), -1, dtype=np.int8)
        h, w = shapes[(g, i, j)]
        cells[i * TILE : i * TILE + h, j * TILE : j * TILE + w] = np.frombuffer(data, np.int8).reshape(h, w)
        if k + 1 == len(logs) or logs[k + 1][0] != rev:
            history.append((rev, cells.copy()))
    return history


def map_at(history: Sequence[tuple[int, GridCells]], revision: int) -> GridCells | None:
    """The map as it was at ``revision`` (the last version at or before it), None before the first."""
    found = None
    for rev, cells in history:
        if rev > revision:
            break
        found = cells
    return found
