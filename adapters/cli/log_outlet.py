"""The serving daemon's output, written by a thread of its own: a reader that stops reading (a
supervisor that pipes the daemon's output and never reads it) costs the daemon log lines, never its work.

Once installed, whoever logs (any thread: the writer, Zenoh callbacks, the ROS ingestion) or prints a
line through :meth:`Outlet.line` only puts it in a bounded queue; the outlet's thread writes the lines
to the process's stdout and stderr. A line that finds the queue full is dropped and counted, and so is
a line the reader is gone for (EPIPE): ``twin status`` shows ``log: {"dropped": N, "queued": M}``.
Without it, a full pipe (64 KiB on Linux) blocks the first thread that logs, and with it every
request behind that thread.

Example::

    outlet = Outlet(capacity=10_000)
    outlet.install()                  # the root logger's stream handlers now go through it
    outlet.line("serving ...")        # stdout, in order with the log lines
    outlet.status()                   # {"log": {"dropped": 0, "queued": 0}}
    outlet.close(timeout_s=2.0)       # write what is queued, unless the reader is stuck
"""

from __future__ import annotations

import logging
import os
import queue
import sys
import threading
import time

THREAD_NAME = "twin-log-outlet"
CAPACITY = 10_000
"""Lines the queue holds (a few MiB at most) before new ones are dropped."""


class _OutletHandler(logging.Handler):
    """Formats a record on the thread that logs it and hands the line to the outlet (never blocks)."""

    def __init__(self, outlet: Outlet, fd: int, original: logging.Handler) -> None:
        super().__init__(original.level)
        self.setFormatter(original.formatter)
        for f in original.filters:
            self.addFilter(f)
        self.outlet, self.fd, self.original = outlet, fd, original

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = self.format(record)
        except Exception:
            self.handleError(record)
            return
        self.outlet.put(self.fd, text)


class Outlet:
    """A bounded queue of output lines and the thread that writes them (see the module docstring)."""

    def __init__(self, capacity: int = CAPACITY) -> None:
        self._queue: queue.Queue[tuple[int, bytes]] = queue.Queue(capacity)
        self._lock = threading.Lock()
        self.dropped = 0
        """Lines dropped: the queue was full, or the reader had gone (EPIPE)."""
        self.written = 0
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._run, name=THREAD_NAME, daemon=True)
        self._swapped: list[tuple[logging.Handler, _OutletHandler]] = []
        self._logger = logging.getLogger()
        self._fds = (1, 2)  # stdout's and stderr's, as :meth:`install` finds them

    # --- any thread -----------------------------------------------------------------------------------
    def put(self, fd: int, text: str) -> None:
        """Queue ``text`` (one line, without its newline) for file descriptor ``fd``; drop it if full."""
        try:
            self._queue.put_nowait((fd, (text + "\n").encode("utf-8", "replace")))
        except queue.Full:
            with self._lock:
                self.dropped += 1

    def line(self, text: str, *, err: bool = False) -> None:
        """A line for stdout (``err``: stderr), in order with the log lines."""
        self.put(self._fds[1] if err else self._fds[0], text)

    def status(self) -> dict[str, object]:
        """``{"log": {"dropped": N, "queued": M}}`` for ``twin status``."""
        with self._lock:
            dropped = self.dropped
        return {"log": {"dropped": dropped, "queued": self._queue.qsize()}}

    # --- lifecycle ------------------------------------------------------------------------------------
    def install(self, logger: logging.Logger | None = None) -> None:
        """Start the thread and put the outlet in place of ``logger``'s (default: the root logger's)
        handlers that write to stdout or stderr."""
        logger = self._logger = logger or logging.getLogger()
        for stream in (sys.stdout, sys.stderr):  # what was written directly goes out first
            stream.flush()
        out, err = _fileno(sys.stdout), _fileno(sys.stderr)
        self._fds = (1 if out is None else out, 2 if err is None else err)
        self._thread.start()
        for handler in list(logger.handlers):
            fd = _fd_of(handler)
            if fd is None:
                continue
            swap = _OutletHandler(self, fd, handler)
            logger.removeHandler(handler)
            logger.addHandler(swap)
            self._swapped.append((handler, swap))

    def close(self, timeout_s: float = 2.0) -> bool:
        """Write what is queued (while the reader takes it: at most ``timeout_s``, less once nothing
        moves for half a second) and stop the thread. True if everything was written; then the original
        handlers are back. Else the outlet's handlers stay (later lines are dropped, not blocking)."""
        if not self._thread.is_alive():
            return True
        deadline = time.monotonic() + timeout_s
        moved_at, last = time.monotonic(), self._queue.qsize()
        while self._queue.unfinished_tasks and time.monotonic() < deadline:
            time.sleep(0.01)
            if (left := self._queue.qsize()) != last:
                moved_at, last = time.monotonic(), left
            elif time.monotonic() - moved_at > 0.5:
                break
        drained = self._queue.unfinished_tasks == 0
        self._closing.set()
        if drained:
            self._thread.join(timeout_s)
            for original, swap in self._swapped:
                self._logger.removeHandler(swap)
                self._logger.addHandler(original)
            self._swapped.clear()
        return drained

    def _run(self) -> None:
        while not (self._closing.is_set() and self._queue.empty()):
            try:
                fd, data = self._queue.get(timeout=0.1)
            except queue.Empty:
                continue
            try:
                view = memoryview(data)
                while view:
                    view = view[os.write(fd, view) :]
                self.written += 1
            except OSError:  # the reader has gone (EPIPE) or the stream is closed
                with self._lock:
                    self.dropped += 1
            finally:
                self._queue.task_done()


def _fd_of(handler: logging.Handler) -> int | None:
    """The file descriptor of a stream handler on stdout or stderr, else None."""
    if type(handler) is not logging.StreamHandler:
        return None
    stream = handler.stream
    if stream is not sys.stdout and stream is not sys.stderr:
        return None
    return _fileno(stream)


def _fileno(stream: object) -> int | None:
    try:
        fd: int = stream.fileno()  # type: ignore[attr-defined]
    except (AttributeError, OSError, ValueError):  # not a file (a test's StringIO)
        return None
    return fd
