"""The writer's wait between requests survives a signal: :meth:`RequestQueue.take` with a timeout,
interrupted by a signal whose handler ends after the deadline, returns (CPython's
``SimpleQueue.get(timeout=...)`` waited forever then, and the daemon never began its stop)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]

SCRIPT = """
import signal, threading, time
from twin.live.requests import RequestQueue
signal.signal(signal.SIGTERM, lambda *_: time.sleep(0.2))  # a handler that ends after the deadline
main = threading.main_thread().ident
threading.Timer(0.05, signal.pthread_kill, args=(main, signal.SIGTERM)).start()
t0 = time.monotonic()
got = RequestQueue(8).take(timeout_s=0.1)
print(got, round(time.monotonic() - t0, 1), flush=True)
"""


def test_a_signal_whose_handler_outlasts_the_writers_wait_does_not_make_the_wait_endless() -> None:
    process = subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(SCRIPT)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, cwd=ROOT,
    )  # fmt: skip
    try:
        out, err = process.communicate(timeout=20)
    except subprocess.TimeoutExpired:  # its SIGTERM handler takes SIGTERM: only SIGKILL ends it
        process.kill()
        process.communicate()
        raise AssertionError("take(timeout_s=0.1) was still waiting 20 s after the signal") from None
    assert process.returncode == 0, err
    got, seconds = out.split()
    assert got == "None" and float(seconds) < 10, out
