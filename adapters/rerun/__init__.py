"""The Rerun adapter: records the twin's history (building, every map version, observations) as a
sink of the twin service, in a recorder process of its own, and reads maps back at any revision. See
:mod:`adapters.rerun.recorder` (the sink), :mod:`adapters.rerun.writer` (what is recorded),
:mod:`adapters.rerun.tiles` (maps exact at every revision) and :mod:`adapters.rerun.reader`.

The Rerun SDK is imported only when a recorder or reader is first used (about 0.3 s, more on a busy
machine): the ``[rerun]`` settings (:mod:`adapters.rerun.settings`), which every ``twin`` command
loads, and a daemon that records nothing never import it."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from adapters.rerun.reader import map_at, map_history
    from adapters.rerun.recorder import RerunRecorder

__all__ = ["RerunRecorder", "map_at", "map_history"]


def __getattr__(name: str) -> Any:
    if name == "RerunRecorder":
        return importlib.import_module("adapters.rerun.recorder").RerunRecorder
    if name in ("map_at", "map_history"):
        return getattr(importlib.import_module("adapters.rerun.reader"), name)
    msg = f"module 'adapters.rerun' has no attribute {name!r}"
    raise AttributeError(msg)
