"""The Rerun adapter: records the twin's history (building, every map version, observations) as a
sink of the twin service. See :mod:`adapters.rerun.recorder`."""

from __future__ import annotations

from adapters.rerun.recorder import RerunRecorder

__all__ = ["RerunRecorder"]
