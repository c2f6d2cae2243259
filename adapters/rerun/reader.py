"""Read the twin's maps back from a recording (``.rrd``), at any revision.

The recorder logs each map as tiles (``maps/<storey>/<skill>/tiles/r<i>_c<j>``), each tile again at
every revision that changed one of its cells. :func:`map_history` replays those logs in revision order
and gives the whole map after each revision that changed it: exactly what the daemon served then.

Example::

    history = map_history(Path("var/recordings/lab.rrd"), "ground-floor", "navigation")
    revision, cells = history[-1]          # (h, w) int8, row 0 = the lowest y
    at_3 = map_at(history, 3)              # the map as served at revision 3
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt
import rerun.chunk as rc

from adapters.rerun.recorder import TILE

GridCells = npt.NDArray[np.int8]
_TILE = re.compile(r"/tiles/r(\d+)_c(\d+)$")


def _column(batch: object, name: str) -> list[object] | None:
    schema = batch.schema  # type: ignore[attr-defined]
    index = schema.get_field_index(name)
    if index < 0:
        return None
    values: list[object] = batch.column(index).to_pylist()  # type: ignore[attr-defined]
    return values


def _tile_logs(path: Path, storey: str, skill: str) -> list[tuple[int, int, int, GridCells]]:
    """``(revision, i, j, cells)`` of every tile log of one map, in the order they were written."""
    prefix = f"/maps/{storey}/{skill}/tiles/"
    out: list[tuple[int, int, int, GridCells]] = []
    for chunk in rc.RrdReader(str(path)).stream().to_chunks():
        entity = str(chunk.entity_path)
        m = _TILE.search(entity)
        if not entity.startswith(prefix) or m is None:
            continue
        batch = chunk.to_record_batch()
        revisions, datas, formats = (
            _column(batch, n) for n in ("revision", "GridMap:data", "GridMap:format")
        )
        if revisions is None or datas is None or formats is None:
            continue
        for rev, data, fmt in zip(revisions, datas, formats, strict=True):
            if data is None or fmt is None:
                continue
            f = fmt[0]  # type: ignore[index]
            cells = np.array(data[0], dtype=np.uint8).view(np.int8).reshape(f["height"], f["width"])  # type: ignore[index]
            out.append((int(rev or 0), int(m[1]), int(m[2]), cells))  # type: ignore[call-overload]
    return out


def map_history(path: Path, storey: str, skill: str) -> list[tuple[int, GridCells]]:
    """Every version of one map in a recording: ``(revision, cells)`` after each revision that logged
    one of its tiles, in revision order. Empty if the recording has no such map."""
    logs = sorted(_tile_logs(path, storey, skill), key=lambda t: t[0])  # stable: written order kept
    if not logs:
        return []
    height = max(i * TILE + c.shape[0] for _, i, _, c in logs)
    width = max(j * TILE + c.shape[1] for _, _, j, c in logs)
    cells: GridCells = np.full((height, width), -1, dtype=np.int8)
    history: list[tuple[int, GridCells]] = []
    for k, (rev, i, j, tile) in enumerate(logs):
        cells[i * TILE : i * TILE + tile.shape[0], j * TILE : j * TILE + tile.shape[1]] = tile
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
