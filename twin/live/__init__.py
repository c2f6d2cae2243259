"""The live twin: the single writer that applies robots' observations and keeps every map current.

- :mod:`twin.live.service`: :class:`TwinService`, the writer's loop, start-up and status;
- :mod:`twin.live.observe`: the hot path, a batch of observations from payload to acks;
- :mod:`twin.live.plan`: one observation checked against the twin, as the triples it changes;
- :mod:`twin.live.membership`: which skills select a changed element, from memory;
- :mod:`twin.live.live_maps`: every (storey, skill) map, re-rendered where it changed;
- :mod:`twin.live.state`: what the writer holds of each element;
- :mod:`twin.live.skill_changes`: skills added and removed at run time;
- :mod:`twin.live.query`: read-only SPARQL with its bounds;
- :mod:`twin.live.requests`: requests and replies.

The three names below are imported when first used: a module of this package (``twin import``'s
:func:`~twin.live.snapshots.snapshot_path`, the events a client decodes) loads without the writer.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from twin.live.publication import PublishedVersion
    from twin.live.requests import Reply
    from twin.live.service import TwinService

__all__ = ["PublishedVersion", "Reply", "TwinService"]

_MODULES = {"PublishedVersion": "publication", "Reply": "requests", "TwinService": "service"}


def __getattr__(name: str) -> Any:
    if name in _MODULES:
        return getattr(importlib.import_module(f"twin.live.{_MODULES[name]}"), name)
    msg = f"module 'twin.live' has no attribute {name!r}"
    raise AttributeError(msg)
