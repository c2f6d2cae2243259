"""What the live twin is asked (observations, skill changes, why a cell is occupied) and what it answers.

Requests come from any thread (e.g. Zenoh callbacks) into the service's queue; each carries the
callback its :class:`Reply` goes to.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Reply:
    """The answer to a request: ``ok`` with a body, or an error message naming what was wrong."""

    ok: bool
    body: dict[str, object]

    @classmethod
    def error(cls, message: str) -> Reply:
        return cls(False, {"ok": False, "error": message})

    def to_json(self) -> bytes:
        return json.dumps(self.body).encode()


ReplyFn = Callable[[Reply], None]


@dataclass(frozen=True, slots=True)
class ObserveRequest:
    robot: str
    payload: bytes
    reply: ReplyFn | None
    received_ns: int


@dataclass(frozen=True, slots=True)
class SkillRequest:
    name: str
    payload: bytes | None  # None: remove
    reply: ReplyFn | None


@dataclass(frozen=True, slots=True)
class ExplainRequest:
    """Why the cell of map (``storey``, ``skill``) at world ``(x, y)`` is what it is."""

    storey: str
    skill: str
    x: float
    y: float
    reply: ReplyFn | None


Request = ObserveRequest | SkillRequest | ExplainRequest
