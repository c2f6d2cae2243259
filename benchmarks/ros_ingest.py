"""Cost of ROS 2 ingestion: robots publishing ``vision_msgs/msg/Detection3DArray`` at a fixed rate,
mostly confirmations, against the daemon process.

The daemon (``twin serve``, on-disk store of the generated lab, no recording) is configured with
``--robots`` robots, each with a ``[robots.NAME.detections]`` table (views and sense times on: the
view cut at the localization map), on one layout. Publisher processes (``--publishers``, default one
per robot) play the robots on loopback: each robot publishes its TF (``map -> base_link``) at
``--tf-rate`` (default twice ``--rate``: the issue's 20 Hz) and, every ``1 / --rate`` s, right after the
TF of its stamp, one array of ``--detections`` tables in ``base_link``, everything its view holds, each
with a tracker id; each robot at its own moment of the period, as robots that run independently send
(``--together``: a publisher's robots all at once, as this benchmark did before 2026-11-29); all but
one table keep their pose (confirmations), the last moves 1.0 m every 2 s (beyond ``certain_move_m``,
into free floor). The robots stand still (``--moving``: each drives 0.4 m ahead and back every 8 s, so
that every array's view is cut from a new pose). Publishers' CPU is not counted.

``--views distinct`` (the default, as the issue that set the targets asks: robots at distinct poses
whose views do not overlap) stands each robot in a room of its own (6 x 4 m, one storey of as many
rooms as robots, written with the sample lab's builder), facing its own tables: no other robot sees
them. ``--views shared`` stands every robot at the same pose in the lab's corridor, all reporting the
same tables (each through its own tracker ids): the worst case for the writer, where every array
resolves through aliases, every robot compares its detector with 24 others (the bias notes) and a
third of the arrays come after another robot's later sighting of the same tables (stale).

Measured over the steady window (after ``--warmup`` s): the daemon process's CPU time (utime + stime)
per array received, its ingest workers' (child processes), the total, the acked rate (accepted +
unchanged acks per second, from the status's ``ros_ingest`` counts), refusals (``overflow`` = an
ingestion queue was full), the ingestion and service queue depths sampled every second (no growth =
keeping up) and the latency from robot0's array that moves the table to the navigation map update's
receipt by a subscriber. The daemon's CPU is split into its main thread (the writer), its native
threads (named by their runtime: Zenoh's ``rx-0``, ``acc-0``, ..., RocksDB's) and the rest (Python's
threads: Zenoh's callbacks, the ingest workers' sender and pool threads); ``threads_ms_per_array``
gives each group of them (Python threads named by ``py-spy dump``, each thread's CPU from ``schedstat``).
``--baseline TREE`` runs the same against the daemon of another code tree.

    python benchmarks/ros_ingest.py --robots 10 --rate 10 --detections 20 --duration 30 --json ros.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
import live  # benchmarks/ is not a package

ROOT = live.ROOT
ROBOT = (15.0, 7.0)  # every robot's base_link in the map: in the lab's corridor (free floor), facing +x
ROOM = (6.0, 4.0)
"""``--views distinct``: each robot's room, inside its walls (m); the robot stands 0.5 m from the room's
west wall, half way across, facing +x: its tables lie 1.0-4.0 m ahead, within 1.0 m of its axis."""
WALL_M = 0.2
MOVE_S = 2.0
"""Every this many seconds (of the wall clock, which every publisher process shares) the last table
moves 1.0 m across the corridor and back (beyond ``[fusion] certain_move_m``, into free floor): a change
among the confirmations, whose navigation map update is timed from robot0's send to the update's
receipt."""
MOVER = (19.0, 6.6, 1.0)  # x, y and the y shift of the table that moves


def rooms(robots: int) -> tuple[int, int]:
    """Columns and rows of the ``--views distinct`` building's rooms."""
    cols = max(1, math.ceil(math.sqrt(robots)))
    return cols, max(1, math.ceil(robots / cols))


def base(robot: int, robots: int, views: str) -> tuple[float, float]:
    """Where robot ``robot`` (of ``robots``) stands (map frame): ``ROBOT`` with shared views, else in its
    own room."""
    if views == "shared":
        return ROBOT
    from twin.samples.lab_plan import BUILDING_OFFSET

    cols, _ = rooms(robots)
    col, row = robot % cols, robot // cols
    return (
        BUILDING_OFFSET[0] + col * (ROOM[0] + WALL_M) + 0.5,
        BUILDING_OFFSET[1] + row * (ROOM[1] + WALL_M) + ROOM[1] / 2,
    )


def write_rooms(path: Path, robots: int) -> None:
    """The ``--views distinct`` building: one storey ("Ground floor") of ``rooms(robots)`` rooms of
    ``ROOM`` in a grid, full-height concrete walls between them, on one slab."""
    from adapters.ifc.sample_lab import write_plans
    from twin.samples.lab_plan import Box, ElementPlan, StoreyPlan

    cols, rows = rooms(robots)
    w, h = cols * (ROOM[0] + WALL_M), rows * (ROOM[1] + WALL_M)
    xs = [c * (ROOM[0] + WALL_M) for c in range(cols + 1)]  # each wall's far side
    ys = [r * (ROOM[1] + WALL_M) for r in range(rows + 1)]
    t = WALL_M
    walls = [
        *(ElementPlan(f"Wall x{i}", Box(x - t, -t, 0, x, h, 2.7), "Concrete") for i, x in enumerate(xs)),
        *(ElementPlan(f"Wall y{i}", Box(-t, y - t, 0, w, y, 2.7), "Concrete") for i, y in enumerate(ys)),
    ]
    outline = ((-WALL_M, -WALL_M), (w, -WALL_M), (w, h), (-WALL_M, h))
    slab = ElementPlan(
        "Ground floor slab", Box(-WALL_M, -WALL_M, -0.2, w, h, 0.0), "Concrete", "IfcSlab",
        predefined_type="FLOOR", outline=outline,
    )  # fmt: skip
    write_plans(path, (StoreyPlan("Ground floor", 0.0, (*walls, slab), ()),))


def views_store(views: str, robots: int, work: Path) -> Path:
    """The store the daemon serves (in ``work``): the lab with shared views, else the building of
    ``rooms(robots)`` rooms (:func:`write_rooms`)."""
    if views == "shared":
        return live.prepare_store("lab", work)
    write_rooms(work / "rooms.ifc", robots)
    return live.import_store(work / "rooms.ifc", work / "store")


def robot_array(stamp_ns: int, per_robot: int, shift: float = 0.0, ahead: float = 0.0) -> bytes:
    """A robot's CDR Detection3DArray in ``base_link``: its ``per_robot`` tables (:func:`tables`, seen from
    ``ROBOT``, or from ``ahead`` m further along x), each with its tracker id, the last one ``shift`` m
    aside (the mover)."""
    from tests.adapters.ros_reports import Det, cdr_detections

    spots = tables(per_robot)
    last = len(spots) - 1
    dets = [
        Det(
            (("table", 0.9),),
            (x - ROBOT[0] - ahead, y - ROBOT[1] + (shift if i == last else 0.0), 0.375),
            (0.2, 0.2, 0.75),
            id=f"t{i}",
        )
        for i, (x, y) in enumerate(spots)
    ]
    return cdr_detections(stamp_ns, "base_link", dets)


DRIVE_M, DRIVE_S = 0.4, 8.0
"""``--moving``: each robot drives ``DRIVE_M`` ahead and back every ``DRIVE_S`` seconds (a smooth swing,
at most 0.16 m/s, at a phase of its own): every array has a view from a new pose."""


def drive(robot: int, stamp_ns: int) -> float:
    """How far ahead of its place robot ``robot`` is at ``stamp_ns`` (``--moving``)."""
    phase = 2 * math.pi * (stamp_ns / 1e9 / DRIVE_S + robot / 7)
    return DRIVE_M * (1.0 - math.cos(phase)) / 2


def tables(per_robot: int) -> list[tuple[float, float]]:
    """``per_robot`` table positions (the last one the mover) in front of the robots, inside their view
    (90 deg, 5 m): every robot reports everything it sees, so its views miss nothing."""
    spots = [(16.0 + 0.6 * (i % 5), 6.4 + 0.4 * (i // 5)) for i in range(max(0, per_robot - 1))]
    return [*spots, MOVER[:2]][:per_robot]


def publisher(
    endpoint: str,
    *,
    robots: int,
    rate: float,
    per_robot: int,
    duration: float,
    layout: str,
    first: int = 0,
    count: int | None = None,
    views: str = "distinct",
    tf_rate: float = 20.0,
    stagger: bool = True,
    moving: bool = False,
) -> int:
    """Publish the TF and detections of robots ``first`` .. ``first + count`` (of ``robots``) for
    ``duration`` seconds: each robot's TF at ``tf_rate`` and its array at ``rate``, the array after
    the TF of its stamp (``stagger``: each robot at its own moment of the period)."""
    import zenoh

    from adapters.ros.interfaces import DETECTION_3D_ARRAY, TF_MESSAGE
    from adapters.ros.rmw_zenoh import RosTopic, attachment
    from adapters.zenoh.session import client_config
    from tests.adapters.ros_reports import Tf, cdr_tf

    with zenoh.open(client_config([endpoint])) as session:
        outs = []
        mine = range(first, robots if count is None else min(robots, first + count))
        for r in mine:
            keys = []
            for name, type_name in (("tf", TF_MESSAGE), ("detections", DETECTION_3D_ARRAY)):
                topic = RosTopic(0, f"/robot{r}", name, type_name)
                key = topic.data_key if layout == "rmw_zenoh" else topic.bridge_key
                keys.append(session.declare_publisher(key, reliability=zenoh.Reliability.RELIABLE))
            outs.append(keys)
        time.sleep(1.0)
        print(json.dumps({"ready": True}), flush=True)
        sent, seq = 0, 0
        gid = bytes(16)
        phase = int(time.time() / MOVE_S)
        per_array = max(1, round(tf_rate / rate))  # TF messages per array (the array's own among them)
        period = 1.0 / (rate * per_array)  # between a robot's TF messages
        # each robot's messages at its own moment of the period (stagger: spread over it, as robots
        # that run independently are; else all of this process's robots at once)
        offsets = [period * k / len(mine) if stagger else 0.0 for k in range(len(mine))]
        start = time.monotonic()
        tick = 0
        while time.monotonic() - start < duration:
            array_tick = tick % per_array == 0
            for k, (r, (tf_pub, det_pub)) in enumerate(zip(mine, outs, strict=True)):
                time.sleep(max(0.0, start + tick * period + offsets[k] - time.monotonic()))
                stamp = time.time_ns()
                seq += 1
                extra = {"attachment": attachment(seq, stamp, gid)} if layout == "rmw_zenoh" else {}
                bx, by = base(r, robots, views)
                ahead = drive(r, stamp) if moving else 0.0
                at = (bx + ahead, by, 0.0)
                tf_pub.put(cdr_tf([Tf("map", "base_link", at, stamp_ns=stamp)]), **extra)
                if not array_tick:
                    continue
                seq += 1
                extra = {"attachment": attachment(seq, stamp, gid)} if layout == "rmw_zenoh" else {}
                now = int(stamp / 1e9 / MOVE_S)
                moves = r == 0 or views == "shared"  # (distinct views: robot 0's table alone)
                array = robot_array(stamp, per_robot, MOVER[2] * (now % 2) if moves else 0.0, ahead)
                if now != phase and r == (mine[0] if views == "shared" else 0):  # the move's first send
                    # (shared views: every robot's table moves, each process's first send; distinct
                    # views: robot 0's alone)
                    phase = now
                    print(json.dumps({"moved": time.time(), "phase": now}), flush=True)
                det_pub.put(array, **extra)
                sent += 1
            tick += 1
            time.sleep(max(0.0, start + tick * period - time.monotonic()))
        print(json.dumps({"sent": sent, "seconds": time.monotonic() - start}), flush=True)
    return 0


def translate_only(per_robot: int, repeat: int = 2000) -> dict[str, float]:
    """In-process cost of translating one array (no daemon): without the fusion terms, and with the
    view (64 rays over a 30 x 30 m structure grid at 0.05 m) and the sense time."""
    import numpy as np

    from adapters.ros.detections import DetectionContext, DetectionSettings, translate_detections
    from adapters.ros.tf import TfBuffer, decode_tf_message
    from tests.adapters.ros_reports import OPTICAL, Det, Tf, cdr_detections, cdr_tf
    from twin.maps.grid import GridFrame, OccupancyGrid

    now = time.time_ns()
    tf = TfBuffer()
    tf.add(decode_tf_message(cdr_tf([Tf("map", "base_link", (15.0, 7.0, 0.0), stamp_ns=now)])), static=False)
    tf.add(decode_tf_message(cdr_tf([Tf("base_link", "cam", (0.2, 0, 1.0), OPTICAL)])), static=True)
    data = np.zeros((600, 600), dtype=np.int8)
    data[::80, :] = 100
    data[:, ::100] = 100
    grid = OccupancyGrid(GridFrame(0.0, 0.0, 0.05, 600, 600), data, "ground-floor", "localization", 0.0)
    upright = (0.5, -0.5, 0.5, 0.5)
    dets = [Det((("table", 0.9),), (0.1 * i - 1, 0.6, 2.0 + 0.1 * i), (0.2, 0.2, 0.75), upright, f"t{i}")
            for i in range(per_robot)]  # fmt: skip
    payload = cdr_detections(now, "cam", dets)
    settings = DetectionSettings(robot="r", classes={"table": "IfcFurniture"})
    out: dict[str, float] = {}
    for label, fusion in (("elements_ms", False), ("with_view_ms", True)):
        ctx = DetectionContext("ground-floor", 0.0, now, tf, grid, fusion)
        t0 = time.perf_counter()
        for _ in range(repeat):
            translate_detections(payload, settings, ctx)
        out[label] = round(1000 * (time.perf_counter() - t0) / repeat, 3)
    return out


def _cpu_s(pid: int, tid: int | None = None) -> float:
    """A process's CPU time (utime + stime), or one of its threads' (``tid``)."""
    path = f"/proc/{pid}/stat" if tid is None else f"/proc/{pid}/task/{tid}/stat"
    fields = Path(path).read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _python_threads(pid: int) -> dict[int, str]:
    """The daemon's Python threads by OS thread id, each named by its group: its Python name
    (``ros-ingest-pool``, ``ros-ingest-send-0``, ...; a numbered suffix dropped) or, for Zenoh's callback
    threads, ``zenoh callbacks`` (their stack holds a callback); empty if ``py-spy`` is not at hand."""
    text = live.py_spy_dump(pid)
    out: dict[int, str] = {}
    for block in re.split(r"\n(?=Thread )", text):
        m = re.match(r'Thread (\d+) \([^)]*\)(?:: "([^"]*)")?', block)
        if m is None:
            continue
        name = m.group(2) or "python, unnamed"
        if "on_sample" in block or name.endswith("(pyo3-closure)"):
            name = "zenoh callbacks"
        out[int(m.group(1))] = re.sub(r"-\d+$", "-N", name) if name.startswith("ros-ingest-send") else name
    return out


def _children_cpu_s(pid: int) -> dict[int, float]:
    """CPU seconds of each live child process of ``pid`` (the ingest workers)."""
    import psutil

    out: dict[int, float] = {}
    for child in psutil.Process(pid).children(recursive=True):
        try:
            t = child.cpu_times()
            out[child.pid] = t.user + t.system
        except psutil.Error:
            continue
    return out


def _status(endpoint: str) -> dict[str, Any]:
    from adapters.zenoh.client import TwinClient

    with TwinClient.connect([endpoint]) as client:
        return client.status()


def run(
    *,
    robots: int,
    rate: float,
    per_robot: int,
    duration: float,
    warmup: float,
    layout: str,
    publishers: int,
    root: Path = ROOT,
    workers: int | None = None,
    extra: str = "",
    views: str = "distinct",
    tf_rate: float = 20.0,
    stagger: bool = True,
    moving: bool = False,
) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        store = views_store(views, robots, work)
        cfg = work / "robots.toml"
        ros = "" if workers is None else f"[ros]\ningest_workers = {workers}\n"
        cfg.write_text(
            extra
            + ros
            + "".join(
                f'[robots.robot{r}]\nnamespace = "/robot{r}"\nstorey = "ground-floor"\nros = ["{layout}"]\n'
                f'[robots.robot{r}.detections]\nclasses = {{ table = "IfcFurniture" }}\n'
                f"max_detections = {max(per_robot, 1)}\n"
                for r in range(robots)
            )
        )
        port = live._free_port()
        endpoint = f"tcp/127.0.0.1:{port}"
        daemon = _serve(cfg, store, endpoint, root)
        drain = threading.Thread(target=lambda: [None for _ in daemon.stdout or []], daemon=True)
        drain.start()
        per = -(-robots // max(1, publishers))
        args = [endpoint, str(robots), str(rate), str(per_robot), str(duration), layout, views, str(tf_rate)]
        args += ["1" if stagger else "0", "1" if moving else "0"]
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        pubs = [
            subprocess.Popen(
                [sys.executable, __file__, "--child", *args, str(first), str(per)],
                stdout=subprocess.PIPE,
                text=True,
                cwd=ROOT,
                env=env,
            )
            for first in range(0, robots, per)
        ]
        for pub in pubs:
            assert pub.stdout is not None
            json.loads(pub.stdout.readline())
        moved_at: dict[int, float] = {}  # phase -> the first send of that move by any publisher
        lines: list[dict[str, Any]] = []

        def read_publisher(pub: subprocess.Popen[str]) -> None:
            assert pub.stdout is not None
            for line in pub.stdout:
                item = json.loads(line)
                if "moved" in item:
                    phase = int(item["phase"])
                    moved_at[phase] = min(moved_at.get(phase, item["moved"]), item["moved"])
                else:
                    lines.append(item)

        readers = [threading.Thread(target=read_publisher, args=(p,), daemon=True) for p in pubs]
        for reader in readers:
            reader.start()
        import zenoh

        from adapters.zenoh.session import client_config

        updates: list[float] = []
        watcher = zenoh.open(client_config([endpoint]))
        watch = watcher.declare_subscriber(
            "twin/*/map_updates/ground-floor/navigation", lambda _: updates.append(time.time())
        )
        t_start, wall_start = time.monotonic(), time.time()
        time.sleep(warmup)
        s0, c0, k0, w0 = _status(endpoint), _cpu_s(daemon.pid), _children_cpu_s(daemon.pid), time.monotonic()
        m0 = _cpu_s(daemon.pid, daemon.pid)  # the main thread: the writer (`TwinService.serve_forever`)
        t0 = live.thread_cpu(daemon.pid)
        depths: list[tuple[int, int]] = []
        while time.monotonic() - t_start < duration - 0.5:
            time.sleep(1.0)
            s = _status(endpoint)
            depths.append((int(s["ros_ingest"]["queue_depth"]), int(s["queue_depth"])))
        s1, c1, k1, w1 = _status(endpoint), _cpu_s(daemon.pid), _children_cpu_s(daemon.pid), time.monotonic()
        m1 = _cpu_s(daemon.pid, daemon.pid)
        t1 = live.thread_cpu(daemon.pid)
        named = _python_threads(daemon.pid)
        for pub in pubs:
            pub.wait(timeout=30)
        for reader in readers:
            reader.join(timeout=10)
        sent = {"sent": sum(int(x.get("sent", 0)) for x in lines)}
        watch.undeclare()
        watcher.close()
        time.sleep(1.0)
        final = _status(endpoint)
        daemon.terminate()
        exit_code = daemon.wait(timeout=30)

    def total(s: dict[str, Any], key: str) -> int:
        if key in ("arrays", "tf"):
            kind = "detections" if key == "arrays" else key
            return sum(int(c["messages"].get(kind, 0)) for c in s["ros_ingest"]["counts"].values())
        return sum(int(c[key]) for c in s["ros_ingest"]["counts"].values())

    window = w1 - w0
    received = total(s1, "arrays") - total(s0, "arrays")
    acked = (total(s1, "accepted") + total(s1, "unchanged")) - (
        total(s0, "accepted") + total(s0, "unchanged")
    )
    refused: dict[str, int] = {}
    for c in final["ros_ingest"]["counts"].values():
        for cause, n in c["refused"].items():
            refused[cause] = refused.get(cause, 0) + int(n)
    workers_s = sum(k1[p] - k0.get(p, 0.0) for p in k1)
    main_name = t1.get(daemon.pid, ("", 0.0))[0]
    native_s = sum(c - t0.get(t, (n, 0.0))[1] for t, (n, c) in t1.items() if n != main_name)
    by_thread: dict[str, float] = {}  # the daemon's threads but the writer, grouped by name
    for t, (n, c) in t1.items():
        if t == daemon.pid:
            continue
        group = "native " + re.sub(r"-?\d+$", "", n) if n != main_name else named.get(t, "python, unnamed")
        by_thread[group] = by_thread.get(group, 0.0) + c - t0.get(t, (n, 0.0))[1]
    counts = list(final["ros_ingest"]["counts"].values())
    latencies = []
    every: list[tuple[float, float]] = []  # (s after the subscription, latency ms) of every move
    moves = sorted(moved_at.values())
    for t in moves:
        after = [u for u in updates if u >= t]
        if after:
            every.append((round(t - wall_start, 2), round(1000 * (after[0] - t), 1)))
            if t >= wall_start + warmup:  # in the steady window: a move made while the tables were
                latencies.append(1000 * (after[0] - t))  # still being created is timed by the next one
    return {
        "layout": layout,
        "views": views,
        "robots": robots,
        "rate_hz": rate,
        "tf_rate_hz": tf_rate,
        "staggered": stagger,
        "moving": moving,
        "detections": per_robot,
        "window_s": round(window, 2),
        "arrays_per_s_offered": round(robots * rate, 1),
        "arrays_received_per_s": round(received / window, 1),
        "tf_received_per_s": round((total(s1, "tf") - total(s0, "tf")) / window, 1),
        "acked_per_s": round(acked / window, 1),
        "cpu_ms_per_array": round(1000 * (c1 - c0) / max(received, 1), 3),
        "writer_ms_per_array": round(1000 * (m1 - m0) / max(received, 1), 3),
        "daemon_threads_ms_per_array": round(1000 * (c1 - c0 - (m1 - m0)) / max(received, 1), 3),
        "daemon_native_threads_ms_per_array": round(1000 * native_s / max(received, 1), 3),
        "threads_ms_per_array": {
            k: round(1000 * v / max(received, 1), 3)
            for k, v in sorted(by_thread.items(), key=lambda kv: -kv[1])
            if 1000 * v / max(received, 1) >= 0.0005
        },
        "workers_ms_per_array": round(1000 * workers_s / max(received, 1), 3),
        "total_ms_per_array": round(1000 * (c1 - c0 + workers_s) / max(received, 1), 3),
        "daemon_cpu_pct": round(100 * (c1 - c0) / window, 1),
        "workers_cpu_pct": round(100 * workers_s / window, 1),
        "publishers": len(pubs),
        "accepted_total": total(final, "accepted"),
        "unchanged_total": total(final, "unchanged"),
        "refused": refused,
        "sent_total": sent["sent"],
        "arrays_received_total": total(final, "arrays"),
        "waited_for_tf": sum(int(c["waited_for_tf"]) for c in counts),
        "overflow": sum(int(c["refused"].get("overflow", 0)) for c in counts),
        "outcomes_per_bunch": _per_bunch(s0, s1),
        "queue_depth_max": max((d[0] for d in depths), default=0),
        "service_queue_max": max((d[1] for d in depths), default=0),
        "queue_depth_last": depths[-1] if depths else None,
        "revision": final["revision"],
        "daemon_exit": exit_code,
        "moves": len(latencies),
        "move_update_ms_p50": round(float(live._pct(latencies, 50)), 1),
        "move_update_ms_p99": round(float(live._pct(latencies, 99)), 1),
        "move_update_ms_max": round(max(latencies, default=float("nan")), 1),
        "move_update_ms_every": every,
        "fusion": final.get("fusion", {}),
    }


def _per_bunch(s0: dict[str, Any], s1: dict[str, Any]) -> float | None:
    """The workers' outcomes per batch delivered to the writer in the window (None: a tree without the
    counts, or no workers)."""
    a, b = s0["ros_ingest"], s1["ros_ingest"]
    if "worker_bunches" not in b:
        return None
    key = "worker_deliveries" if "worker_deliveries" in b else "worker_bunches"
    bunches = b[key] - a[key]
    return round((b["worker_outcomes"] - a["worker_outcomes"]) / max(bunches, 1), 2)


def _serve(cfg: Path, store: Path, endpoint: str, root: Path = ROOT) -> subprocess.Popen[str]:
    """``twin serve`` of the code in ``root`` (another tree: a baseline of an earlier commit)."""
    path = os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")])
    daemon = subprocess.Popen(
        live._twin("--config", str(cfg), "serve", "--store", str(store), "--listen", endpoint, "--no-record"),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=root,
        env={**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONPATH": path},
    )  # fmt: skip
    assert daemon.stdout is not None
    line = ""
    while "serving site" not in line:
        line = daemon.stdout.readline()
        if not line:
            raise RuntimeError(f"the daemon did not start: exit code {daemon.wait()}")
    return daemon


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        endpoint, robots, rate, per_robot, duration, layout, views, tf_rate, stagger, moving, first, count = (
            sys.argv[2:]
        )
        return publisher(
            endpoint, robots=int(robots), rate=float(rate), per_robot=int(per_robot),
            duration=float(duration), layout=layout, first=int(first), count=int(count), views=views,
            tf_rate=float(tf_rate), stagger=stagger == "1", moving=moving == "1",
        )  # fmt: skip
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--robots", type=int, default=10)
    p.add_argument("--rate", type=float, default=10.0)
    p.add_argument("--detections", type=int, default=20)
    p.add_argument(
        "--tf-rate",
        type=float,
        default=None,
        help="each robot's TF messages a second (default: twice --rate, the issue's 20 Hz for 10 Hz arrays)",
    )
    p.add_argument(
        "--moving",
        action="store_true",
        help="each robot drives 0.4 m ahead and back every 8 s (every view from a new pose; default: still)",
    )
    p.add_argument(
        "--together",
        action="store_true",
        help="a publisher's robots send at the same instant (default: each at its own moment of the "
        "period, as robots that run independently)",
    )
    p.add_argument("--duration", type=float, default=30.0)
    p.add_argument("--warmup", type=float, default=8.0)
    p.add_argument("--layout", choices=["bridge", "rmw_zenoh"], default="rmw_zenoh")
    p.add_argument("--json", type=Path)
    p.add_argument(
        "--publishers",
        type=int,
        default=0,
        help="publisher processes, the robots shared among them (default: one per robot)",
    )
    p.add_argument("--workers", type=int, default=None, help="[ros] ingest_workers (default: the daemon's)")
    p.add_argument(
        "--baseline",
        metavar="TREE",
        type=Path,
        help="also run the daemon of this code tree (e.g. `git archive cd19a56 | tar -x -C TREE`)",
    )
    p.add_argument(
        "--views",
        choices=["distinct", "shared"],
        default="distinct",
        help="distinct: each robot in a room of its own, its own tables (the issue's setup); shared: "
        "every robot at one pose, all reporting the same tables (the writer's worst case)",
    )
    p.add_argument(
        "--extra",
        default="",
        metavar="TOML",
        help="TOML put before the robots in this tree's configuration (not the baseline's), "
        "e.g. '[serve]\\nbatch_wait_ms = 10' (the baseline then runs the same tree without it)",
    )
    p.add_argument("--translate-only", action="store_true", help="time the translation in-process only")
    a = p.parse_args()
    if a.translate_only:
        print(json.dumps(translate_only(a.detections), indent=1))
        return 0
    common = {
        "robots": a.robots, "rate": a.rate, "per_robot": a.detections, "duration": a.duration,
        "warmup": a.warmup, "layout": a.layout, "publishers": a.publishers or a.robots, "views": a.views,
        "tf_rate": a.tf_rate if a.tf_rate is not None else 2 * a.rate, "stagger": not a.together,
        "moving": a.moving,
    }  # fmt: skip
    extra = a.extra.replace("\\n", "\n") + "\n"
    result: dict[str, Any] = {"this": run(**common, workers=a.workers, extra=extra)}
    if a.baseline is not None:
        result["baseline"] = run(**common, root=a.baseline.resolve())
    print(json.dumps(result, indent=1))
    if a.json:
        a.json.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
