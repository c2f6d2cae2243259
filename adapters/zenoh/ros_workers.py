"""The robots' side of ROS 2 ingestion: TF, camera info and detection arrays turned into observations,
in the daemon's ingest thread or in worker processes.

:class:`RobotTranslator` holds what translating a robot's arrays needs (its TF buffer, the arrays
waiting for TF, its camera's fields of view, its storey, the storeys' elevations and the maps that
occlude its views) and turns each message into :data:`Outcome` records. The daemon's ingest thread
runs one when ``[ros] ingest_workers = 0``; otherwise :class:`WorkerPool` runs one per worker process,
each robot always in the same worker (sharded by name) so that its arrays stay in order, and the daemon
feeds every worker, in order with the messages, what it learns: storey switches, elevations, the
occluding maps and their updates. Occlusion (the views) runs in the worker, beside the TF that places
the sensor: the map it is cut by is fed to the worker (a copy per version), where the twin's held
elements that hide things are looked at by the writer's fusion, which owns them.

Each worker has a pipe each way, written in batches (:data:`LINGER_S`): a robot's TF and its array, and
the other robots' of the same moment, go to the worker as one message (one pickle, one write, one
wake-up), and the outcomes of a batch come back as one (a long batch's every :data:`FLUSH_S`), so the
queues cost next to nothing per array.

A worker that dies is started again with what the daemon fed it (the maps, storeys, the last
``tf_static`` and camera info of its robots); the arrays it held are lost (counted ``worker_lost``),
never submitted twice: only what a worker put out reaches the twin.
"""

from __future__ import annotations

import contextlib
import copy
import gc
import logging
import math
import multiprocessing as mp
import pickle
import queue
import selectors
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from adapters.ros.detections import (
    DetectionContext,
    DetectionSettings,
    array_header,
    camera_fov,
    translate_detections,
)
from adapters.ros.observation_doc import RosInputError
from adapters.ros.sessions import TrackerSession
from adapters.ros.tf import TfBuffer, decode_tf_message
from adapters.ros.view import Structure, ViewCache
from adapters.zenoh.ros_hold import SteadyHold
from adapters.zenoh.ros_outcomes import Outcome, Refused, Translated, Waited
from twin.config import Limits
from twin.errors import MapError
from twin.live.validate import checked
from twin.maps.grid import OccupancyGrid
from twin.records import Observation

__all__ = ["Outcome", "Refused", "RobotTranslator", "Translated", "Waited", "WorkerPool"]

log = logging.getLogger(__name__)

ROBOT_KINDS = ("detections", "tf", "tf_static", "camera_info")
SUPERVISE_S = 0.25
"""How often the pool looks for a worker that died."""
"""The messages of a robot that its translator handles."""




@dataclass(frozen=True, slots=True)
class RobotSpec:
    """A robot as its translator knows it (picklable: a worker gets it at its start)."""

    name: str
    settings: DetectionSettings
    view_skill: str | None
    session: TrackerSession = field(default_factory=TrackerSession)
    """Its tracker's session to resume (from the twin at start, or from a worker that died)."""


@dataclass(eq=False, slots=True)
class _Robot:
    spec: RobotSpec
    tf: TfBuffer = field(default_factory=TfBuffer)
    waiting: list[tuple[float, bytes, int]] = field(default_factory=list)
    """Arrays whose transform is not in yet: (monotonic deadline, payload, arrival ns), oldest first."""
    fov_rad: tuple[float, float] | None = None
    session: TrackerSession = field(default_factory=TrackerSession)
    view_cache: ViewCache = field(default_factory=ViewCache)
    """Its camera's last march (reused while it stands still and the map is the same)."""


class RobotTranslator:
    """Robots' messages -> outcomes (see the module's docstring); one thread uses it at a time, except
    :meth:`set_grid` and friends, which may come from another (the grids are replaced, never changed)."""

    def __init__(
        self,
        robots: list[RobotSpec],
        *,
        fusion_terms: bool,
        typed: bool,
        clock: Callable[[], int] = time.time_ns,
        tf_wait_s: float = 0.5,
        max_waiting: int = 64,
        storey_of: Callable[[str], str | None] | None = None,
        limits: Limits | None = None,
    ) -> None:
        """``storey_of``: a robot's current storey, asked at each array (in the daemon's process);
        None: the storeys fed with :meth:`set_storey` (in a worker). ``limits``: the twin's, to check
        typed records here (:func:`twin.live.validate.checked`: the writer need not check them again)."""
        self.storey_of = storey_of
        self.limits = limits
        self.robots = {r.name: _Robot(r, session=copy.deepcopy(r.session)) for r in robots}
        self.fusion_terms = fusion_terms
        self.typed = typed
        self.clock = clock
        self.tf_wait_s = tf_wait_s
        self.max_waiting = max_waiting
        self.storeys: dict[str, str | None] = {}
        self.elevations: dict[str, float] = {}
        self.grids: dict[tuple[str, str], Structure] = {}
        """(storey, skill) -> the occluding map, ready for marching rays (made once per map version)."""
        self._lock = threading.Lock()

    # --- what the daemon learns (any thread) ----------------------------------------------------------
    def set_storey(self, robot: str, storey: str | None) -> None:
        with self._lock:
            self.storeys[robot] = storey

    def set_session(self, robot: str, session: TrackerSession) -> None:
        """Resume ``robot``'s tracker session (a restarted worker: the one its predecessor last told)."""
        if robot in self.robots:
            self.robots[robot].session = copy.deepcopy(session)

    def set_elevations(self, elevations: Mapping[str, float]) -> None:
        with self._lock:
            self.elevations = dict(elevations)

    def set_grid(self, grid: OccupancyGrid) -> None:
        structure = Structure.of(grid)
        with self._lock:
            self.grids[(grid.storey, grid.skill)] = structure

    def wants(self, skill: str) -> bool:
        return any(r.spec.view_skill == skill for r in self.robots.values())

    # --- messages (the translating thread) ------------------------------------------------------------
    def handle(self, owner: str, kind: str, payload: bytes, received_ns: int) -> list[Outcome]:
        robot = self.robots[owner]
        if kind in ("tf", "tf_static"):
            try:
                robot.tf.add(decode_tf_message(payload), static=kind == "tf_static")
            except MapError as err:
                return [Refused(owner, "malformed", str(err))]
            return self._retry_waiting(robot) if robot.waiting else []
        if kind == "camera_info":
            try:
                robot.fov_rad = camera_fov(payload)
            except RosInputError as err:
                return [Refused(owner, err.cause, str(err))]
            return []
        if len(robot.waiting) < self.max_waiting and (robot.waiting or self._must_wait(robot, payload)):
            robot.waiting.append((time.monotonic() + self.tf_wait_s, payload, received_ns))  # in order
            return [Waited(owner)]
        return [self._translate(robot, payload, received_ns)]

    def give_up_waiting(self) -> list[Outcome]:
        """Translate the arrays that waited for TF too long (refused if it still does not resolve)."""
        now = time.monotonic()
        out: list[Outcome] = []
        for robot in self.robots.values():
            while robot.waiting and robot.waiting[0][0] <= now:
                _, payload, received = robot.waiting.pop(0)
                out.append(self._translate(robot, payload, received))
        return out

    @property
    def waiting(self) -> bool:
        return any(r.waiting for r in self.robots.values())

    def _retry_waiting(self, robot: _Robot) -> list[Outcome]:
        still: list[tuple[float, bytes, int]] = []
        out: list[Outcome] = []
        for item in robot.waiting:
            if still or self._must_wait(robot, item[1]):  # in order: none overtakes a waiting one
                still.append(item)
            else:
                out.append(self._translate(robot, item[1], item[2]))
        robot.waiting = still
        return out

    def _must_wait(self, robot: _Robot, payload: bytes) -> bool:
        header = array_header(payload)
        if header is None:
            return False
        frame, stamp = header
        s = robot.spec.settings
        target = s.map_frame
        frames = {f for f in (frame, s.sensor_frame or frame) if f and f.lstrip("/") != target.lstrip("/")}
        return any(robot.tf.waits_for(target, f, stamp) for f in frames)

    def _translate(self, robot: _Robot, payload: bytes, received_ns: int) -> Outcome:
        name, skill = robot.spec.name, robot.spec.view_skill
        with self._lock:
            storey = self.storey_of(name) if self.storey_of is not None else self.storeys.get(name)
            elevation = self.elevations.get(storey or "", 0.0)
            grid = self.grids.get((storey, skill)) if storey and skill else None
        known = skill is None or grid is not None
        ctx = DetectionContext(
            storey, elevation, self.clock(), robot.tf, grid, self.fusion_terms, known,
            fov_rad=robot.fov_rad, session=robot.session, view_cache=robot.view_cache,
        )  # fmt: skip
        try:
            t = translate_detections(payload, robot.spec.settings, ctx, typed=self.typed)
        except RosInputError as err:
            return Refused(name, err.cause, str(err))
        if self.limits is not None and isinstance(t.document, Observation):  # checked here, not by the writer
            t = replace(t, document=checked(t.document, limits=self.limits))
        return Translated(name, t, received_ns, copy.copy(robot.session))


# --- worker processes -------------------------------------------------------------------------------
LINGER_S = 0.002
"""How long a worker's sender waits, once a message is queued, for more to send with it: a robot's TF and
its array (and other robots' of the same moment) go as one batch (one pickle, one write, one wake-up of
the worker); the outcomes of a batch come back as one."""


WORKER_GC_THRESHOLD = (20_000, 50, 100)
"""A worker's collector thresholds: an array makes about a hundred container objects that outlive the
records' making (its reports, boxes, tuples; freed by their counts once handed over), so the default
700 ran a young collection every few arrays over everything young; cycles are rare here."""


FLUSH_S = 0.003
"""A worker sends what it made of a batch so far once it has worked on it this long (a batch of many
robots' arrays: the first ones do not wait for the last)."""


def _worker_main(
    robots: list[RobotSpec],
    *,
    fusion_terms: bool,
    typed: bool,
    tf_wait_s: float,
    inbox: Any,
    outbox: Any,
    taken: Any,
    limits: Limits | None = None,
) -> None:
    """A worker process: batches of feeds and messages from the ``inbox`` pipe, handled in order, their
    outcomes to the ``outbox`` pipe as one batch (or one every :data:`FLUSH_S` of work); ``taken``
    counts the items taken (the queue's depth); None stops (after the items before it)."""
    logging.basicConfig(level=logging.WARNING)
    t = RobotTranslator(robots, fusion_terms=fusion_terms, typed=typed, tf_wait_s=tf_wait_s, limits=limits)
    gc.freeze()  # what the start made (modules, type stores, the robots' state) is not collected again
    gc.set_threshold(*WORKER_GC_THRESHOLD)
    stop = False
    while not stop:
        items: list[Any] = []
        try:
            if inbox.poll(0.05 if t.waiting else 0.5):
                items = pickle.loads(inbox.recv_bytes())
        except (EOFError, OSError, KeyboardInterrupt):
            return
        taken.value += len(items)
        out: list[Outcome] = []
        sent_at = time.monotonic()
        try:
            for item in items:
                if item is None:
                    stop = True
                    break
                try:
                    _handle(t, item, out)
                except Exception:  # a bad message must never stop the worker
                    log.exception("ROS 2 ingest worker failed on %s", item[0])
                if out and time.monotonic() - sent_at >= FLUSH_S:  # a long batch: what is done goes now
                    _send_outcomes(outbox, out)
                    out, sent_at = [], time.monotonic()
            try:
                out += t.give_up_waiting()
            except Exception:
                log.exception("ROS 2 ingest worker failed on the arrays waiting for TF")
            if out:
                _send_outcomes(outbox, out)
        except (OSError, KeyboardInterrupt):
            return
    with contextlib.suppress(OSError):
        outbox.send_bytes(pickle.dumps(None))  # this worker's last word


def _send_outcomes(outbox: Any, out: list[Outcome]) -> None:
    outbox.send_bytes(pickle.dumps(out, protocol=pickle.HIGHEST_PROTOCOL))


def _handle(t: RobotTranslator, item: tuple[Any, ...], out: list[Outcome]) -> None:
    op = item[0]
    if op == "msg":
        out += t.handle(item[1], item[2], item[3], item[4])
    elif op == "storey":
        t.set_storey(item[1], item[2])
    elif op == "session":
        t.set_session(item[1], item[2])
    elif op == "elevations":
        t.set_elevations(item[1])
    elif op == "grid":
        t.set_grid(item[1])


@dataclass(eq=False, slots=True)
class _Worker:
    """A worker process and its pipes: ``pending`` is what its sender has not written yet, ``sent`` how
    many items it wrote to this process (both under ``wake``), ``taken`` (shared memory) how many the
    process took: the queue's depth is ``len(pending) + sent - taken``."""

    index: int
    robots: list[RobotSpec]
    process: Any = None
    started: int = 0
    inbox: Any = None
    """The write end of the pipe to the process."""
    outbox: Any = None
    """The read end of the pipe from the process (None once it said its last word or died)."""
    taken: Any = None
    sent: int = 0
    pending: list[tuple[Any, ...] | None] = field(default_factory=list)
    wake: threading.Condition = field(default_factory=threading.Condition)
    sender: threading.Thread | None = None

    def depth(self) -> int:
        return len(self.pending) + self.sent - int(self.taken.value)


class WorkerPool:
    """``count`` worker processes, robots sharded over them by name (each robot in one worker, its
    messages in order); their outcomes go to ``deliver`` on the pool's own thread. ``replay(robot)``
    gives what a restarted worker must be fed again (feeds, in order).

    Each worker has a pipe each way: a sender thread writes what is queued for it in batches (everything
    queued within :data:`LINGER_S` of the first: one pickle and one write), and the worker answers each
    batch with one batch of outcomes, read by the pool's thread."""

    def __init__(
        self,
        robots: list[RobotSpec],
        count: int,
        *,
        deliver: Callable[[list[Outcome]], None],
        replay: Callable[[list[str]], list[tuple[Any, ...]]],
        on_restart: Callable[[list[str]], None],
        fusion_terms: bool,
        typed: bool,
        tf_wait_s: float,
        queue_depth: int,
        limits: Limits | None = None,
        hold_steady_s: float = 0.0,
    ) -> None:
        """``limits``: the twin's, for the workers to check the typed records they make (see
        :class:`RobotTranslator`); ``hold_steady_s``: how long the pool's thread holds steady arrays
        before it delivers them (:mod:`adapters.zenoh.ros_hold`)."""
        self._ctx = mp.get_context("spawn")  # no fork: the daemon holds Zenoh's and the store's threads
        self.deliver = deliver
        self.replay = replay
        self.on_restart = on_restart
        self._args = {
            "fusion_terms": fusion_terms,
            "typed": typed,
            "tf_wait_s": tf_wait_s,
            "limits": limits,
        }
        self.queue_depth = queue_depth
        ordered = sorted(robots, key=lambda r: r.name)
        n = max(1, min(count, len(ordered)))
        self.workers = [_Worker(i, ordered[i::n]) for i in range(n)]
        self.of = {r.name: w for w in self.workers for r in w.robots}
        self.restarts = 0
        self.bunches = 0
        """Batches of outcomes read from the workers (the pool's thread writes it)."""
        self.outcomes = 0
        """Outcomes in them."""
        self.delivered = 0
        """Batches delivered (after the hold: ``outcomes / delivered`` is how many the writer gets at
        once)."""
        self._hold = SteadyHold(hold_steady_s)
        """Steady arrays held back (the pool's thread alone uses it)."""
        self._closing = threading.Event()
        self._lock = threading.Lock()
        for w in self.workers:
            self._start(w)
            w.sender = threading.Thread(
                target=self._send, args=(w,), name=f"ros-ingest-send-{w.index}", daemon=True
            )
            w.sender.start()
        self._thread = threading.Thread(target=self._run, name="ros-ingest-pool", daemon=True)
        self._thread.start()

    def _start(self, w: _Worker) -> None:
        """Start ``w``'s process with new pipes (its condition held, or before its sender runs)."""
        inbox_r, inbox_w = self._ctx.Pipe(duplex=False)
        outbox_r, outbox_w = self._ctx.Pipe(duplex=False)
        taken = self._ctx.RawValue("q", 0)
        w.process = self._ctx.Process(
            target=_worker_main,
            args=(w.robots,),
            kwargs={**self._args, "inbox": inbox_r, "outbox": outbox_w, "taken": taken},
            name=f"twin-ros-ingest-{w.index}",
            daemon=True,
        )
        w.process.start()
        inbox_r.close()  # the process's ends: a dead process is a broken pipe / an end of file here
        outbox_w.close()
        w.inbox, w.outbox, w.taken, w.sent = inbox_w, outbox_r, taken, 0
        w.started += 1

    def put(self, owner: str, kind: str, payload: bytes, received_ns: int) -> None:
        """Queue a robot's message for its worker; queue.Full if that worker holds ``queue_depth``
        already (the feeds are never refused)."""
        w = self.of[owner]
        with w.wake:
            if w.depth() >= self.queue_depth:
                raise queue.Full
            w.pending.append(("msg", owner, kind, payload, received_ns))
            if len(w.pending) == 1:
                w.wake.notify()

    def feed(self, item: tuple[Any, ...], robot: str | None = None) -> None:
        """Something every worker (or ``robot``'s) must know, in order with the messages."""
        for w in [self.of[robot]] if robot is not None else self.workers:
            with w.wake:
                w.pending.append(item)
                w.wake.notify()

    def depths(self) -> list[int]:
        out = []
        for w in self.workers:
            with w.wake:
                out.append(w.depth())
        return out

    def _send(self, w: _Worker) -> None:
        """``w``'s sender thread: what is queued for it, in batches, in order."""
        last = False
        while not last:
            with w.wake:
                while not w.pending:
                    w.wake.wait()
            time.sleep(LINGER_S)  # the rest of the burst (a robot's array right after its TF)
            with w.wake:
                batch, w.pending = w.pending, []
                w.sent += len(batch)
                pipe = w.inbox
            last = self._closing.is_set() and batch[-1] is None
            try:
                data = pickle.dumps(batch, protocol=pickle.HIGHEST_PROTOCOL)
            except Exception:  # a bug must cost this batch, never the sender
                log.exception("Could not send %d items to ROS 2 ingest worker %d", len(batch), w.index)
                continue
            try:
                pipe.send_bytes(data)
            except (OSError, ValueError):  # the process died (restarted by the pool): the batch is lost
                continue

    def _run(self) -> None:
        next_check = 0.0
        selector = selectors.DefaultSelector()  # kept while the pipes are (one made per wait: 10 us)
        watched: dict[Any, _Worker] = {}
        try:
            while True:
                outboxes = {w.outbox: w for w in self.workers if w.outbox is not None}
                if outboxes.keys() != watched.keys():  # a worker started again or gone quiet: a new one
                    selector.close()  # (a closed pipe cannot be unregistered by its file number)
                    selector = selectors.DefaultSelector()
                    for conn in outboxes:
                        selector.register(conn, selectors.EVENT_READ)
                    watched = outboxes
                if self._closing.is_set() and not watched:
                    if self._hold.held:
                        self._deliver(self._hold.take(math.inf))
                    return
                got: list[Any] = []
                wait = self._hold.wait_s(time.monotonic())
                wait = 0.25 if wait is None else min(0.25, wait)
                if watched:
                    with contextlib.suppress(OSError):
                        got = [key.fileobj for key, _ in selector.select(timeout=wait)]
                else:  # every worker dead (started again by the check below)
                    time.sleep(min(0.05, wait))
                self._take(got, watched)
                now = time.monotonic()
                if self._hold.due(now):
                    self._deliver(self._hold.take(now))
                if not self._closing.is_set() and now >= next_check:  # a waitpid per worker: not per batch
                    next_check = now + SUPERVISE_S
                    self._supervise()
        finally:
            selector.close()

    def _take(self, ready: list[Any], watched: dict[Any, _Worker]) -> None:
        """Read a batch of outcomes from each ready pipe and deliver it, or put it in the hold (the pool's
        thread)."""
        for conn in ready:
            w = watched.get(conn)
            if w is None or w.outbox is not conn:
                continue
            try:
                item = pickle.loads(conn.recv_bytes())
            except (EOFError, OSError):  # it died without its last word
                item = None
            if item is None:
                with contextlib.suppress(OSError):
                    conn.close()
                w.outbox = None
                continue
            self.bunches += 1
            self.outcomes += len(item)
            if self._hold.hold_s > 0.0:
                self._hold.add(item, time.monotonic())
            else:  # (no hold: each batch delivered as it is read, as it always was)
                self._deliver(item)

    def _deliver(self, outcomes: list[Any]) -> None:
        self.delivered += 1
        try:
            self.deliver(outcomes)
        except Exception:
            log.exception("Delivering a ROS 2 ingest worker's outcomes failed")

    def _supervise(self) -> None:
        for w in self.workers:
            if w.process.is_alive() or self._closing.is_set():
                continue
            names = [r.name for r in w.robots]
            if self._hold.held:  # (the replay resumes the tracker sessions the writer was told of)
                self._deliver(self._hold.take(math.inf))
            log.warning(
                "ROS 2 ingest worker %d (robots %s) exited with code %s; starting it again",
                w.index, ", ".join(names), w.process.exitcode,
            )  # fmt: skip
            with self._lock:
                self.restarts += 1
            with w.wake:  # what the dead worker had not taken is dropped with it (counted)
                old = (w.inbox, w.outbox)
                self._start(w)
                w.pending = list(self.replay(names))
                w.wake.notify()
            for conn in old:
                with contextlib.suppress(Exception):
                    if conn is not None:
                        conn.close()
            self.on_restart(names)

    def close(self, timeout_s: float = 5.0) -> None:
        """Stop every worker (they finish what they hold), join them and the pool's threads."""
        self._closing.set()
        deadline = time.monotonic() + timeout_s
        for w in self.workers:
            with w.wake:
                w.pending.append(None)
                w.wake.notify()
        for w in self.workers:
            w.process.join(timeout=max(0.1, deadline - time.monotonic()))
            if w.process.is_alive():
                w.process.kill()
                w.process.join(timeout=1.0)
        self._thread.join(timeout=max(0.5, deadline - time.monotonic()))
        for w in self.workers:
            if w.sender is not None:
                w.sender.join(timeout=max(0.1, deadline - time.monotonic()))
            for conn in (w.inbox, w.outbox):
                with contextlib.suppress(Exception):
                    if conn is not None:
                        conn.close()
