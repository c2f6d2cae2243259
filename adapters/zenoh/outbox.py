"""Zenoh sends off the writer's thread, in the order the writer made them.

The twin's single writer must not wait for Zenoh: a reply, a put or a query's final message takes
0.1-0.5 ms of waiting in Zenoh (with the GIL released), a third of the writer's time under load. The
writer hands each send to an outbox instead, and the outbox's one thread makes them in order, so an
ack still follows the map updates of its change. The daemon runs several (:mod:`adapters.zenoh.daemon`):
its dispatcher, and one *lane* per link (the site's keys, each ROS 2 robot), so that a send blocked by a
slow link holds only that link's lane.

Sends that come in a burst (a batch's acks: up to a few dozen at once) are *joined*: a joined send
queued right after another joined one (nothing put between them) runs with it as one job, so that the
outbox's thread wakes once for the burst, not once per send; the order stays the order they were
queued in. And while the writer *holds* the outbox (:meth:`Outbox.hold`, for one piece of its work: a
batch of observations, its map updates and its acks), what it puts gathers and goes to the outbox's
thread as one job when it lets go (:meth:`Outbox.release`): the thread is not woken in the middle of
the batch to fight the writer for the interpreter. Another thread's put, a drain or a close hands on
what was gathered first, so the order is always the order of the puts.

Example::

    outbox = Outbox()
    outbox.put(lambda: publisher.put(payload))
    outbox.join(lambda: reply(a)); outbox.join(lambda: reply(b))    # one wake-up for both
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
        self._lock = threading.Lock()  # orders put and join between threads; held for a queue put
        self._open: list[Job] | None = None  # the joined sends queued as one job, not yet taken
        self._holder: int | None = None  # the thread whose puts gather (hold .. release)
        self._held: list[Job] = []
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._closed = False
        self._thread.start()

    def put(self, job: Job) -> None:
        """Queue ``job``; after :meth:`close` it runs at once on the caller's thread."""
        if self._closed:
            _run_one(job)
            return
        with self._lock:
            if self._gathered(job):
                return
            self._open = None  # a send joined later must not overtake this one
            self._jobs.put(job)

    def join(self, job: Job) -> None:
        """Queue ``job`` as :meth:`put` does, run with the joined jobs queued right before it (nothing
        put between them) as one job of the outbox's thread, each on its own (a failing one is logged)."""
        if self._closed:
            _run_one(job)
            return
        with self._lock:
            if self._gathered(job):
                return
            if self._open is not None:
                self._open.append(job)
                return
            group = self._open = [job]
            self._jobs.put(lambda: self._run_joined(group))

    def hold(self) -> None:
        """From now on gather the calling thread's puts and joins, in order, until :meth:`release`."""
        with self._lock:
            self._queue_held()
            self._holder = threading.get_ident()

    def release(self) -> None:
        """Queue what was gathered since :meth:`hold` as one job, and gather no more."""
        with self._lock:
            self._holder = None
            self._queue_held()

    def _gathered(self, job: Job) -> bool:
        """(Lock held.) ``job`` gathered, if its thread holds the outbox; another thread's job first
        queues what was gathered (the order of the puts is the order of the sends)."""
        if self._holder is None:
            return False
        if self._holder == threading.get_ident():
            self._held.append(job)
            return True
        self._queue_held()
        return False

    def _queue_held(self) -> None:
        """(Lock held.) What was gathered, queued as one job."""
        if self._held:
            jobs, self._held = self._held, []
            self._open = None
            self._jobs.put(lambda: _run_all(jobs))

    def _run_joined(self, group: list[Job]) -> None:
        with self._lock:  # taken: the jobs joined from now on form the next group
            if self._open is group:
                self._open = None
        _run_all(group)

    @property
    def depth(self) -> int:
        """Sends queued and not yet made (joined sends count as one job)."""
        return self._jobs.qsize()

    def drain(self, timeout_s: float = 30.0) -> bool:
        """Wait until every send queued so far was made; False on time-out."""
        if self._closed:
            return True
        done = threading.Event()
        with self._lock:  # what its own thread gathered too
            self._queue_held()
            self._open = None
            self._jobs.put(done.set)
        return done.wait(timeout_s)

    def close(self, timeout_s: float = 30.0) -> None:
        """Make every queued send, then stop the thread."""
        if self._closed:
            return
        with self._lock:
            self._holder = None
            self._queue_held()
            self._open = None
            self._jobs.put(None)
        self._thread.join(timeout_s)
        if self._thread.is_alive():
            log.error("The Zenoh outbox did not empty within %.0f s (%d sends left)", timeout_s, self.depth)
        self._closed = True

    def _run(self) -> None:
        while (job := self._jobs.get()) is not None:
            _run_one(job)


def _run_all(jobs: list[Job]) -> None:
    for job in jobs:
        _run_one(job)


def _run_one(job: Job) -> None:
    try:
        job()
    except Exception:  # a send must never stop the others
        log.exception("A Zenoh send failed")
