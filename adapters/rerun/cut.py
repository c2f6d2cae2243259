"""Cut a range of the twin's history out of recordings into a new ``.rrd`` that replays alone.

The cut holds the static data (the building, tile placements), then *the state at the range's start*:
for every entity, the last row of each kind (a tile's cells, an observed element's mesh and
transform, a clear) logged before the range, stamped one tick before it, in their original order;
then every row inside the range. So the map an operator sees at any revision of the range is the one
the daemon served, the observed elements stand where they stood, and nothing after the range is kept.
Rotated files are read in order, as one recording. The cut carries the daemon's layout (a tab per
storey, a top-down view per skill map), rebuilt from the maps it holds.

Example::

    cut([Path("var/recordings/lab.rrd"), Path("var/recordings/lab-0001.rrd")], Path("morning.rrd"),
        timeline="revision", start=120, end=480)
"""

from __future__ import annotations

import logging
import re
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun as rr
import rerun.blueprint as rrb
import rerun.chunk as rc

from adapters.rerun.style import blueprint, looking_down
from twin.errors import TwinError

log = logging.getLogger(__name__)

_ROW_ID = "rerun.controls.RowId"


@dataclass(frozen=True, slots=True)
class CutSummary:
    """What a cut holds: rows of the state at its start, rows inside the range, static chunks."""

    state_rows: int
    range_rows: int
    static_chunks: int
    first: int | None = None
    """The sources' first and last value on the cut's timeline (None: no row has one)."""
    last: int | None = None


class RecordingError(TwinError):
    """A file given as a recording that Rerun cannot read (not a recording, empty, truncated)."""


def _unreadable(source: Path, err: Exception) -> RecordingError:
    reason = str(err).splitlines()[0] if str(err) else type(err).__name__
    reason = reason.removeprefix(f"Failed to read RRD file at {source}: ")
    if source.stat().st_size == 0:
        reason = "the file is empty"
    elif "exceeds file size" in reason:
        reason = f"it ends early, cut short: {reason}"
    msg = f"{source} is not a Rerun recording that can be read ({reason})."
    return RecordingError(msg)


def _chunks(sources: Sequence[Path]) -> Iterator[rc.Chunk]:
    for source in sources:
        if not source.exists():
            msg = f"Recording {source} does not exist."
            raise FileNotFoundError(msg)
        try:
            with warnings.catch_warnings():  # the daemon's files have no footer
                warnings.simplefilter("ignore")
                reader = rc.RrdReader(str(source))
            stores = reader.recordings()
        except (RuntimeError, ValueError, OSError) as err:  # Rerun's reader raises RuntimeError
            raise _unreadable(source, err) from None
        for store in stores:
            try:
                yield from reader.stream(store=store)
            except (RuntimeError, ValueError) as err:
                raise _unreadable(source, err) from None


def _restamped(row: pa.RecordBatch, timeline: str, at: int, entity: str) -> rc.Chunk:
    """``row`` at ``at`` on ``timeline``, with a fresh row id (so later than every original row)."""
    field = row.schema.field(timeline)
    row = row.set_column(
        row.schema.get_field_index(timeline), field, pa.array([at], type=pa.int64()).cast(field.type)
    )
    row = row.remove_column(row.schema.get_field_index(_ROW_ID))
    indexes = [f.name for f in row.schema if (f.metadata or {}).get(b"rerun:kind") == b"index"]
    return rc.Chunk.from_record_batch(row, index=indexes, entity_path=entity)[0]


class _Layout:
    """Storeys (elevation, extent) and skills, from the static tile placements: the cut's blueprint."""

    _TILE = re.compile(r"^/maps/([^/]+)/([^/]+)/tiles[^/]*/r\d+_c\d+$")

    def __init__(self) -> None:
        self.skills: dict[str, None] = {}
        self.storeys: dict[str, list[float]] = {}  # storey -> [elevation, xmin, ymin, xmax, ymax]

    def add(self, entity: str, batch: pa.RecordBatch) -> None:
        m = self._TILE.match(entity)
        names = batch.schema.names
        if m is None or not {"GridMap:translation", "GridMap:format", "GridMap:cell_size"} <= set(names):
            return
        (x, y, z), fmt = (
            batch.column("GridMap:translation")[0][0].as_py(),
            batch.column("GridMap:format")[0][0].as_py(),
        )
        size = batch.column("GridMap:cell_size")[0][0].as_py()
        x1, y0 = x + fmt["width"] * size, y - fmt["height"] * size  # the tile is turned about x
        self.skills[m[2]] = None
        box = self.storeys.setdefault(m[1], [z, x, y0, x1, y])
        box[1:] = [min(box[1], x), min(box[2], y0), max(box[3], x1), max(box[4], y)]

    def blueprint(self) -> rrb.Blueprint:
        storeys = sorted(self.storeys.items(), key=lambda item: item[1][0])
        cameras = {storey: looking_down(box[1], box[2], box[3], box[4], box[0]) for storey, box in storeys}
        return blueprint([(storey, box[0]) for storey, box in storeys], list(self.skills), cameras)


def cut(
    sources: Sequence[Path],
    out: Path,
    *,
    timeline: str = "revision",
    start: int | None = None,
    end: int | None = None,
    application: str = "building-twin",
) -> CutSummary:
    """Write the rows of ``sources`` in ``[start, end]`` on ``timeline`` (``revision``, or ``time`` in
    ns since the epoch) to ``out``, preceded by the state at ``start``. None: from the first or to the
    last row."""
    lo = start if start is not None else np.iinfo(np.int64).min + 1
    hi = end if end is not None else np.iinfo(np.int64).max
    if hi < lo:
        msg = f"The range to cut ends ({end}) before it starts ({start})."
        raise ValueError(msg)
    static: list[rc.Chunk] = []
    inside: list[rc.Chunk] = []
    latest: dict[tuple[str, frozenset[str]], tuple[tuple[int, bytes], pa.RecordBatch]] = {}
    range_rows = 0
    first: int | None = None
    last: int | None = None
    layout = _Layout()
    for chunk in _chunks(sources):
        if chunk.is_static:
            static.append(chunk)
            layout.add(chunk.entity_path, chunk.to_record_batch())
            continue
        batch = chunk.to_record_batch()
        if timeline not in batch.schema.names:
            continue
        times = np.asarray(batch.column(timeline).cast(pa.int64()).fill_null(lo - 1))
        within = (times >= lo) & (times <= hi)
        range_rows += int(within.sum())
        stamped = times[batch.column(timeline).is_valid().to_numpy(zero_copy_only=False)]
        if stamped.size:
            first = int(stamped.min()) if first is None else min(first, int(stamped.min()))
            last = int(stamped.max()) if last is None else max(last, int(stamped.max()))
        if within.all():
            inside.append(chunk)
        elif within.any():  # the rows inside keep their row ids and the chunk its id
            inside.extend(rc.Chunk.from_record_batch(batch.filter(pa.array(within))))
        entity = chunk.entity_path
        data = [f.name for f in batch.schema if (f.metadata or {}).get(b"rerun:kind") == b"data"]
        row_ids = batch.column(_ROW_ID)
        for k in np.flatnonzero(times < lo):
            row = batch.slice(int(k), 1)
            kind = frozenset(name for name in data if row.column(name).is_valid().to_pylist()[0])
            order = (int(times[k]), row_ids[int(k)].as_py())
            known = latest.get((entity, kind))
            if known is None or known[0] < order:
                latest[(entity, kind)] = (order, row)
    state = [
        _restamped(row, timeline, lo - 1, entity)
        for (entity, _), (_, row) in sorted(latest.items(), key=lambda item: item[1][0][1])
    ] if start is not None else []  # fmt: skip
    stream = rr.RecordingStream(application_id=application)
    stream.set_sinks(rr.FileSink(str(out)))
    stream.send_blueprint(layout.blueprint())
    rr.send_chunks([*static, *state, *inside], recording=stream)
    stream.flush()
    stream.disconnect()
    log.info("Cut %d state rows and %d rows in range into %s", len(state), range_rows, out)
    return CutSummary(len(state), range_rows, len(static), first, last)
