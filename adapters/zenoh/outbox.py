"""Zenoh sends off the writer's thread, in the order the writer made them.

The twin's single writer must not wait for Zenoh: a reply, a put or a query's final message takes
0.1-0.5 ms of waiting in Zenoh (with the GIL released), a third of the writer's time under load. The
writer hands each send to an outbox instead, and the outbox's one thread makes them in order, so an
ack still follows the map updates of its change. The daemon runs several (:mod:`adapters.zenoh.daemon`):
its dispatcher, and one *lane* per link (the site's keys, each ROS 2 robot), so that a send blocked by a
slow link holds only that link's lane.

Example::

    outbox = Outbox()
    outbox.put(lambda: publisher.put(payload))
    outbox.drain()    # wait until everything put so far was sent
    outbox.close()    # drain, then stop the thread
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable

log = logging.getLogger(__name__)

Job = Callable[[], None]


class Outbox:
    """One thread that runs queued sends in order; a failing send is logged, never stops the others."""

    def __init__(self, name: str = "zenoh-outbox") -> None:
        self._jobs: queue.SimpleQueue[Job | None] = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._closed = False
        self._thread.start()

    def put(self, job: Job) -> None:
        """Queue ``job``; after :meth:`close` it runs at once on the caller's thread."""
        if self._closed:
            _run_one(job)
        else:
            self._jobs.put(job)

    @property
    def depth(self) -> int:
        """Sends queued and not yet made."""
        return self._jobs.qsize()

    def drain(self, timeout_s: float = 30.0) -> bool:
        """Wait until every send queued so far was made; False on time-out."""
        if self._closed:
            return True
        done = threading.Event()
        self._jobs.put(done.set)
        return done.wait(timeout_s)

    def close(self, timeout_s: float = 30.0) -> None:
        """Make every queued send, then stop the thread."""
        if self._closed:
            return
        self._jobs.put(None)
        self._thread.join(timeout_s)
        if self._thread.is_alive():
            log.error("The Zenoh outbox did not empty within %.0f s (%d sends left)", timeout_s, self.depth)
        self._closed = True

    def _run(self) -> None:
        while (job := self._jobs.get()) is not None:
            _run_one(job)


def _run_one(job: Job) -> None:
    try:
        job()
    except Exception:  # a send must never stop the others
        log.exception("A Zenoh send failed")
