"""The Rerun recorder: a sink of the twin service that records the twin's history for operators.

The service's thread only queues each event (never blocks, never raises); a feeder thread pickles it
into a pipe to the recorder process (:mod:`adapters.rerun.child`), which owns the Rerun SDK and writes
the recording (:mod:`adapters.rerun.writer`: what is recorded, rotation). So the SDK's logging,
encoding and compression never hold the daemon's GIL, and recording never delays map updates. The
queue is large (``max_queue`` events); if it overflows, events are dropped and an error is logged,
counting them (the recording then misses versions). A full map that equals its updates applied (the
normal case: the full version follows its updates) crosses the pipe as a :class:`MapMark`, not as the
whole grid.

Example::

    recorder = RerunRecorder(path=Path("var/recordings/lab.rrd"))
    service.sinks.append(recorder)
    ...
    recorder.close()                 # the recorder process flushes the file and exits
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import queue
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import IO

from adapters.rerun.pipe import write_message
from adapters.rerun.tiles import MapMark
from twin.live.events import MapPublished, MapRemoved, MapUpdated, RoutesPublished, TwinEvent, TwinStarted
from twin.maps.grid import GridFrame, OccupancyGrid

log = logging.getLogger(__name__)

_END = object()
_WAKE = object()
BATCH_S = 0.02
"""How long the feeder lets events gather before it pickles them into the pipe."""


class RerunRecorder:
    """Records service events to an ``.rrd`` file and/or a live viewer, in a separate process.

    It holds no map: ``_held`` is, per map, only the frame and version the recorder process has (to
    send a full map that equals its updates applied as a :class:`MapMark`). The cells live in the
    recorder process (:class:`~adapters.rerun.writer.RecordingWriter`), which says why it needs them.
    """

    def __init__(
        self,
        *,
        path: Path | None = None,
        connect_url: str | None = None,
        application: str = "building-twin",
        max_queue: int = 100_000,
        max_failures: int = 20,
        rotate_every_s: float = 0.0,
        max_bytes: int = 0,
    ) -> None:
        self.path = path
        self._max_bytes = max_bytes
        self.files: list[Path] = [path] if path is not None else []
        """Every file written so far, in order (the first is ``path``); complete after :meth:`close`."""
        self.dropped = 0
        self.failures = 0
        self.disabled = False
        self._held: dict[tuple[str, str], tuple[GridFrame, int]] = {}
        """Per map, the frame and version the recorder process holds (full map and updates sent)."""
        self._queue: queue.Queue[object] = queue.Queue(maxsize=max_queue)
        self._state = threading.Condition()
        self._synced = self._syncs = 0
        self._exited = False
        self._options: dict[str, object] = {
            "path": path,
            "connect_url": connect_url,
            "application": application,
            "rotate_every_s": rotate_every_s,
            "max_bytes": max_bytes,
        }
        self._max_failures = max_failures
        self.restarts = 0
        """How many times the recorder process died and a new one took over (a new segment each)."""
        self._closing = threading.Event()
        self._copy = _HeldMaps()
        """The feeder's copy of every map as sent so far: what a new recorder process starts with."""
        self._files_before: list[Path] = []
        self._backoff_s = 0.0
        self._started_at = 0.0
        self._process = self._spawn()
        self._queue.put(self._open_message(path))
        self._feeder = threading.Thread(target=self._feed, name="rerun-feeder", daemon=True)
        self._listener = threading.Thread(target=self._listen, name="rerun-replies", daemon=True)
        self._feeder.start()
        self._listener.start()

    def _spawn(self) -> subprocess.Popen[bytes]:
        self._started_at = time.monotonic()
        return subprocess.Popen(
            [sys.executable, "-m", "adapters.rerun.child"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            start_new_session=True,  # a Ctrl-C reaches the daemon, which then closes the recording
            env={"RUST_LOG": "warn,re_log_encoding::rrd::file_sink=error", **os.environ},  # no footer: known
        )

    def _open_message(self, path: Path | None) -> tuple[object, ...]:
        options = {**self._options, "path": path}
        return ("open", options, self._max_failures, logging.getLogger("adapters").getEffectiveLevel())

    @property
    def pid(self) -> int:
        """The recorder process."""
        return self._process.pid

    @property
    def max_bytes(self) -> int:
        return self._max_bytes

    @max_bytes.setter
    def max_bytes(self, value: int) -> None:
        """Rotate once the current file reaches ``value`` bytes (0: never), from the next event on."""
        self._max_bytes = value
        self._options["max_bytes"] = value  # for a recorder process started after a death
        self._queue.put(("set", "max_bytes", value))

    # --- the sink (service thread: never blocks, never raises) ---------------------------------------
    def emit(self, event: TwinEvent) -> None:
        if self.disabled:
            return
        message = self._compact(event)
        try:
            self._queue.put_nowait(("event", message))
        except queue.Full:
            self.dropped += 1
            if isinstance(event, MapPublished | MapUpdated):  # send the next full map whole
                key = (event.grid.storey, event.grid.skill) if isinstance(event, MapPublished) else (
                    event.storey, event.skill)  # fmt: skip
                self._held.pop(key, None)
            if self.dropped in (1, 100) or self.dropped % 10_000 == 0:
                log.error(
                    "The Rerun recorder is behind: %d event(s) not recorded (queue of %d full)",
                    self.dropped,
                    self._queue.maxsize,
                )

    def _compact(self, event: TwinEvent) -> TwinEvent | MapMark:
        """``event``, or a :class:`MapMark` for a full map the recorder process already holds."""
        if isinstance(event, MapUpdated):
            key = (event.storey, event.skill)
            held = self._held.get(key)
            if held is not None and held[0] == event.frame:
                self._held[key] = (event.frame, event.version)
        elif isinstance(event, MapPublished):
            g = event.grid
            key = (g.storey, g.skill)
            if self._held.get(key) == (g.frame, event.version):
                return MapMark(g.storey, g.skill, event.revision, event.version, event.stamp_ns)
            self._held[key] = (g.frame, event.version)
        elif isinstance(event, MapRemoved):
            self._held.pop((event.storey, event.skill), None)
        return event

    # --- the pipe ------------------------------------------------------------------------------------
    def _feed(self) -> None:
        pipe = self._process.stdin
        assert pipe is not None
        try:
            while True:
                batch = [self._queue.get()]
                # Let the service finish the observation it is publishing before this thread takes
                # the GIL: one hand-off per batch, not one per event (that cost ~1 ms of update p50).
                time.sleep(BATCH_S)
                with contextlib.suppress(queue.Empty):
                    while len(batch) < 10_000:
                        batch.append(self._queue.get_nowait())
                i = 0
                while i < len(batch):
                    message = batch[i]
                    i += 1
                    if message is _END:
                        return
                    if message is _WAKE:  # the listener saw the process's output end
                        if self._process.poll() is not None:
                            restarted = self._restart()
                            if restarted is None:
                                self.disabled = True
                                return
                            pipe = restarted
                        continue
                    self._copy.take(message)
                    try:
                        write_message(pipe, message)
                        if i == len(batch):
                            pipe.flush()
                    except (BrokenPipeError, OSError):  # it died: what it had not written is the gap
                        restarted = self._restart()
                        if restarted is None:
                            self.disabled = True
                            return
                        pipe = restarted
                with contextlib.suppress(OSError):  # a batch that ended with a wake-up
                    pipe.flush()
        finally:
            with contextlib.suppress(OSError):
                pipe.close()

    def _restart(self) -> IO[bytes] | None:
        """On the feeder: the recorder process died. Start a new one after a back-off (1 s, doubling
        while it keeps dying within a minute, at most 60 s) recording into a new segment,
        ``<name>-restart<N>.rrd``, that begins with the building and every current full map; return
        its pipe (None: the recorder is closing)."""
        old = self._process
        with contextlib.suppress(OSError):
            if old.stdin is not None:
                old.stdin.close()
        with contextlib.suppress(subprocess.TimeoutExpired):
            old.wait(5)
        lived = time.monotonic() - self._started_at
        self._backoff_s = 1.0 if lived > 60 or not self._backoff_s else min(60.0, 2 * self._backoff_s)
        path = self._options["path"]
        n = self.restarts + 1
        segment = path.with_name(f"{path.stem}-restart{n}{path.suffix}") if isinstance(path, Path) else None
        log.error(
            "The Rerun recorder process %d exited (code %s) after %.0f s: a new one in %.0f s, recording "
            "into %s", old.pid, old.returncode, lived, self._backoff_s, segment or "the viewer",
        )  # fmt: skip
        if self._closing.wait(self._backoff_s):
            return None
        self._listener.join(5)
        with self._state:
            self._files_before = list(self.files)
            self._exited = False
        self._process = self._spawn()
        self.restarts = n
        self._listener = threading.Thread(target=self._listen, name="rerun-replies", daemon=True)
        self._listener.start()
        pipe = self._process.stdin
        assert pipe is not None
        gap = (f"recording resumed after the recorder process died (code {old.returncode}); "
               f"events between were not recorded")  # fmt: skip
        try:
            write_message(pipe, self._open_message(segment))
            for message in self._copy.replay():
                write_message(pipe, message)
            write_message(pipe, ("note", gap, "WARN"))
            pipe.flush()
        except (BrokenPipeError, OSError):
            return self._restart()
        return pipe

    def _listen(self) -> None:
        replies: IO[bytes] | None = self._process.stdout
        assert replies is not None
        for line in replies:
            state = json.loads(line)
            with self._state:
                self.files = [*self._files_before, *(Path(p) for p in state["files"])] or self.files
                self.failures = int(state["failures"])
                self.disabled = self.disabled or bool(state["disabled"])
                self._synced = max(self._synced, int(state.get("sync", 0)))
                self._state.notify_all()
        with self._state:
            self._exited = True
            self._state.notify_all()
        if not self._closing.is_set():  # it died: wake the feeder, which starts another
            with contextlib.suppress(queue.Full):
                self._queue.put_nowait(_WAKE)

    def wait_idle(self, timeout_s: float = 60.0) -> None:
        """Return once every event emitted so far is recorded (or dropped)."""
        with self._state:
            self._syncs += 1
            n = self._syncs
        self._queue.put(("sync", n), timeout=timeout_s)
        with self._state:
            self._state.wait_for(lambda: self._synced >= n or self._exited, timeout=timeout_s)

    # --- lifecycle ----------------------------------------------------------------------------------
    def close(self, timeout_s: float = 60.0) -> None:
        """Record what is queued, then let the recorder process flush the file and exit."""
        self._closing.set()
        try:
            self._queue.put(("close",), timeout=timeout_s)
            self._queue.put(_END, timeout=timeout_s)
        except queue.Full:
            log.error("The Rerun recorder could not finish its queue in %s s", timeout_s)
        self._feeder.join(timeout_s)
        try:
            self._process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            log.error("The Rerun recorder process %d did not finish in %s s: killed", self.pid, timeout_s)
            self._process.kill()
            self._process.wait()
        self._listener.join(timeout_s)


class _HeldMaps:
    """The feeder's copy of the start and of every map as sent to the recorder process (updates
    applied), so that a new recorder process can begin a segment with them. One owner: the feeder."""

    def __init__(self) -> None:
        self.started: TwinStarted | None = None
        self.maps: dict[tuple[str, str], MapPublished] = {}
        self.routes: dict[str, RoutesPublished] = {}

    def take(self, message: object) -> None:
        if not (isinstance(message, tuple) and len(message) == 2 and message[0] == "event"):
            return
        event = message[1]
        if isinstance(event, TwinStarted):
            self.started = event
        elif isinstance(event, MapPublished):
            g = event.grid
            own = OccupancyGrid(g.frame, g.data.copy(), g.storey, g.skill, g.elevation_m)
            self.maps[(g.storey, g.skill)] = MapPublished(own, event.revision, event.version, event.stamp_ns)
        elif isinstance(event, MapUpdated):
            held = self.maps.get((event.storey, event.skill))
            if held is not None and held.grid.frame == event.frame:
                w = event.window
                held.grid.data[w.row0 : w.row1, w.col0 : w.col1] = event.data
                self.maps[(event.storey, event.skill)] = MapPublished(
                    held.grid, event.revision, event.version, event.stamp_ns
                )
        elif isinstance(event, MapMark):
            held = self.maps.get((event.storey, event.skill))
            if held is not None:
                self.maps[(event.storey, event.skill)] = MapPublished(
                    held.grid, event.revision, event.version, event.stamp_ns
                )
        elif isinstance(event, MapRemoved):
            self.maps.pop((event.storey, event.skill), None)
        elif isinstance(event, RoutesPublished):
            self.routes[event.graph.skill] = event

    def replay(self) -> list[tuple[str, object]]:
        """The start, every map now (in full, at its latest revision) and every route graph's latest
        version, as events."""
        out: list[tuple[str, object]] = []
        if self.started is not None:
            out.append(("event", self.started))
        out += [("event", m) for _, m in sorted(self.maps.items(), key=lambda kv: kv[1].revision)]
        out += [("event", r) for _, r in sorted(self.routes.items())]
        return out
