"""A throttling TCP proxy: an emulated slow link (rate and one-way latency) between a robot's session and
the daemon, for the tests and ``benchmarks/wifi.py`` (netem is not available on these machines).

Each direction of each connection is a reader thread and a writer thread joined by a queue bounded in
bytes (``buffer_bytes``, default about twice the bandwidth-delay product): a chunk read at ``t`` leaves
no earlier than ``t + latency_s``, and the writer sends at most ``rate_bps`` bits a second. A full
queue stops the reader, so the sender feels the back-pressure of a slow link (its TCP window fills) as
it would on Wi-Fi.

Example::

    with ThrottlingProxy(("127.0.0.1", daemon_port), rate_bps=20e6, latency_s=0.02) as proxy:
        robot = zenoh.open(client_config([f"tcp/127.0.0.1:{proxy.port}"]))
        ...
        proxy.accepted    # connections accepted (1 if the robot's transport was never closed)
"""

from __future__ import annotations

import collections
import contextlib
import socket
import threading
import time
from types import TracebackType

CHUNK = 16 * 1024


class _Pipe:
    """One direction: read from ``src``, hold each chunk ``latency_s``, write to ``dst`` at the rate."""

    def __init__(self, src: socket.socket, dst: socket.socket, rate_bps: float, latency_s: float,
                 buffer_bytes: int) -> None:  # fmt: skip
        self.src, self.dst = src, dst
        self.bytes_per_s = rate_bps / 8.0
        self.latency_s = latency_s
        self.buffer_bytes = buffer_bytes
        self.queue: collections.deque[tuple[float, bytes]] = collections.deque()
        self.queued = 0
        self.cond = threading.Condition()
        self.eof = False
        self.sent = 0
        for target in (self._read, self._write):
            threading.Thread(target=target, daemon=True, name="throttle").start()

    def _read(self) -> None:
        try:
            while data := self.src.recv(CHUNK):
                with self.cond:
                    self.cond.wait_for(lambda: self.queued < self.buffer_bytes)
                    self.queue.append((time.monotonic(), data))
                    self.queued += len(data)
                    self.cond.notify_all()
        except OSError:
            pass
        with self.cond:
            self.eof = True
            self.cond.notify_all()

    def _write(self) -> None:
        next_free = time.monotonic()  # when the emulated link can take the next byte
        try:
            while True:
                with self.cond:
                    self.cond.wait_for(lambda: self.queue or self.eof)
                    if not self.queue:
                        break
                    at, data = self.queue.popleft()
                    self.queued -= len(data)
                    self.cond.notify_all()
                now = time.monotonic()
                start = max(now, next_free, at + self.latency_s)
                time.sleep(max(0.0, start - now))
                self.dst.sendall(data)
                self.sent += len(data)
                next_free = start + len(data) / self.bytes_per_s
        except OSError:
            pass
        for s in (self.dst, self.src):
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)


class ThrottlingProxy:
    """Listens on a free port of 127.0.0.1 and forwards every connection to ``upstream`` through a link
    of ``rate_bps`` bits a second and ``latency_s`` one way (both directions)."""

    def __init__(self, upstream: tuple[str, int], *, rate_bps: float, latency_s: float,
                 buffer_bytes: int | None = None) -> None:  # fmt: skip
        self.upstream = upstream
        self.rate_bps, self.latency_s = rate_bps, latency_s
        self.buffer_bytes = buffer_bytes or max(64 * 1024, int(2 * rate_bps / 8 * latency_s))
        self._server = socket.create_server(("127.0.0.1", 0))
        self.port: int = self._server.getsockname()[1]
        self.accepted = 0
        self.pipes: list[_Pipe] = []
        self._sockets: list[socket.socket] = []
        threading.Thread(target=self._accept, daemon=True, name="throttle-accept").start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self._server.accept()
            except OSError:
                return
            upstream = socket.create_connection(self.upstream)
            for s in (client, upstream):
                s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self.accepted += 1
            self._sockets += [client, upstream]
            args = (self.rate_bps, self.latency_s, self.buffer_bytes)
            self.pipes += [_Pipe(client, upstream, *args), _Pipe(upstream, client, *args)]

    @property
    def bytes_down(self) -> int:
        """Bytes delivered from the upstream (the daemon) to the clients so far."""
        return sum(p.sent for p in self.pipes[1::2])

    def close(self) -> None:
        self._server.close()
        for s in self._sockets:
            with contextlib.suppress(OSError):
                s.close()

    def __enter__(self) -> ThrottlingProxy:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, err: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
