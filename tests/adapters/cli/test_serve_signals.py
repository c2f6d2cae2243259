"""The daemon's signals (``adapters.cli.serve_cmd._Signals``), each in a small process of its own: a
stop asked for while the main thread is held in a native call, and the native last resort that ends a
stop whose GIL is held."""

from __future__ import annotations

import subprocess
import sys
import textwrap

from tests.integration.conftest import ROOT

HELD_MAIN_THREAD = """
import signal, threading, time
from adapters.cli.serve_cmd import _Signals
signals = _Signals(stop_timeout_s=10.0)
signals.install()
signals.serving = True
other = threading.Thread(target=time.sleep, args=(30,), daemon=True)
other.start()
signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})  # the main thread never takes it
signal.pthread_kill(other.ident, signal.SIGTERM)  # the C handler runs there; Python's is left pending
signals.stop.wait()  # a lock acquired without a timeout: the main thread runs no handler until woken
print("stop seen", flush=True)
import faulthandler; faulthandler.cancel_dump_traceback_later()
"""

GIL_HELD = """
import os, signal
from adapters.cli.serve_cmd import _Signals
signals = _Signals(stop_timeout_s=0.1, margin_s=0.3)
signals.install()
signals.serving = True
os.kill(os.getpid(), signal.SIGTERM)
print("stopping", flush=True)
sum(range(10**13))  # one native loop that holds the GIL for hours: no Python thread runs again
"""


def _run(script: str, timeout_s: float) -> subprocess.CompletedProcess[str]:
    process = subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(script)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
    )  # fmt: skip
    try:
        out, err = process.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:  # it takes SIGTERM as a stop: only SIGKILL ends it
        process.kill()
        out, err = process.communicate()
        raise AssertionError(f"no stop within {timeout_s} s:\n{out}{err}") from None
    return subprocess.CompletedProcess(process.args, process.returncode, out, err)


def test_a_stop_is_seen_while_the_main_thread_is_held_in_a_native_wait_that_runs_no_handler() -> None:
    r = _run(HELD_MAIN_THREAD, timeout_s=20)
    assert r.returncode == 0 and r.stdout.strip() == "stop seen", (r.returncode, r.stdout, r.stderr)


def test_a_stop_whose_gil_is_held_by_a_native_call_ends_with_every_threads_stack_and_code_1() -> None:
    r = _run(GIL_HELD, timeout_s=20)
    assert r.stdout.strip() == "stopping" and r.returncode == 1, (r.returncode, r.stdout, r.stderr)
    assert "Timeout (0:00:00.5" in r.stderr and "twin-signals" not in r.stdout, r.stderr
    assert '<string>", line 9' in r.stderr, r.stderr  # where the main thread was held
