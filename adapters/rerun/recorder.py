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
from twin.live.events import MapPublished, MapRemoved, MapUpdated, TwinEvent
from twin.maps.grid import GridFrame

log = logging.getLogger(__name__)

_END = object()
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
        self._process = subprocess.Popen(
            [sys.executable, "-m", "adapters.rerun.child"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            start_new_session=True,  # a Ctrl-C reaches the daemon, which then closes the recording
            env={"RUST_LOG": "warn,re_log_encoding::rrd::file_sink=error", **os.environ},  # no footer: known
        )
        options = {
            "path": path,
            "connect_url": connect_url,
            "application": application,
            "rotate_every_s": rotate_every_s,
            "max_bytes": max_bytes,
        }
        self._queue.put(("open", options, max_failures, logging.getLogger("adapters").getEffectiveLevel()))
        self._feeder = threading.Thread(target=self._feed, name="rerun-feeder", daemon=True)
        self._listener = threading.Thread(target=self._listen, name="rerun-replies", daemon=True)
        self._feeder.start()
        self._listener.start()

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
                for message in batch:
                    if message is _END:
                        return
                    write_message(pipe, message)
                pipe.flush()
        except (BrokenPipeError, OSError):
            self.disabled = True
            log.error("The Rerun recorder process %d exited: recording stopped", self._process.pid)
        finally:
            with contextlib.suppress(OSError):
                pipe.close()

    def _listen(self) -> None:
        replies: IO[bytes] | None = self._process.stdout
        assert replies is not None
        for line in replies:
            state = json.loads(line)
            with self._state:
                self.files = [Path(p) for p in state["files"]] or self.files
                self.failures = int(state["failures"])
                self.disabled = self.disabled or bool(state["disabled"])
                self._synced = max(self._synced, int(state.get("sync", 0)))
                self._state.notify_all()
        with self._state:
            self._exited = True
            self._state.notify_all()

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
