"""``twin watch``: subscribe to maps like a robot, print every version, write the last ones.

What is watched: a skill's maps on the daemon's keys (``--skill``; a ``points`` skill's clouds too), or a
ROS 2 robot's topic (``--ros NAMESPACE [--topic map | points_map ...]``) as a node on rmw_zenoh or the
DDS bridge would see it. How long: ``--timeout`` is the wait for the daemon (its session and its first
answer), ``--count N`` stops after N versions, ``--for SECONDS`` bounds the whole watch; Ctrl-C and
SIGTERM end it too. On every end, ``--out DIR`` gets the latest of each map (map_server files) or cloud
(PCD), and a watch that ended before ``--count`` versions says so and exits 1.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from adapters.cli.common import add_client_args, key_prefix, open_client
from adapters.ros import write_map_files
from adapters.ros.pcd import pcd_of_points
from adapters.zenoh.client import MapVersion, MapWatcher, TwinClient
from adapters.zenoh.cloud_watch import CloudSample, CloudWatcher
from twin.config import Config
from twin.errors import ObservationError, SkillError
from twin.maps.grid import OccupancyGrid

POINTS_TOPIC = "points_map"
"""A ROS topic whose name starts with this carries ``sensor_msgs/PointCloud2`` (``points_map``,
``points_map_<skill>``: :mod:`adapters.zenoh.ros_points`); any other, ``nav_msgs/OccupancyGrid``."""


def cell_counts(data: np.ndarray[Any, Any]) -> str:
    """``"1534 occupied"``, and the cells of any other value (a speed mask's percent): ``", 30 at 30"``."""
    values, counts = np.unique(data, return_counts=True)
    text = f"{int(counts[values == 100].sum())} occupied"
    for value, n in zip(values.tolist(), counts.tolist(), strict=True):
        if 0 < value < 100:
            text += f", {n} at {value}"
    return text


def _describe(v: MapVersion) -> str:
    return (
        f"{v.grid.storey}/{v.grid.skill} version {v.version} (revision {v.revision}) via {v.via}: "
        f"{v.grid.frame.width}x{v.grid.frame.height} cells, {cell_counts(v.grid.data)}"
    )


@contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM ends a watch as Ctrl-C does (the final maps are still written)."""

    def on_term(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, on_term)
    except ValueError:  # not the main thread (the command run in-process): leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


class Tally:
    """Counts what arrived (from Zenoh's threads) and prints each line under one lock."""

    def __init__(self) -> None:
        self.seen = threading.Semaphore(0)
        self.lock = threading.Lock()
        self.got = 0
        self.ended = False
        self.interrupted = False
        """Ended by Ctrl-C or SIGTERM: the user's choice, not a failure (exit 0)."""

    def arrived(self, line: str) -> None:
        with self.lock:
            if self.ended:  # arrived while the watch was ending: not counted, not printed
                return
            print(line, flush=True)
        self.seen.release()

    def wait(self, count: int | None, for_s: float | None) -> bool:
        """Wait for ``count`` arrivals (forever when None) for at most ``for_s`` seconds (None: no
        limit); Ctrl-C or SIGTERM ends it early. True when ``count`` arrived."""
        deadline = None if for_s is None else time.monotonic() + for_s
        try:
            with _sigterm_as_interrupt():
                while count is None or self.got < count:
                    left = 3600.0 if deadline is None else deadline - time.monotonic()
                    if left <= 0:
                        break
                    if self.seen.acquire(timeout=min(left, 3600.0)):
                        self.got += 1
        except KeyboardInterrupt:
            self.interrupted = True
        with self.lock:
            self.ended = True
        return count is None or self.got >= count


def _ended(tally: Tally, args: argparse.Namespace, what: str) -> int:
    """Exit code of a watch: 1 with one line when ``--count`` was not reached before ``--for`` ended it."""
    if args.count is None or tally.got >= args.count or tally.interrupted:
        return 0
    print(f"twin: error: {tally.got} of {args.count} {what} in {args.for_s:g} s (--for)", file=sys.stderr)
    return 1


def _write_cloud(cloud: CloudSample, out: Path, stem: str, label: str) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{stem}.pcd"
    path.write_bytes(pcd_of_points(cloud.points[:, :3], cloud.points[:, 3:], comment=label))
    return path


def _revision_version(attachment: bytes | None) -> tuple[int, int]:
    try:
        data = json.loads(attachment or b"")
        return int(data["revision"]), int(data["version"])
    except (ValueError, KeyError, TypeError):
        return (-1, -1)


def _ros_robots(twin: TwinClient, timeout_s: float) -> dict[str, dict[str, Any]] | None:
    """The daemon's configured ROS 2 robots (status ``robots``), or None when no daemon answers soon."""
    if not twin.wait_for_route(twin.keys.status, min(timeout_s, 2.0)):
        return None
    robots = twin.status().get("robots")
    return robots if isinstance(robots, dict) else {}


def _check_ros_target(args: argparse.Namespace, robots: dict[str, dict[str, Any]] | None, site: str) -> None:
    """SkillError naming the configured robots (their topics) when ``--ros``/``--topic`` is none of them."""
    if robots is None:
        return  # no daemon of this site answers: a foreign publisher may still be there
    namespace = "/" + args.ros.strip("/")
    by_ns = {str(r.get("namespace") or ""): (name, r) for name, r in robots.items() if isinstance(r, dict)}
    if namespace not in by_ns:
        known = ", ".join(f"{ns} ({name})" for ns, (name, _) in sorted(by_ns.items()) if ns)
        msg = (
            f"Unknown robot namespace {namespace!r}: the daemon of {site} serves ROS 2 maps to {known}."
            if known
            else f"Unknown robot namespace {namespace!r}: the daemon of {site} has no ROS 2 robots "
            "configured ([robots.NAME] with a namespace)."
        )
        raise SkillError(msg)
    name, robot = by_ns[namespace]
    topics = [t.rsplit("/", 1)[-1] for t in (robot.get("topics") or {})]
    points = args.topic.startswith(POINTS_TOPIC)  # every robot gets the points skills' topics
    if topics and args.topic not in topics and not points and not args.topic.endswith("_updates"):
        msg = f"Robot {name} ({namespace}) has no topic {args.topic!r}: its topics are {', '.join(topics)}."
        raise SkillError(msg)


def cmd_watch_ros(args: argparse.Namespace, cfg: Config) -> int:
    """``twin watch --ros NS``: subscribe exactly as an rmw_zenoh node or the DDS bridge would."""
    from adapters.ros.pcd import POINT_CLOUD2
    from adapters.ros.rmw_zenoh import RosTopic
    from adapters.zenoh.ros_watch import RosMapWatcher, RosSample

    tally = Tally()
    name = f"{args.ros.rstrip('/')}/{args.topic}"
    stem = f"{args.ros.strip('/').replace('/', '-')}__{args.topic.replace('/', '-')}"
    prefix = key_prefix(cfg, args.site)  # ROS 2 keys: no site to look for
    with open_client(args, cfg, prefix=prefix) as twin:
        _check_ros_target(args, _ros_robots(twin, args.timeout), twin.keys.prefix)
        if args.topic.startswith(POINTS_TOPIC):
            topic = RosTopic(args.domain_id, args.ros, args.topic, POINT_CLOUD2)
            key = topic.data_key if args.layout == "rmw_zenoh" else topic.bridge_key

            def on_cloud(c: CloudSample) -> None:
                tally.arrived(f"{name} via {args.layout}: {len(c.points):,} points")

            clouds = CloudWatcher(twin.session, key, on_cloud=on_cloud)
            try:
                tally.wait(args.count, args.for_s)
            finally:
                clouds.close()
            if args.out and clouds.latest is not None:
                path = _write_cloud(
                    clouds.latest, Path(args.out), stem, f"ROS 2 topic {name} (twin watch --ros)"
                )
                print(f"wrote {path}")
            return _ended(tally, args, f"clouds on {key}")

        def on_sample(s: RosSample) -> None:
            seq = f", rmw sequence {s.sequence}" if s.sequence is not None else ""
            size = f"{s.grid.frame.width}x{s.grid.frame.height}"
            tally.arrived(f"{name} via {s.kind}{seq}: {size}, {cell_counts(s.grid.data)}")

        watcher = RosMapWatcher(
            twin.session, namespace=args.ros, layout=args.layout, domain_id=args.domain_id,
            topic=args.topic, on_sample=on_sample,
        )  # fmt: skip
        try:
            tally.wait(args.count, args.for_s)
        finally:
            watcher.close()
        if args.out and watcher.latest is not None:
            g = watcher.latest  # a ROS message names no storey or skill: files are named <ns>__<topic>
            named = OccupancyGrid(
                g.frame,
                g.data,
                args.ros.strip("/").replace("/", "-"),
                args.topic.replace("/", "-"),
                g.elevation_m,
            )
            files = write_map_files(named, Path(args.out), stamp_ns=time.time_ns())
            _label_ros_yaml(files.yaml, name)
            print(f"wrote {files.yaml}")
        return _ended(tally, args, f"samples on {watcher.keys[0]}")


META = "# building-twin map:"
"""The start of the comment line of a map_server YAML that names the map's storey and skill
(``adapters.ros.map_server``)."""


def _label_ros_yaml(yaml: Path, topic: str) -> None:
    """A ROS map names no storey or skill: its YAML's building-twin comment names the topic instead."""
    lines = yaml.read_text().splitlines(keepends=True)
    lines = [f"# ROS 2 topic {topic} (twin watch --ros)\n" if ln.startswith(META) else ln for ln in lines]
    yaml.write_text("".join(lines))


def _points_storeys(twin: TwinClient, skill: str) -> list[str] | None:
    """The storeys of ``skill``'s clouds when it is a points skill the daemon has, else None."""
    profile = twin.skills().get(skill)
    if not isinstance(profile, dict) or profile.get("kind") != "points":
        return None
    storeys = twin.status().get("storeys")
    return [str(s) for s in storeys] if isinstance(storeys, list) else []


def _only_storey(args: argparse.Namespace, storeys: list[str], site: str) -> list[str]:
    if not args.storey:
        return storeys
    if args.storey not in storeys:
        msg = (
            f"Unknown storey {args.storey!r}: {site} serves {args.skill} maps of the storeys "
            f"{', '.join(storeys)}."
        )
        raise SkillError(msg)
    return [args.storey]


def _watch_clouds(args: argparse.Namespace, twin: TwinClient, storeys: list[str]) -> int:
    tally = Tally()

    def on_cloud(storey: str) -> Callable[[CloudSample], None]:
        def arrived(c: CloudSample) -> None:
            revision, version = _revision_version(c.attachment)
            tally.arrived(
                f"{storey}/{args.skill} version {version} (revision {revision}): {len(c.points):,} points"
            )

        return arrived

    watchers = {
        s: CloudWatcher(twin.session, twin.keys.points_map(s, args.skill), on_cloud=on_cloud(s))
        for s in storeys
    }
    try:
        tally.wait(args.count, args.for_s)
    finally:
        for w in watchers.values():
            w.close()
    if args.out:
        for storey, w in watchers.items():
            if w.latest is not None:
                label = f"building-twin storey={storey} skill={args.skill} (twin watch)"
                print(f"wrote {_write_cloud(w.latest, Path(args.out), f'{storey}__{args.skill}', label)}")
    return _ended(tally, args, "clouds")


def cmd_watch(args: argparse.Namespace, cfg: Config) -> int:
    if args.ros:
        return cmd_watch_ros(args, cfg)
    if not args.skill:
        msg = "Give --skill NAME (or --ros NAMESPACE to watch a ROS 2 robot's /map)."
        raise ObservationError(msg)
    with open_client(args, cfg) as twin:
        maps = twin.list_maps()
        storeys = [s for s, k in maps if k == args.skill]
        if not storeys:
            clouds = _points_storeys(twin, args.skill)
            if clouds is not None:
                return _watch_clouds(args, twin, _only_storey(args, clouds, twin.keys.prefix))
            known = ", ".join(sorted({k for _, k in maps} | set(twin.skills()))) or "none"
            msg = f"Unknown skill {args.skill!r}: {twin.keys.prefix} serves maps of the skills {known}."
            raise SkillError(msg)
        storeys = _only_storey(args, storeys, twin.keys.prefix)
        tally = Tally()
        watchers: list[MapWatcher] = [
            twin.watch(s, args.skill, lambda v: tally.arrived(_describe(v))) for s in storeys
        ]
        try:
            tally.wait(args.count, args.for_s)
        finally:
            for w in watchers:
                w.close()
        if args.out:
            out = Path(args.out)
            for w in watchers:
                if w.latest is not None:
                    files = write_map_files(w.latest.grid, out, stamp_ns=time.time_ns())
                    print(f"wrote {files.yaml}")
        return _ended(tally, args, "map versions")


def add_parser(sub: Any) -> None:
    sp = sub.add_parser("watch", help="subscribe to a skill's maps like a robot; print each version")
    add_client_args(sp)
    sp.add_argument("--skill", help="the skill whose maps (or, for a points skill, clouds) to watch")
    sp.add_argument("--ros", metavar="NAMESPACE", help="watch <NAMESPACE>/map as a ROS 2 node would instead")
    sp.add_argument(
        "--topic", default="map",
        help="with --ros: the topic under the namespace (default map; points_map...: a PointCloud2)",
    )  # fmt: skip
    sp.add_argument("--layout", choices=["rmw_zenoh", "bridge"], default="rmw_zenoh", help="with --ros")
    sp.add_argument("--domain-id", type=int, default=0, help="ROS domain id, with --ros (default 0)")
    sp.add_argument("--storey", help="one storey key (default: every storey)")
    sp.add_argument("--count", type=int, help="stop after this many versions (maps, clouds or samples)")
    sp.add_argument(
        "--for", dest="for_s", type=float, metavar="SECONDS",
        help="stop after this long in all (default: until --count, Ctrl-C or SIGTERM)",
    )  # fmt: skip
    sp.add_argument(
        "--out",
        help="on any end, write the latest maps (map_server files) or clouds (PCD) into this directory",
    )
    sp.set_defaults(func=cmd_watch)
