"""Integration fixtures: the lab imported on disk and the daemon as a real process on a free port."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def twin(*args: str | Path, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "adapters.cli", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=timeout,
        check=False,
    )


@dataclass
class Daemon:
    process: subprocess.Popen[str]
    endpoint: str
    store: Path | None
    log: list[str]

    def stop(self, sig: int = signal.SIGTERM, timeout: float = 10.0) -> tuple[int, float]:
        """Signal the daemon; return its exit code and how long it took to exit."""
        t0 = time.monotonic()
        self.process.send_signal(sig)
        out, _ = self.process.communicate(timeout=timeout)
        self.log += out.splitlines()
        return self.process.returncode, time.monotonic() - t0

    def stop_cleanly(self, sig: int = signal.SIGTERM, timeout: float = 30.0) -> None:
        """Stop the daemon if it still runs, and assert that the stop was clean: exit 0, no ``FATAL``
        (a thread that re-entered Python while the interpreter finalized aborts the process)."""
        if self.process.poll() is not None:
            return
        try:
            code, _ = self.stop(sig, timeout)
        except subprocess.TimeoutExpired:
            self.process.send_signal(signal.SIGUSR1)  # the daemon writes every thread's stack (faulthandler)
            time.sleep(2.0)
            self.process.kill()
            out, _ = self.process.communicate(timeout=10)
            self.log += out.splitlines()
            raise AssertionError(
                f"the daemon did not stop within {timeout} s; its last lines and its threads' stacks:\n"
                + "\n".join(self.log[-200:])
            ) from None
        fatal = [line for line in self.log if "FATAL" in line]
        assert code == 0 and not fatal, f"stop by {sig}: exit {code}:\n" + "\n".join(self.log[-200:])


def lines_until(daemon: Daemon, found: Callable[[str], bool], timeout_s: float = 10.0) -> list[str]:
    """The daemon's next output lines, up to the first for which ``found`` is true (or ``timeout_s``).
    A thread reads them (a text stream's buffer hides lines from ``select``); after a timeout it reads on
    until the daemon exits."""
    stream = daemon.process.stdout
    assert stream is not None
    seen: list[str] = []
    done = threading.Event()

    def read() -> None:
        for line in stream:
            seen.append(line.rstrip())
            if found(line):
                break
        done.set()

    threading.Thread(target=read, daemon=True).start()
    done.wait(timeout_s)
    return list(seen)


def start_daemon(store: Path | None, *extra: str, config: Path | None = None, scheme: str = "tcp") -> Daemon:
    """``twin serve`` on ``store`` (None: the store named in ``extra``, e.g. ``--store-url URL``)."""
    endpoint = f"{scheme}/127.0.0.1:{free_port()}"
    before = ["--config", str(config)] if config is not None else []
    where = ["--store", str(store)] if store is not None else []
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "adapters.cli",
            *before,
            "serve",
            *where,
            "--listen",
            endpoint,
            *extra,
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        cwd=ROOT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    log: list[str] = []
    assert process.stdout is not None
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        if not line:
            break
        log.append(line.rstrip())
        if "serving site" in line:
            return Daemon(process, endpoint, store, log)
    process.kill()
    raise AssertionError("the daemon did not start:\n" + "\n".join(log))


@pytest.fixture(scope="session")
def lab_store_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The lab imported once per worker: tests read it or copy it (``fresh_store``), never change it."""
    root = tmp_path_factory.mktemp("live")
    assert twin("sample", "lab", root / "lab.ifc", "--storeys", "2").returncode == 0
    r = twin("import", root / "lab.ifc", "--store", root / "store")
    assert r.returncode == 0, r.stderr
    return root / "store"


@pytest.fixture
def fresh_store(lab_store_dir: Path, tmp_path: Path) -> Path:
    """A copy of the imported lab's store, so that each test starts from revision 0."""
    import shutil

    copy = tmp_path / "store"
    shutil.copytree(lab_store_dir, copy)
    return copy


@pytest.fixture
def daemon(fresh_store: Path) -> Iterator[Daemon]:
    d = start_daemon(fresh_store, "--no-record")
    yield d
    d.stop_cleanly()


class JsonLinesProcess:
    """A helper process (a robot, a subscriber) that prints one JSON object per line on stdout."""

    def __init__(self, *args: str) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", *args],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
        )  # fmt: skip
        self.lines: list[dict[str, object]] = []

    def next(self) -> dict[str, object]:
        assert self.process.stdout is not None
        line = self.process.stdout.readline()
        assert line, self.process.stderr.read() if self.process.stderr else "the process died"
        self.lines.append(json.loads(line))
        return self.lines[-1]

    def close_stdin_and_wait(self, timeout: float = 30) -> None:
        assert self.process.stdin is not None
        self.process.stdin.close()
        assert self.process.wait(timeout=timeout) == 0, (
            self.process.stderr.read() if self.process.stderr else ""
        )
