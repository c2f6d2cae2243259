"""``twin observe``, ``twin watch`` and ``twin storey``: what a robot does, from the command line."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from adapters.cli.common import add_client_args, key_prefix, open_client
from adapters.ros import write_map_files
from adapters.zenoh.client import MapVersion, MapWatcher
from adapters.zenoh.errors import RemoteError, StoreySwitchError
from twin.config import Config
from twin.errors import ObservationError, SkillError
from twin.graph import vocab
from twin.maps.grid import OccupancyGrid


def box_turtle(iri: str, box: list[float], *, ifc_class: str, storey: str, label: str | None = None) -> str:
    """An observation of one oriented box ``[x, y, z, sx, sy, sz, yaw]`` (see docs/observations.md)."""
    t = vocab.TWIN
    text = f"<{iri}> <{t}ifcClass> {json.dumps(ifc_class)} ; <{t}storey> {json.dumps(storey)} ; "
    if label is not None:
        text += f"<{vocab.RDFS_LABEL}> {json.dumps(label)} ; "
    return text + f'<{t}box> "{" ".join(repr(v) for v in box)}" .\n'


def observation_turtle(args: argparse.Namespace) -> bytes:
    """The observation document the options describe."""
    t = vocab.TWIN
    if args.turtle:
        return Path(args.turtle).read_bytes()
    if args.box:
        try:
            values = [float(v) for v in args.box.split(",")]
        except ValueError:
            values = []
        if len(values) != 7:
            msg = f"--box takes 7 comma-separated numbers x,y,z,sx,sy,sz,yaw, got {args.box!r}."
            raise ObservationError(msg)
        if not args.ifc_class or not args.storey:
            msg = "--box needs --class IFCCLASS and --storey KEY."
            raise ObservationError(msg)
        iri = args.id or f"urn:twin:{args.robot}:{uuid.uuid4()}"
        return box_turtle(iri, values, ifc_class=args.ifc_class, storey=args.storey).encode()
    marks = (
        (args.remove, "removed", "true"),
        (args.open, "isOpen", "true"),
        (args.close, "isOpen", "false"),
        (args.keepout, "keepout", "true"),
        (args.no_keepout, "keepout", "false"),
    )
    for iri, predicate, value in marks:
        if iri:
            return f"<{iri}> <{t}{predicate}> {value} .\n".encode()
    if args.speed_limit:
        iri, percent = args.speed_limit
        if not percent.isdigit():
            msg = f"--speed-limit takes an IRI and a percent from 0 (no limit) to 100, got {percent!r}."
            raise ObservationError(msg)
        return f"<{iri}> <{t}speedLimit> {int(percent)} .\n".encode()
    msg = (
        "Say what was observed: --box ... | --turtle FILE | --remove IRI | --open IRI | --close IRI | "
        "--keepout IRI | --no-keepout IRI | --speed-limit IRI PERCENT."
    )
    raise ObservationError(msg)


def cmd_observe(args: argparse.Namespace, cfg: Config) -> int:
    payload = observation_turtle(args)
    with open_client(args, cfg) as twin:
        if args.no_ack:
            twin.publish_observation(args.robot, payload)
            time.sleep(0.2)  # let the put leave before the session closes
            print("sent (no ack requested)")
            return 0
        try:
            ack = twin.observe(args.robot, payload)
        except RemoteError as err:
            print(json.dumps({"ok": False, "error": str(err)}))
            return 1
    print(json.dumps(ack))
    return 0


def cmd_storey(args: argparse.Namespace, cfg: Config) -> int:
    """``twin storey --robot NAME [KEY]``: print the robot's storey, after switching it to KEY if given."""
    with open_client(args, cfg) as twin:
        robots = twin.status().get("robots") or {}
        if args.robot not in robots:
            site = twin.keys.prefix
            known = (
                f"the robots configured at {site} ([robots.NAME]) are {', '.join(sorted(robots))}"
                if robots
                else f"the daemon of {site} has no robots configured (no [robots.NAME] table)"
            )
            msg = f"Unknown robot {args.robot!r}: {known}."
            raise StoreySwitchError(msg)
        try:
            storey = twin.robot_storey(args.robot, args.storey)
        except RemoteError as err:
            print(f"twin: error: {err}", file=sys.stderr)
            return 1
    print(storey)
    return 0


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


def _await(seen: threading.Semaphore, count: int | None, timeout_s: float, what: str) -> bool:
    """Wait for ``count`` releases of ``seen`` (forever when None; Ctrl-C ends it); False on timeout."""
    deadline = time.monotonic() + timeout_s
    got = 0
    try:
        while count is None or got < count:
            left = deadline - time.monotonic() if count is not None else 3600.0
            if left <= 0 or not seen.acquire(timeout=left):
                if count is not None:
                    print(f"twin: error: {got} of {count} {what} in {timeout_s} s", file=sys.stderr)
                    return False
                continue
            got += 1
    except KeyboardInterrupt:
        pass
    return True


def cmd_watch_ros(args: argparse.Namespace, cfg: Config) -> int:
    """``twin watch --ros NS``: subscribe exactly as an rmw_zenoh node or the DDS bridge would."""
    from adapters.zenoh.ros_watch import RosMapWatcher, RosSample

    seen = threading.Semaphore(0)

    def on_sample(s: RosSample) -> None:
        seq = f", rmw sequence {s.sequence}" if s.sequence is not None else ""
        size = f"{s.grid.frame.width}x{s.grid.frame.height}"
        print(f"{args.ros}/{args.topic} via {s.kind}{seq}: {size}, {cell_counts(s.grid.data)}", flush=True)
        seen.release()

    prefix = key_prefix(cfg, args.site)  # ROS 2 keys: no site to look for
    with open_client(args, cfg, prefix=prefix) as twin:
        watcher = RosMapWatcher(
            twin.session,
            namespace=args.ros,
            layout=args.layout,
            domain_id=args.domain_id,
            topic=args.topic,
            on_sample=on_sample,
        )
        try:
            with _sigterm_as_interrupt():
                if not _await(seen, args.count, args.timeout, f"samples on {watcher.keys[0]}"):
                    return 1
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
            _label_ros_yaml(files.yaml, f"{args.ros.rstrip('/')}/{args.topic}")
            print(f"wrote {files.yaml}")
    return 0


META = "# building-twin map:"
"""The start of the comment line of a map_server YAML that names the map's storey and skill
(``adapters.ros.map_server``)."""


def _label_ros_yaml(yaml: Path, topic: str) -> None:
    """A ROS map names no storey or skill: its YAML's building-twin comment names the topic instead."""
    lines = yaml.read_text().splitlines(keepends=True)
    lines = [f"# ROS 2 topic {topic} (twin watch --ros)\n" if ln.startswith(META) else ln for ln in lines]
    yaml.write_text("".join(lines))


def cmd_watch(args: argparse.Namespace, cfg: Config) -> int:
    if args.ros:
        return cmd_watch_ros(args, cfg)
    if not args.skill:
        msg = "Give --skill NAME (or --ros NAMESPACE to watch a ROS 2 robot's /map)."
        raise ObservationError(msg)
    with open_client(args, cfg) as twin:
        maps = twin.list_maps()
        skills = sorted({k for _, k in maps})
        storeys = [s for s, k in maps if k == args.skill]
        if not storeys:
            known = ", ".join(skills) or "none"
            msg = f"Unknown skill {args.skill!r}: {twin.keys.prefix} serves maps of the skills {known}."
            raise SkillError(msg)
        if args.storey:
            if args.storey not in storeys:
                msg = (
                    f"Unknown storey {args.storey!r}: {twin.keys.prefix} serves {args.skill} maps of the "
                    f"storeys {', '.join(storeys)}."
                )
                raise SkillError(msg)
            storeys = [args.storey]
        seen = threading.Semaphore(0)
        lock = threading.Lock()

        def on_version(v: MapVersion) -> None:
            with lock:
                print(_describe(v), flush=True)
            seen.release()

        watchers: list[MapWatcher] = [twin.watch(s, args.skill, on_version) for s in storeys]
        try:
            with _sigterm_as_interrupt():
                if not _await(seen, args.count, args.timeout, "map versions"):
                    return 1
        finally:
            for w in watchers:
                w.close()
        if args.out:
            out = Path(args.out)
            for w in watchers:
                if w.latest is not None:
                    files = write_map_files(w.latest.grid, out, stamp_ns=time.time_ns())
                    print(f"wrote {files.yaml}")
    return 0


def add_parsers(sub: Any) -> None:
    common = add_client_args

    sp = sub.add_parser("observe", help="send a robot's observation to the daemon and print the ack")
    common(sp)
    sp.add_argument("--robot", required=True, help="the observing robot's name")
    what = sp.add_mutually_exclusive_group(required=True)
    what.add_argument("--box", metavar="x,y,z,sx,sy,sz,yaw", help="an oriented box (z above the storey)")
    what.add_argument("--turtle", metavar="FILE", help="a Turtle observation document")
    what.add_argument("--remove", metavar="IRI", help="the element is gone")
    what.add_argument("--open", metavar="IRI", help="the door was seen open")
    what.add_argument("--close", metavar="IRI", help="the door was seen closed")
    what.add_argument("--keepout", metavar="IRI", help="mark a keepout zone (needs the 'zones' right)")
    what.add_argument("--no-keepout", metavar="IRI", help="lift a keepout zone")
    what.add_argument(
        "--speed-limit", nargs=2, metavar=("IRI", "PERCENT"), help="mark a speed zone (0 lifts it)"
    )
    sp.add_argument("--id", help="IRI of the boxed element (default: a new urn:twin:<robot>:<uuid>)")
    sp.add_argument("--class", dest="ifc_class", help="IFC class of the boxed element, e.g. IfcFurniture")
    sp.add_argument("--storey", help="storey key of the boxed element (see 'twin stats')")
    sp.add_argument("--no-ack", action="store_true", help="best effort: put, do not wait for an ack")
    sp.set_defaults(func=cmd_observe)

    sp = sub.add_parser("watch", help="subscribe to a skill's maps like a robot; print each version")
    common(sp)
    sp.add_argument("--skill", help="the skill whose maps to watch")
    sp.add_argument("--ros", metavar="NAMESPACE", help="watch <NAMESPACE>/map as a ROS 2 node would instead")
    sp.add_argument(
        "--topic", default="map", help="with --ros: the map topic under the namespace (default map)"
    )
    sp.add_argument("--layout", choices=["rmw_zenoh", "bridge"], default="rmw_zenoh", help="with --ros")
    sp.add_argument("--domain-id", type=int, default=0, help="ROS domain id, with --ros (default 0)")
    sp.add_argument("--storey", help="one storey key (default: every storey)")
    sp.add_argument("--count", type=int, help="stop after this many map versions")
    sp.add_argument("--out", help="write the final maps as map_server files into this directory")
    sp.set_defaults(func=cmd_watch)

    sp = sub.add_parser("status", help="the running daemon's status: revision, elements, maps, robots, ...")
    common(sp)
    sp.add_argument("--json", action="store_true", help="print the daemon's JSON as it is")
    sp.set_defaults(func=cmd_status)

    sp = sub.add_parser("storey", help="print a robot's current storey, or switch it (the lift)")
    common(sp)
    sp.add_argument("--robot", required=True, help="the robot's name ([robots.NAME])")
    sp.add_argument("storey", nargs="?", help="the storey key to switch to (see 'twin stats')")
    sp.set_defaults(func=cmd_storey)


def _status_value(value: Any) -> str:
    if isinstance(value, list) and all(not isinstance(v, dict | list) for v in value):
        return ", ".join(str(v) for v in value) or "none"
    if isinstance(value, dict) and all(not isinstance(v, dict | list) for v in value.values()):
        return ", ".join(f"{k} {v}" for k, v in value.items()) or "none"
    if isinstance(value, dict | list):
        return json.dumps(value)
    return str(value)


def describe_status(status: dict[str, Any]) -> str:
    """The daemon's status as lines: one a key, one a map, one a robot (any other section as JSON)."""
    out: list[str] = []
    maps = status.get("maps")
    for key, value in status.items():
        if key == "maps" and isinstance(maps, list):
            out.append(f"maps ({len(maps)}):")
            out += [
                f"  {m.get('storey')}/{m.get('skill')} version {m.get('version')} "
                f"(revision {m.get('revision')})"
                for m in maps
                if isinstance(m, dict)
            ]
        elif isinstance(value, dict) and value and all(isinstance(v, dict) for v in value.values()):
            out.append(f"{key} ({len(value)}):")  # robots: one line each
            out += [f"  {name}: {_status_value(entry)}" for name, entry in value.items()]
        else:
            out.append(f"{key}: {_status_value(value)}")
    return "\n".join(out)


def cmd_status(args: argparse.Namespace, cfg: Config) -> int:
    """``twin status``: what the daemon answers on ``<prefix>/status``."""
    with open_client(args, cfg) as twin:
        status = twin.status()
    print(json.dumps(status, indent=2) if args.json else describe_status(status))
    return 0
