"""``twin serve``: the daemon. Opens the store (importing ``--ifc`` first when it is empty), builds and
publishes every skill map, serves robots over Zenoh until SIGINT/SIGTERM, then shuts down cleanly."""

from __future__ import annotations

import argparse
import dataclasses
import logging
import signal
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import zenoh

from adapters.cli.common import (
    add_store_args,
    key_prefix,
    open_store,
    remote_store_of,
    store_exists,
    store_label,
    store_path_of,
    stored_site,
    zenoh_of,
)
from adapters.cli.memory import fix_heap_thresholds, free_memory_releaser
from adapters.cli.progress import Advance, progress_bar
from adapters.rerun.settings import RerunSettings
from adapters.ros.sessions import resume_sessions
from adapters.ros.settings import RosSettings, ros_robots
from adapters.zenoh.access import site_access_control
from adapters.zenoh.daemon import ZenohDaemon
from adapters.zenoh.errors import TransportError
from adapters.zenoh.keys import SiteKeys
from adapters.zenoh.points import ZenohPoints
from adapters.zenoh.ros_ingest import RosIngest
from adapters.zenoh.ros_maps import RosMapPublisher
from adapters.zenoh.ros_points import RosPointsPublisher
from adapters.zenoh.session import session_config
from twin.config import Config
from twin.errors import StoreNotFoundError
from twin.live import TwinService
from twin.live.events import MapPublished, TwinEvent, TwinStarted
from twin.live.snapshots import Snapshots, snapshot_path

if TYPE_CHECKING:
    from adapters.rerun import RerunRecorder

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
        if isinstance(event, TwinStarted):
            self.total = len(event.storeys) * len(event.skills)
            self.advance(0, self.total)
        elif isinstance(event, MapPublished):
            self.published += 1
            self.total = max(self.total, self.published)
            self.advance(self.published, self.total)


def cmd_serve(args: argparse.Namespace, cfg: Config) -> int:
    if args.site:
        cfg = dataclasses.replace(cfg, site=args.site, site_set=True)
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
    stop = threading.Event()

    def on_signal(signum: int, frame: Any) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
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
            access_control=site_access_control(cfg, keys),
        )
        try:
            session = zenoh.open(conf)
        except Exception as err:
            endpoints = ", ".join(args.listen or zenoh_of(cfg).listen)
            msg = f"Cannot open the Zenoh session (listening on {endpoints}): {err}"
            raise TransportError(msg) from err
        recorder = _recorder(args, cfg, cfg.site)
        release = free_memory_releaser()
        service = TwinService(
            store,
            cfg,
            housekeeping=[release] if release is not None else [],
            snapshot=_snapshots(args, cfg),
        )
        daemon: ZenohDaemon | None = None
        ros: RosMapPublisher | None = None
        ingest: RosIngest | None = None
        ros_points: RosPointsPublisher | None = None
        points: ZenohPoints | None = None
        try:
            frame_id = cfg.section(RosSettings).frame_id
            daemon = ZenohDaemon(session, service, keys=keys, frame_id=frame_id)
            if cfg.robots:  # ROS 2 map topics, and every robot's storey (robots/<name>/storey)
                ros = RosMapPublisher.following(daemon, cfg)  # on the dispatcher, a lane per robot
            if cfg.sources or any(r.detections is not None for r in ros_robots(cfg).values()):
                storey_of = ros.storey_of if ros is not None else (lambda _robot: None)
                sessions = resume_sessions(service.store.select, cfg.robots)  # a restart starts none
                ingest = RosIngest(
                    session, cfg, service.submit_observation, storey_of=storey_of, sessions=sessions
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
            with progress_bar("preparing maps") as advance:
                progress = _StartProgress(advance)
                service.sinks.insert(0, progress)
                try:
                    service.start()
                finally:
                    service.sinks.remove(progress)
            daemon.drain()  # every map is declared and sent before we say so
            maps = service.published_maps()
            endpoints = ", ".join(args.listen or zenoh_of(cfg).listen) or "(no listener)"
            print(
                f"serving site {cfg.site!r} at revision {service.revision} on {endpoints} "
                f"under {keys.prefix}/: {len(maps)} maps published in {time.perf_counter() - t0:.2f} s "
                + (
                    "(built from the store)"
                    if service.restored_from is None
                    else f"(from the snapshot of revision {service.restored_from})"
                ),
                flush=True,
            )
            service.serve_forever(stop)
        finally:
            t1 = time.perf_counter()
            for closable in (ingest, daemon, points, ros, ros_points):
                if closable is not None:
                    closable.close()
            session.close()
            if recorder is not None:
                recorder.close()
    print(f"stopped cleanly in {time.perf_counter() - t1:.2f} s", flush=True)
    sys.stdout.flush()
    return 0


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
