"""The Rerun adapter: records the twin's history (building, every map version, observations) as a
sink of the twin service, in a recorder process of its own, and reads maps back at any revision. See
:mod:`adapters.rerun.recorder` (the sink), :mod:`adapters.rerun.writer` (what is recorded),
:mod:`adapters.rerun.tiles` (maps exact at every revision) and :mod:`adapters.rerun.reader`."""

from __future__ import annotations

from adapters.rerun.reader import map_at, map_history
from adapters.rerun.recorder import RerunRecorder

__all__ = ["RerunRecorder", "map_at", "map_history"]
