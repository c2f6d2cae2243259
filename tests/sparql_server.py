"""A real SPARQL 1.1 server for the tests: Oxigraph's own (``oxigraph serve``, from the ``oxigraph``
package on PyPI, in the dev extra), started on a free loopback port and waited for."""

from __future__ import annotations

import shutil
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path

import pytest


def oxigraph_binary() -> str:
    """The ``oxigraph`` command beside this Python (the venv's), else on PATH.

    It installs with the dev extra, so its absence is a broken install: the test fails, naming the fix.
    """
    found = shutil.which("oxigraph", path=str(Path(sys.executable).parent)) or shutil.which("oxigraph")
    if found is None:
        pytest.fail(
            "the Oxigraph server is not installed ('oxigraph' command): pip install oxigraph "
            "(it is in the dev extra: pip install -e '.[dev]')"
        )
    return found


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


@dataclass
class SparqlServer:
    """An ``oxigraph serve`` process; ``url`` is its base URL (``/query``, ``/update``, ``/store``)."""

    process: subprocess.Popen[bytes]
    url: str

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait(timeout=10)

    def query_json(self, sparql: str) -> dict[str, object]:
        """Ask the server directly over HTTP (no project code in between)."""
        import json

        request = urllib.request.Request(
            f"{self.url}/query",
            data=sparql.encode(),
            headers={"Content-Type": "application/sparql-query", "Accept": "application/sparql-results+json"},
        )
        with urllib.request.urlopen(request, timeout=10) as response:
            value: dict[str, object] = json.loads(response.read())
            return value


def start_sparql_server(
    location: Path | None = None, *, port: int | None = None, wait_s: float = 20.0
) -> SparqlServer:
    """Start ``oxigraph serve`` (in memory, or on disk at ``location``; on a free loopback port unless
    ``port`` is given) and wait until it answers."""
    binary = oxigraph_binary()
    port = port or _free_port()
    args = [binary, "serve", "--bind", f"127.0.0.1:{port}"]
    if location is not None:
        args += ["--location", str(location)]
    process = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    server = SparqlServer(process, f"http://127.0.0.1:{port}")
    deadline = time.monotonic() + wait_s
    while time.monotonic() < deadline:
        if process.poll() is not None:
            err = process.stderr.read().decode() if process.stderr else ""
            raise AssertionError(f"oxigraph serve exited with {process.returncode}: {err}")
        try:
            server.query_json("ASK {}")
            return server
        except (urllib.error.URLError, ConnectionError):
            time.sleep(0.05)
    server.stop()
    raise AssertionError(f"oxigraph serve did not answer at {server.url} within {wait_s} s")
