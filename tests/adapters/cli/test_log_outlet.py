"""The serving daemon's output outlet: lines are queued by whoever logs and written by the outlet's own
thread; a reader that never reads costs dropped lines (counted), never a blocked caller."""

from __future__ import annotations

import logging
import os
import sys
import time
from collections.abc import Iterator

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
    deadline = time.monotonic() + 5
    while len(out) < n and time.monotonic() < deadline:
        try:
            out += os.read(fd, 1 << 16)
        except BlockingIOError:
            time.sleep(0.01)
    return out


def test_lines_past_a_full_pipe_and_a_full_queue_are_dropped_and_counted_without_blocking_the_caller(
    pipe: tuple[int, int],
) -> None:
    r, w = pipe
    outlet = Outlet(capacity=20)
    outlet.install(logging.getLogger("test-outlet-none"))  # the thread only
    line = "x" * 999  # 1,000 bytes with its newline: 66 fill a 64 KiB pipe
    t = time.perf_counter()
    for _ in range(500):  # 500 KB, at the pace of a busy log: the pipe fills, then the queue
        outlet.put(w, line)
        time.sleep(0.001)
    assert time.perf_counter() - t < 5.0  # no caller waited for the reader
    time.sleep(0.2)
    status = outlet.status()["log"]
    assert isinstance(status, dict)
    assert status["queued"] == 20
    assert 500 - 20 - 70 <= status["dropped"] <= 500 - 20 - 60
    assert outlet.close(timeout_s=1.0) is False  # the reader is stuck: the exit does not wait on it
    written = _read_all(r, (500 - status["dropped"]) * 1000)  # the reader comes back: the rest comes out
    assert written == (line + "\n").encode() * (500 - status["dropped"])


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
