"""What the live twin is asked (observations, skill changes, why a cell is occupied) and what it answers.

Requests come from any thread (e.g. Zenoh callbacks) into the service's queue; each carries the
callback its :class:`Reply` goes to.
"""

from __future__ import annotations

import json
import queue
import time
from collections.abc import Callable
from dataclasses import dataclass

from twin.records import Observation


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
    """An observation by ``robot``: a Turtle document (``payload``), or the typed records an adapter in
    the daemon's process made (``observation``, ``payload`` empty), checked by the same validator."""

    robot: str
    payload: bytes
    reply: ReplyFn | None
    received_ns: int
    observation: Observation | None = None
    checked: bool = False
    """``observation`` passed :func:`~twin.live.validate.check_observation` under the writer's limits
    where it was made (:class:`~twin.live.validate.Checked`): not checked again."""


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


@dataclass(frozen=True, slots=True)
class StoreyRequest:
    """Put ``robot`` on ``storey`` (it took the lift); ``source`` says who asked (``"zenoh"``, ``"ros"``)."""

    robot: str
    storey: str
    source: str
    reply: ReplyFn | None


Request = ObserveRequest | SkillRequest | ExplainRequest | StoreyRequest


class RequestQueue:
    """The service's queue: any thread puts, the writer takes the next piece of work, where
    observations queued one behind the other come as one batch (group commit).

    It holds a :class:`queue.Queue`, not the cheaper :class:`queue.SimpleQueue`: CPython's
    ``SimpleQueue.get(timeout=...)``, interrupted by a signal whose handler ends after the timeout's
    deadline, goes on waiting with a negative timeout, which means forever (``_queuemodule.c``
    recomputes the timeout without checking its sign; the locks of ``threading`` check it). The writer
    waits in :meth:`take` between requests, so an idle daemon's SIGTERM that came late in a wait left it
    waiting for a next request that never came: a stop that never began (about once in 50-100 stops at
    load 5-10). ``Queue`` costs about a microsecond more per request."""

    def __init__(self, max_batch: int, *, wait_s: float = 0.0) -> None:
        """``wait_s``: after taking the first observation of a batch, how long to wait (one sleep) for
        more to join it (robots that report at the same instants arrive a few hundred microseconds
        apart; 0: take only what is queued)."""
        self.max_batch = max(1, max_batch)
        self.wait_s = max(0.0, wait_s)
        self._queue: queue.Queue[Request] = queue.Queue()  # not SimpleQueue (above)
        self._held: Request | None = None  # taken while batching, handled next

    def put(self, request: Request) -> None:
        self._queue.put(request)

    @property
    def depth(self) -> int:
        return self._queue.qsize() + (self._held is not None)

    def take(
        self, timeout_s: float = 0.0
    ) -> list[ObserveRequest] | SkillRequest | ExplainRequest | StoreyRequest | None:
        """The next work: a batch of up to ``max_batch`` observations queued in a row (those that came
        within ``wait_s`` of taking the first included), or one other request; None if nothing came
        within ``timeout_s`` (0: do not wait)."""
        if self._held is not None:
            request: Request = self._held
            self._held = None
        else:
            try:
                request = self._queue.get(timeout=timeout_s) if timeout_s > 0 else self._queue.get_nowait()
            except queue.Empty:
                return None
        if not isinstance(request, ObserveRequest):
            return request
        batch = [request]
        if self.wait_s > 0 and self._queue.qsize() < self.max_batch - 1:
            time.sleep(self.wait_s)  # one wake-up for those that follow, not one each
        while len(batch) < self.max_batch:
            try:
                nxt = self._queue.get_nowait()
            except queue.Empty:
                break
            if not isinstance(nxt, ObserveRequest):
                self._held = nxt
                break
            batch.append(nxt)
        return batch
