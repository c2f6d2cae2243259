"""The Rerun adapter: records the twin's history (building, every map version, observations) as a
sink of the twin service, and reads maps back at any revision. See :mod:`adapters.rerun.recorder` and
:mod:`adapters.rerun.reader`."""

from __future__ import annotations

from adapters.rerun.reader import map_at, map_history
from adapters.rerun.recorder import RerunRecorder

__all__ = ["RerunRecorder", "map_at", "map_history"]
