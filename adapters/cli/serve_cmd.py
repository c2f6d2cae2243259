"""``twin serve``: the daemon. Opens the store (importing ``--ifc`` first when it is empty), builds and
publishes every skill map, serves robots over Zenoh until SIGINT/SIGTERM, then shuts down cleanly."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import faulthandler
import gc
import logging
import multiprocessing
import os
import signal
import socket
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import zenoh

from adapters.cli.common import (
    add_store_args,
    check_site,
    key_prefix,
    open_store,
    remote_store_of,
    store_exists,
    store_label,
    store_path_of,
    stored_site,
    zenoh_of,
)
from adapters.cli.log_outlet import THREAD_NAME as OUTLET_THREAD
from adapters.cli.log_outlet import Outlet
from adapters.cli.memory import fix_heap_thresholds, free_memory_releaser
from adapters.cli.progress import Advance, progress_bar
from adapters.cli.serve_settings import ServeSettings
from adapters.rerun.settings import RerunSettings
from adapters.ros.sessions import resume_sessions
from adapters.ros.settings import RosSettings, ros_robots
from adapters.zenoh.access import access_summary, log_refused_sessions, site_access_control
from adapters.zenoh.daemon import ZenohDaemon
from adapters.zenoh.errors import TransportError
from adapters.zenoh.keys import SiteKeys
from adapters.zenoh.points import ZenohPoints
from adapters.zenoh.ros_maps import RosMapPublisher
from adapters.zenoh.ros_points import RosPointsPublisher
from adapters.zenoh.session import session_config
from twin.config import Config
from twin.errors import StoreNotFoundError
from twin.live import TwinService
from twin.live.events import MapPublished, PointsPublished, TwinEvent, TwinStarted
from twin.live.snapshots import Snapshots, snapshot_path

if TYPE_CHECKING:
    from adapters.cli.map_routes import ServedRoutes
    from adapters.cli.route_updates import RouteUpdates
    from adapters.rerun import RerunRecorder
    from adapters.zenoh.ros_ingest import RosIngest

log = logging.getLogger(__name__)


def _needs_import(args: argparse.Namespace, cfg: Config) -> bool:
    if not store_exists(args, cfg):
        return True
    with open_store(args, cfg) as store:
        return store.is_empty()


def _recorder(args: argparse.Namespace, cfg: Config, site: str) -> RerunRecorder | None:
    """The Rerun recorder sink, unless recording is off (``--no-record``, or ``[rerun] record = false``
    with no ``--record`` and no viewer URL)."""
    rerun = cfg.section(RerunSettings)
    if args.no_record or (not rerun.record and not args.record and not rerun.connect_url):
        return None
    path = Path(args.record) if args.record else None
    if path is None and rerun.record:
        path = rerun.directory / f"{site}-{time.strftime('%Y%m%d-%H%M%S')}.rrd"
    from adapters.rerun import RerunRecorder  # here: a daemon that records nothing starts without Rerun

    return RerunRecorder(
        path=path,
        connect_url=rerun.connect_url,
        application=f"twin {site}",
        rotate_every_s=rerun.rotate_every_s,
        max_bytes=rerun.max_bytes,
    )


def _snapshots(args: argparse.Namespace, cfg: Config) -> Snapshots | None:
    """Where the daemon keeps its derived state: ``<store>.snapshot`` next to the embedded store."""
    if args.no_snapshot or not cfg.store_snapshot:
        return None
    if remote_store_of(args, cfg) is not None:
        log.info("No snapshot of the derived state: the graph is on a SPARQL server (rebuilt on each start)")
        return None
    return Snapshots(snapshot_path(store_path_of(args, cfg)), every_s=cfg.store_snapshot_every_s)


class _StartProgress:
    """A sink that reports the start's maps: TwinStarted says how many, each MapPublished is one more."""

    def __init__(self, advance: Advance) -> None:
        self.advance = advance
        self.total = 0
        self.published = 0

    def emit(self, event: TwinEvent) -> None:
        if isinstance(event, TwinStarted):  # clouds come after: _CloudProgress reports them
            grids = [name for name, skill in event.skills.items() if skill.kind != "points"]
            self.total = len(event.storeys) * len(grids)
            self.advance(0, self.total)
        elif isinstance(event, MapPublished):
            self.published += 1
            self.total = max(self.total, self.published)
            self.advance(self.published, self.total)


STOP_TIMED_OUT = 124
"""The exit code of a stop that did not end within ``[serve] stop_timeout_s`` (as timeout(1) exits)."""
INTERRUPTED = 130
"""The exit code of a start-up interrupted by SIGINT or SIGTERM (as the other commands)."""
STACKS_SIGNAL = signal.SIGUSR1
"""The signal on which the daemon writes every Python thread's stack to stderr and runs on (Python's
:mod:`faulthandler`, written from the signal handler: it works when the threads are stuck, even in a
native call that holds the GIL). ``kill -USR1 PID`` when a daemon does not answer or does not stop."""


class _Signals:
    """SIGINT and SIGTERM: during start-up they interrupt it (KeyboardInterrupt, exit 130); once the
    daemon serves, they ask for a clean stop (:attr:`stop`). A second signal during a stop is ignored.

    Python runs a signal's handler on the main thread, between two bytecodes: a main thread held in a
    native call would not see the signal. So the C handler also writes the signal's number to a socket
    (:func:`signal.set_wakeup_fd`) that a thread of its own reads: it asks for the stop too, and arms
    :data:`LAST_RESORT_S` after it, :mod:`faulthandler`'s native timer that writes every thread's stack
    and ends the process (code 1) should the stop not end, even with the GIL held. Example::

        signals = _Signals(stop_timeout_s=10.0)
        signals.install()  # the handlers, the wakeup socket and its thread (as long as the process)
        signals.stop.wait()
    """

    def __init__(self, stop_timeout_s: float, *, margin_s: float | None = None) -> None:
        self.stop = threading.Event()
        self.serving = False
        self.last_resort_s = 2 * stop_timeout_s + (LAST_RESORT_S if margin_s is None else margin_s)
        self._lock = threading.RLock()  # the main thread's handler may run again inside it
        self._interrupted = False
        self._reader: socket.socket | None = None
        self._writer: socket.socket | None = None
        self._thread: threading.Thread | None = None

    def install(self) -> None:
        signal.signal(signal.SIGINT, self)
        signal.signal(signal.SIGTERM, self)
        self._reader, self._writer = socket.socketpair()
        self._writer.setblocking(False)
        signal.set_wakeup_fd(self._writer.fileno(), warn_on_full_buffer=False)
        self._thread = threading.Thread(target=self._read, name=SIGNALS_THREAD, daemon=True)
        self._thread.start()

    def __call__(self, signum: int, frame: Any) -> None:  # the main thread's handler
        self._request()
        if not self.serving and not self._interrupted:
            self._interrupted = True
            raise KeyboardInterrupt

    def _read(self) -> None:
        assert self._reader is not None
        while data := self._reader.recv(64):
            if any(n in (signal.SIGINT, signal.SIGTERM) for n in data):
                self._request()

    def _request(self) -> None:
        """The first signal: the stop, or (during start-up) the interrupt's deadline; once, whichever
        thread sees it first."""
        with self._lock:
            if self.stop.is_set():
                return
            self.stop.set()
            serving = self.serving
        if serving:
            faulthandler.dump_traceback_later(self.last_resort_s, exit=True)
        else:
            threading.Thread(target=_interrupt_deadline, name=STOP_WATCHDOG, daemon=True).start()


SIGNALS_THREAD = "twin-signals"
STOP_WATCHDOG = "twin-stop-watchdog"
LAST_RESORT_S = 5.0
"""How long after twice ``[serve] stop_timeout_s`` (when the stop's own watchdog should have ended the
process with 124) :mod:`faulthandler`'s native timer ends a stop that still runs: it needs no Python
thread to run, so it ends a process whose GIL is held by a stuck native call, after writing the stacks."""


OUTLET_CLOSE_S = 2.0
"""How long the exit waits for the output to be written while its reader takes it."""
INTERRUPT_DEADLINE_S = 3.0
"""How long an interrupted start-up may take to close what it opened before the process just ends."""


def _interrupt_deadline() -> None:
    """The start-up was interrupted: if it has not ended in :data:`INTERRUPT_DEADLINE_S` (a native call
    that does not return, a lock the interrupt left held), end it now: kill the meshing children and
    leave with 130. The store then recovers as after ``kill -9`` (nothing was acked yet)."""
    time.sleep(INTERRUPT_DEADLINE_S)
    for child in multiprocessing.active_children():
        with contextlib.suppress(Exception):
            child.kill()
    _leave(INTERRUPTED, f"the interrupted start-up did not end in {INTERRUPT_DEADLINE_S:g} s")


class _Stop:
    """The stop's deadline (``[serve] stop_timeout_s`` from the signal), what it is doing, and what it
    found still running. A watchdog ends the process if the stop itself hangs (a native call that
    never returns) for twice the timeout."""

    def __init__(self, timeout_s: float, outlet: Outlet | None = None) -> None:
        self.timeout_s = timeout_s
        self.outlet = outlet
        self.deadline = time.monotonic() + timeout_s
        self.phase = "finishing the queued requests"
        self.left: list[str] = []
        self._done = threading.Event()
        self._watchdog = threading.Thread(target=self._watch, name=STOP_WATCHDOG, daemon=True)
        self._watchdog.start()

    def remaining(self) -> float:
        return max(0.0, self.deadline - time.monotonic())

    def _watch(self) -> None:
        if not self._done.wait(2 * self.timeout_s):
            reason = f"the stop hung for {2 * self.timeout_s:.0f} s while {self.phase}"
            _leave(STOP_TIMED_OUT, reason, outlet=self.outlet)

    def done(self) -> None:
        self._done.set()
        self._watchdog.join()


def _leave(code: int, reason: str | None = None, *, outlet: Outlet | None = None) -> NoReturn:
    """End the process now, without the interpreter's finalization: Zenoh's and RocksDB's native
    threads outlive the closed session and store, and one that calls into Python while the
    interpreter finalizes aborts the process (glibc's ``FATAL: exception not rethrown``, SIGABRT).
    Everything the daemon owns is closed and joined before this is called; ``reason`` (a stop that
    did not end in time) is printed as one line; through ``outlet`` (the serving daemon's output), which
    gets a moment to write what it holds unless its reader is stuck."""
    if reason is not None:
        line = f"twin: stop: {reason}; exiting with code {code}"
        if outlet is not None:
            outlet.line(line, err=True)
        else:
            print(line, file=sys.stderr, flush=True)
    if outlet is not None:
        outlet.close(OUTLET_CLOSE_S)
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(code)


class _CloudProgress:
    """A sink that reports the points skills' clouds, built after the daemon serves its maps: a line on
    stderr as each storey's first cloud is published (``cloud 1 of 4 ...``), then nothing more."""

    def __init__(self) -> None:
        self.total = 0
        self.seen: set[tuple[str, str]] = set()
        self.t0 = time.perf_counter()
        self.outlet: Outlet | None = None
        """Where the lines go once the daemon serves (else printed)."""

    def emit(self, event: TwinEvent) -> None:
        if isinstance(event, TwinStarted):
            points = [name for name, skill in event.skills.items() if skill.kind == "points"]
            self.total = len(event.storeys) * len(points)
        if not isinstance(event, PointsPublished) or len(self.seen) >= self.total:
            return
        key = (event.cloud.storey, event.cloud.skill)
        if key in self.seen:
            return
        self.seen.add(key)
        took = time.perf_counter() - self.t0
        line = (
            f"cloud {len(self.seen)} of {self.total} ready: {key[0]}/{key[1]}, {len(event.cloud):,} points "
            f"({took:.1f} s after loading)"
        )
        if self.outlet is not None:
            self.outlet.line(line, err=True)
        else:
            print(line, file=sys.stderr, flush=True)


def cmd_serve(args: argparse.Namespace, cfg: Config) -> int:
    signals = _Signals(cfg.section(ServeSettings).stop_timeout_s)
    signals.install()
    faulthandler.register(STACKS_SIGNAL, all_threads=True)  # `kill -USR1 PID`: every thread's stack
    try:
        return _serve(args, cfg, signals)
    except KeyboardInterrupt:  # during start-up: what was opened is closed again on the way out
        print("twin: interrupted", file=sys.stderr, flush=True)
        _leave(INTERRUPTED)


def _serve(args: argparse.Namespace, cfg: Config, signals: _Signals) -> int:
    if args.site:
        cfg = dataclasses.replace(cfg, site=check_site(args.site), site_set=True)
    if args.ifc and _needs_import(args, cfg):
        from adapters.cli.model_cmds import cmd_import

        ns = argparse.Namespace(
            model=args.ifc,
            store=args.store,
            store_url=args.store_url,
            site=cfg.site if cfg.site_set else None,  # None: named after the file
            base_iri=None,
            replace=False,
        )
        cmd_import(ns, cfg)  # before any Zenoh or store thread exists: meshing forks a child
    fix_heap_thresholds()  # before the store and Zenoh allocate: RSS stays flat all day
    stop_timeout_s = cfg.section(ServeSettings).stop_timeout_s
    stopping: _Stop | None = None
    outlet: Outlet | None = None  # the output, once serving: a reader that stops reading blocks nothing
    with open_store(args, cfg, create=False) as store:
        if store.is_empty():
            msg = f"The store at {store_label(args, cfg)} is empty."
            raise StoreNotFoundError(msg)
        if not cfg.site_set:  # no --site, no site.name: the site the model was imported as
            cfg = dataclasses.replace(cfg, site=stored_site(store) or cfg.site)
        keys = SiteKeys(key_prefix(cfg))
        conf = session_config(
            zenoh_of(cfg),
            mode=args.mode,
            listen=args.listen or None,
            connect=args.connect or None,
            access_control=(acl := site_access_control(cfg, keys)),
        )
        log_refused_sessions(zenoh_of(cfg))
        try:
            session = zenoh.open(conf)
        except Exception as err:
            endpoints = ", ".join(args.listen or zenoh_of(cfg).listen)
            msg = f"Cannot open the Zenoh session (listening on {endpoints}): {err}"
            raise TransportError(msg) from err
        recorder: RerunRecorder | None = None
        daemon: ZenohDaemon | None = None
        ros: RosMapPublisher | None = None
        ingest: RosIngest | None = None
        ros_points: RosPointsPublisher | None = None
        points: ZenohPoints | None = None
        routes: ServedRoutes | None = None
        route_updates: RouteUpdates | None = None
        service: TwinService | None = None
        try:
            recorder = _recorder(args, cfg, cfg.site)
            release = free_memory_releaser()
            service = TwinService(
                store,
                cfg,
                batch_wait_s=cfg.section(ServeSettings).batch_wait_ms / 1e3,
                housekeeping=[release] if release is not None else [],
                snapshot=_snapshots(args, cfg),
            )
            frame_id = cfg.section(RosSettings).frame_id
            daemon = ZenohDaemon(session, service, keys=keys, frame_id=frame_id)
            if cfg.robots:  # ROS 2 map topics, and every robot's storey (robots/<name>/storey)
                ros = RosMapPublisher.following(daemon, cfg)  # on the dispatcher, a lane per robot
            if cfg.sources or any(r.detections is not None for r in ros_robots(cfg).values()):
                from adapters.zenoh.ros_ingest import RosIngest  # here: a site with no ROS input loads none

                storey_of = ros.storey_of if ros is not None else (lambda _robot: None)
                sessions = resume_sessions(service.store.select, cfg.robots)  # a restart starts none
                ingest = RosIngest(  # the obstacles of a previous run from the graph, on TwinStarted
                    session,
                    cfg,
                    service.submit_observation,
                    storey_of=storey_of,
                    select=service.store.select,
                    sessions=sessions,
                )
                daemon.status_sources.append(ingest.status)
                service.sinks.append(ingest)  # storeys, doors and occluding maps: cheap, on the writer
            service.sinks += [sink for sink in (daemon, recorder) if sink is not None]
            points = ZenohPoints(  # points skills' clouds, from the daemon's holder, on the site's lane
                session, prefix=keys.prefix, frame_id=frame_id, maps=daemon.maps, lane=daemon.site
            )
            daemon.followers.append(points)  # on the dispatcher, off the writer
            if any(s.kind == "points" for s in cfg.skills.values()) and cfg.robots:  # /<ns>/points_map
                ros_points = RosPointsPublisher(session, cfg, maps=daemon.maps)
                daemon.followers.append(ros_points)  # a lane per robot
            t0 = time.perf_counter()
            source = store_label(args, cfg)
            print(f"loading site {cfg.site!r} from {source} ...", file=sys.stderr, flush=True)
            clouds = _CloudProgress()
            service.sinks.append(clouds)  # clouds are built after the maps, while serving
            with progress_bar("preparing maps") as advance:
                progress = _StartProgress(advance)
                service.sinks.insert(0, progress)
                try:
                    service.start()
                finally:
                    service.sinks.remove(progress)
            daemon.drain()  # every map is declared and sent before we say so
            if cfg.routes:  # here: the route builders (SciPy) load only for a site with routes skills
                from adapters.cli.map_routes import serve_routes
                from adapters.cli.route_updates import RouteUpdates, routes_published

                routes = serve_routes(session, cfg, store, service.live_maps.scene, prefix=keys.prefix)
            if routes is not None:  # a structural change makes a new graph version
                live = service
                for name, graph in routes.graphs.items():  # drawn over the maps in the recording
                    if recorder is not None:
                        recorder.emit(routes_published(cfg, graph, routes.zenoh.version(name)))
                route_updates = RouteUpdates(
                    routes,
                    cfg,
                    service.store,
                    skills=lambda: live.skills,
                    on_graph=recorder.emit if recorder is not None else None,
                    static=(iri for iri, state in service.states.items() if state.is_static),
                )
                service.sinks.append(route_updates)
            maps = service.published_maps()
            endpoints = ", ".join(args.listen or zenoh_of(cfg).listen) or "(no listener)"
            gc.collect()  # what start-up built lives as long as the daemon: frozen, full collections no
            gc.freeze()  # longer walk it (one cost the writer ~60 ms, 0.2 ms per array, in confirm_cost.py)
            signals.serving = True  # from here a signal asks for a clean stop
            if signals.stop.is_set():  # one came in the last moment of the start
                raise KeyboardInterrupt
            outlet = Outlet()
            outlet.install()
            clouds.outlet = outlet
            daemon.status_sources.append(outlet.status)
            outlet.line(
                f"serving site {cfg.site!r} at revision {service.revision} on {endpoints} "
                f"under {keys.prefix}/, {access_summary(acl, keys, brief=True)}: "
                f"{len(maps)} maps published in {time.perf_counter() - t0:.2f} s "
                + (
                    "(built from the store)"
                    if service.restored_from is None
                    else f"(from the snapshot of revision {service.restored_from})"
                )
            )

            def shut() -> None:  # the stop is seen: no new request; those queued are answered
                nonlocal stopping
                stopping = _Stop(stop_timeout_s, outlet)
                if daemon is not None:
                    daemon.gate.shut()

            service.serve_forever(signals.stop, on_stop=shut)
        finally:
            if stopping is None:  # start-up interrupted, or an error: the same closing, on a deadline
                stopping = _Stop(stop_timeout_s, outlet)
            t1 = time.perf_counter()
            stopping.phase = "closing the Zenoh side"
            for closable in (ingest, points, ros, ros_points, route_updates, routes):
                if closable is not None:
                    closable.close()
            if daemon is not None:
                daemon.close(stopping.remaining())
            stopping.phase = "waiting for SPARQL queries in flight"
            if service is not None and (n := service.queries.close(stopping.remaining())):
                stopping.left.append(
                    f"{n} SPARQL quer{'y' if n == 1 else 'ies'} (pyoxigraph cannot cancel one)"
                )
            if service is not None and service.snapshot is not None:
                stopping.phase = "writing the snapshot"
                service.snapshot.join()
            stopping.phase = "closing the Zenoh session"
            session.close()
            if recorder is not None:
                stopping.phase = "closing the Rerun recording"
                recorder.close(max(1.0, stopping.remaining()))
            stopping.phase = "closing the store"
    # the store is closed: every acked change is in its files
    assert stopping is not None
    stopping.phase = "joining the daemon's threads"
    left = stopping.left + _threads_left(stopping)
    stopping.done()
    if left:
        _leave(
            STOP_TIMED_OUT,
            f"{', '.join(left)} still running after {stop_timeout_s:g} s ([serve] stop_timeout_s)",
            outlet=outlet,
        )
    stopped = f"stopped cleanly in {time.perf_counter() - t1:.2f} s"
    if outlet is not None:
        outlet.line(stopped)
    else:
        print(stopped, flush=True)
    _leave(0, outlet=outlet)


_OWN_THREADS = (STOP_WATCHDOG, OUTLET_THREAD, SIGNALS_THREAD)
"""The threads that live until the process ends: the stop's deadline, the output and the signals."""


def _threads_left(stopping: _Stop) -> list[str]:
    """The Python threads other than this one and the watchdog still running at the deadline (each
    joined until then): a thread left to the interpreter's finalization is a bug, named here."""
    names: list[str] = []
    for thread in threading.enumerate():
        if thread is threading.current_thread() or thread.name in _OWN_THREADS:
            continue
        thread.join(stopping.remaining())
        if thread.is_alive():
            names.append(f"thread {thread.name!r}")
    return names


def add_parser(sub: Any) -> None:
    sp = sub.add_parser("serve", help="run the live twin daemon: serve maps, take observations (Zenoh)")
    add_store_args(sp)
    sp.add_argument("--ifc", help="an IFC file to import first when the store is empty")
    sp.add_argument(
        "--site",
        help="site name (default: site.name if configured, else the site the store was imported as; "
        "the key prefix is twin/<site>)",
    )
    sp.add_argument(
        "--listen", action="append", metavar="ENDPOINT", help="e.g. tcp/127.0.0.1:7447 (repeatable)"
    )
    sp.add_argument("--connect", action="append", metavar="ENDPOINT", help="a router or peer to connect to")
    sp.add_argument("--mode", choices=["peer", "client", "router"], help="Zenoh mode (default: zenoh.mode)")
    sp.add_argument(
        "--no-snapshot",
        action="store_true",
        help="neither read nor write the derived-state snapshot (<store>.snapshot): rebuild every map",
    )
    rec = sp.add_mutually_exclusive_group()
    rec.add_argument("--record", metavar="FILE.rrd", help="record the run to this Rerun file")
    rec.add_argument("--no-record", action="store_true", help="do not record the run")
    sp.set_defaults(func=cmd_serve)
