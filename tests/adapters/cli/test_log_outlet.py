"""The serving daemon's output outlet: lines are queued by whoever logs and written by the outlet's own
thread; a reader that never reads costs dropped lines (counted), never a blocked caller."""

from __future__ import annotations

import logging
import os
import sys
import time
from collections.abc import Callable, Iterator

import pytest

from adapters.cli.log_outlet import Outlet


@pytest.fixture
def pipe() -> Iterator[tuple[int, int]]:
    r, w = os.pipe()
    try:
        yield r, w
    finally:
        os.close(r)
        os.close(w)


def _read_all(fd: int, n: int) -> bytes:
    os.set_blocking(fd, False)
    out = b""
    deadline = time.monotonic() + 30
    while len(out) < n and time.monotonic() < deadline:
        try:
            out += os.read(fd, 1 << 16)
        except BlockingIOError:
            time.sleep(0.01)
    return out


def _until(predicate: Callable[[], bool], timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.001)


def _fill(fd: int, data: bytes) -> int:
    """Write ``data`` to the pipe ``fd`` until it takes no more; how many times it took it."""
    os.set_blocking(fd, False)
    n = 0
    try:
        while True:
            os.write(fd, data)  # whole or not at all: less than PIPE_BUF
            n += 1
    except BlockingIOError:
        return n
    finally:
        os.set_blocking(fd, True)


def test_lines_past_a_full_pipe_and_a_full_queue_are_dropped_and_counted_without_blocking_the_caller(
    pipe: tuple[int, int],
) -> None:
    r, w = pipe
    line = "x" * 999  # 1,000 bytes with its newline
    waiting = _fill(w, (line + "\n").encode())  # a reader that stopped reading: 64 lines in 64 KiB
    outlet = Outlet(capacity=20)
    outlet.install(logging.getLogger("test-outlet-none"))  # the thread only
    outlet.put(w, line)
    _until(lambda: outlet.status()["log"] == {"dropped": 0, "queued": 0})  # taken: its write waits
    t, blocked = time.perf_counter(), 0.0
    for _ in range(499):  # at the pace of a busy log: the queue fills, then the lines are dropped
        outlet.put(w, line)
        blocked += time.perf_counter() - t
        time.sleep(0.001)
        t = time.perf_counter()
    assert blocked < 5.0  # no caller waited for the reader (it would wait forever)
    assert outlet.status()["log"] == {"dropped": 500 - 1 - 20, "queued": 20}
    assert outlet.close(timeout_s=1.0) is False  # the reader is stuck: the exit does not wait on it
    lines = waiting + 1 + 20
    written = _read_all(r, lines * 1000)  # the reader comes back: the rest comes out
    assert written == (line + "\n").encode() * lines


def test_the_root_loggers_stream_handler_goes_through_the_outlet_in_order_with_its_lines_and_comes_back(
    pipe: tuple[int, int], monkeypatch: pytest.MonkeyPatch
) -> None:
    r, w = pipe
    stream = os.fdopen(os.dup(w), "w")
    monkeypatch.setattr(sys, "stderr", stream)
    logger = logging.getLogger("test-outlet-root")
    logger.propagate = False
    original = logging.StreamHandler(sys.stderr)
    original.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    logger.addHandler(original)
    try:
        outlet = Outlet()
        outlet.install(logger)
        assert original not in logger.handlers
        logger.warning("first")
        outlet.line("second", err=True)
        logger.warning("third")
        assert outlet.close() is True
        assert logger.handlers == [original]
        expected = b"WARNING test-outlet-root: first\nsecond\nWARNING test-outlet-root: third\n"
        assert _read_all(r, len(expected)) == expected
    finally:
        logger.handlers.clear()
        stream.close()
