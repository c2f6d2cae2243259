"""The daemon's Zenoh callbacks, counted, so that a stop can wait for the ones running.

Zenoh calls back on its own native threads. A callback still inside Python when the process ends
would re-enter the interpreter while it finalizes (glibc then aborts: ``FATAL: exception not
rethrown``). A :class:`CallbackGate` wraps each callback: after :meth:`CallbackGate.close`, a new one
returns at once, and close waits (up to a deadline) for those running.

Example::

    gate = CallbackGate()
    session.declare_queryable(key, gate.wrap(on_query))
    ...
    gate.close(timeout_s=5.0)   # then undeclare and close the session
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


class CallbackGate:
    """Counts the callbacks running; closed, it lets none in."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._running = 0
        self._closed = False

    def wrap(self, callback: Callable[[T], None]) -> Callable[[T], None]:
        """``callback``, counted while it runs; a no-op once the gate is closed."""

        def guarded(arg: T) -> None:
            with self._cond:
                if self._closed:
                    return
                self._running += 1
            try:
                callback(arg)
            finally:
                with self._cond:
                    self._running -= 1
                    if self._closed:  # only a close waits (it closes first, under the same lock)
                        self._cond.notify_all()

        return guarded

    @property
    def running(self) -> int:
        with self._cond:
            return self._running

    def shut(self) -> None:
        """Let no new callback in (those running go on)."""
        with self._cond:
            self._closed = True

    def close(self, timeout_s: float) -> int:
        """Let no new callback in; wait up to ``timeout_s`` for the running ones. Returns how many
        are still running (0: none)."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            self._closed = True
            self._cond.wait_for(lambda: self._running == 0, timeout=max(0.0, deadline - time.monotonic()))
            return self._running
