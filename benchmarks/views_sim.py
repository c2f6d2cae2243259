"""Views that saw it, against ground truth: scripted scenes where views used to remove real objects, for
two kinds of views, each against its own daemon process.

The lab's ground floor holds a storage room of 20 boxes (0.5 x 0.5 x 1.2 m) in five rows of four
(Room B), a 2.4 m bench along Room A's west wall with a person (not in the twin) walking back and
forth before it, a box under a pitched camera's frame (its blind zone) and two loose boxes. Two robots
look at them from viewpoints they cycle through (4 s each): a level camera 1 m up in the storage room,
and a camera 1.2 m up pitched 30 degrees down (45 degrees vertical field of view) in Room A. A robot
detects an object when at least 5 of 9 points over its footprint, at mid-height, lie in its camera's
frustum (the band 0.1 to 0.5 m above the floor in frame, within range) with nothing in between
(structure, other objects, the person), and then misses it with ``--p-miss``; detections carry a
little noise. Over the run, two front-row boxes and the two loose boxes are removed.

Two sets of views:

- ``zenoh``: a Zenoh robot that does not know the twin's furniture: its view is its camera's floor
  cut by the structure only (the localization map), with ``twin:origin``, and the person's shadow as a
  ``twin:hole`` (it detects people but does not report them);
- ``ros``: the ROS adapter's translation of each ``vision_msgs/msg/Detection3DArray`` (the person in
  it as an unmapped class ``person``), in process, its document sent over Zenoh;
- ``flat`` (for comparison): the view the ROS adapter sent before, a flat wedge of the horizontal
  field of view cut by the structure, without an origin.

Every second: the twin's navigation map against the true world's (a twin of its own with fusion off):
false-free cells (free in the twin where an object stands); at the end, removals' precision and
recall (removed within 10 s of the first view that would have seen the object), and false removals
(a seeded element gone while its object stands).

    python benchmarks/views_sim.py --duration 60 --json views.json
"""

from __future__ import annotations

import argparse
import json
import math
import random
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # tests.adapters.ros_reports: the ROS messages
import fleet_sim
import live  # benchmarks/ is not a package

STOREY, NAV, LOC = "ground-floor", "lab-navigation", "lab-localization"
ROWS_X = (19.6, 20.1, 20.6, 21.1, 21.6)
COLUMNS_Y = (6.25, 6.75, 7.25, 7.75)
BAND = (0.1, 0.5)
RANGE_M = 5.0
PERSON = (0.5, 0.4, 1.8)
PERSON_PATH = ((11.2, 5.6), (11.2, 7.3))  # walked back and forth at 0.5 m/s
DWELL_S = 4.0
RATE_HZ = 5.0
RECALL_S = 10.0


@dataclass(frozen=True)
class Rig:
    """A robot's camera: height, pitch (down), fields of view, and its viewpoints (x, y, yaw)."""

    name: str
    height: float
    pitch: float
    hfov: float
    vfov: float | None
    viewpoints: tuple[tuple[float, float, float], ...]


RIGS = (
    Rig("store", 1.0, 0.0, math.radians(87), None,
        ((18.4, 6.4, 0.25), (18.4, 7.0, 0.0), (18.4, 7.6, -0.25))),
    Rig("pitched", 1.2, math.radians(30), math.radians(70), math.radians(45),
        ((13.6, 7.0, math.pi), (13.5, 5.8, 2.7), (13.4, 8.4, -2.6))),
)  # fmt: skip


def scene() -> dict[int, fleet_sim.Obj]:
    objs: dict[int, fleet_sim.Obj] = {}
    for r, x in enumerate(ROWS_X):
        for c, y in enumerate(COLUMNS_Y):
            objs[4 * r + c] = fleet_sim.Obj(4 * r + c, x, y, 0.0, 0.5, 0.5, 1.2)
    objs[20] = fleet_sim.Obj(20, 10.5, 7.0, math.pi / 2, 2.4, 0.5, 0.5)  # the bench
    objs[21] = fleet_sim.Obj(21, 12.6, 7.3, 0.3, 0.4, 0.4, 0.4)  # loose boxes
    objs[22] = fleet_sim.Obj(22, 12.4, 6.6, 0.0, 0.45, 0.4, 0.4)
    objs[23] = fleet_sim.Obj(23, 13.05, 7.0, 0.0, 0.3, 0.3, 0.3)  # under the pitched camera's frame
    return objs


REMOVALS = ((0.25, 1), (0.35, 21), (0.45, 2), (0.55, 22))  # (fraction of the run, object)


def camera_pose(rig: Rig, x: float, y: float, yaw: float) -> np.ndarray:
    """``map_from_camera`` (x forward, y left, z up), pitched down by ``rig.pitch``."""
    cy, sy = math.cos(yaw), math.sin(yaw)
    cp, sp = math.cos(rig.pitch), math.sin(rig.pitch)
    yaw_m = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    pitch_m = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])  # +pitch about y: x tilts down
    m = np.eye(4)
    m[:3, :3] = yaw_m @ pitch_m
    m[:3, 3] = (x, y, rig.height)
    return m


@dataclass
class Truth:
    """The true world: objects present, the person, and the structure that hides things."""

    objs: dict[int, fleet_sim.Obj]
    blocked: np.ndarray
    origin: tuple[float, float]
    res: float
    person_xy: tuple[float, float] = PERSON_PATH[0]
    removed_at: dict[int, float] = field(default_factory=dict)

    def structure_clear(self, a: tuple[float, float], points: np.ndarray) -> np.ndarray:
        """Which segments from ``a`` to each point cross no blocked cell."""
        n = max(2, int(np.hypot(*(points - a).T).max() / (self.res / 2)) + 1)
        t = np.linspace(0.0, 1.0, n)[None, :]
        xs = a[0] + (points[:, 0:1] - a[0]) * t
        ys = a[1] + (points[:, 1:2] - a[1]) * t
        rows = ((ys - self.origin[1]) / self.res).astype(int)
        cols = ((xs - self.origin[0]) / self.res).astype(int)
        h, w = self.blocked.shape
        inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        hit = ~inside | self.blocked[np.clip(rows, 0, h - 1), np.clip(cols, 0, w - 1)]
        return np.asarray(~hit.any(axis=1))

    def solids(self) -> tuple[Any, dict[int, int]]:
        """The upright boxes that hide things (the objects standing and the person), and each object's row."""
        from twin.fusion.footprints import box_pose
        from twin.fusion.visibility import Solids

        standing = [o for o in self.objs.values() if o.present]
        poses = [box_pose(o.x, o.y, o.sz / 2, o.sx, o.sy, o.sz, yaw=o.yaw) for o in standing]
        px, py = self.person_xy
        poses.append(box_pose(px, py, PERSON[2] / 2, PERSON[0], PERSON[1], PERSON[2], yaw=0.0))
        rows = {o.key: i for i, o in enumerate(standing)}
        rows[-1] = len(standing)  # the person
        return Solids.of(poses), rows

    def seen_points(self, cam: Any, o: fleet_sim.Obj) -> int:
        """How many of 9 points over ``o``'s footprint, at its mid-height, the camera sees."""
        from twin.fusion.visibility import line_of_sight

        solids, rows = self.solids()
        u = np.array([-1 / 3, 0.0, 1 / 3])
        c, s = math.cos(o.yaw), math.sin(o.yaw)
        lx, ly = (a.ravel() for a in np.meshgrid(u * o.sx, u * o.sy))
        pts = np.stack([o.x + c * lx - s * ly, o.y + s * lx + c * ly], axis=1)  # (9, 2)
        d = np.hypot(pts[:, 0] - cam.position[0], pts[:, 1] - cam.position[1])
        top = min(BAND[1], o.sz)
        ok = cam.sees(pts[:, 0], pts[:, 1], BAND[0]) & cam.sees(pts[:, 0], pts[:, 1], top)
        ok &= (d <= RANGE_M) & (d >= cam.near_m)
        ok &= self.structure_clear(cam.position[:2], pts)
        feet = np.repeat(pts[:, None, :], 4, axis=1)
        own = np.full(9, rows.get(o.key, -1))
        ok &= line_of_sight(feet, np.full(9, o.sz / 2), cam.position, solids, own=own)
        return int(ok.sum())

    def person(self) -> fleet_sim.Obj:
        return fleet_sim.Obj(-1, *self.person_xy, 0.0, *PERSON)


def run_set(kind: str, args: argparse.Namespace) -> dict[str, Any]:
    from adapters.ros.view import Camera
    from adapters.zenoh.client import TwinClient
    from twin.maps.grid import OCCUPIED, OccupancyGrid

    rng = random.Random(args.seed)
    work = Path(tempfile.mkdtemp(prefix="views-"))
    store = live.prepare_store("lab", work)
    oracle = fleet_sim.oracle_service(store, work)
    nav = oracle.live_maps.skill_maps[(STOREY, NAV)]
    loc = oracle.live_maps.skill_maps[(STOREY, LOC)]
    f = nav.plan.frame
    grid = OccupancyGrid(loc.plan.frame, loc.data.copy(), STOREY, LOC, 0.0)
    truth = Truth(scene(), nav.data == OCCUPIED, (f.origin_x, f.origin_y), f.resolution_m)
    seed = "".join(
        f'<urn:seed:{o.key}> twin:ifcClass "IfcFurniture" ; twin:storey "{STOREY}" ; '
        f'twin:box "{o.x} {o.y} {o.sz / 2} {o.sx} {o.sy} {o.sz} {o.yaw}" .\n'
        for o in truth.objs.values()
    )
    for o in truth.objs.values():
        fleet_sim.apply_truth(oracle, fleet_sim.truth_box(o, STOREY, 0.0))
    endpoint = f"tcp/127.0.0.1:{live._free_port()}"
    daemon, line = live.serve("--store", str(store), "--listen", endpoint, "--no-record")
    prefix = "twin/" + line.split("site '", 1)[1].split("'", 1)[0]
    samples: list[dict[str, Any]] = []
    first_view: dict[int, float] = {}
    gone_at: dict[int, float] = {}
    false_removed: set[int] = set()
    observations = 0
    try:
        with TwinClient.connect([endpoint], prefix=prefix, timeout_s=30.0) as client:
            assert client.observe("seeder", fleet_sim.PREFIX + seed)["ok"]
            cpu0 = fleet_sim.cpu_seconds(daemon.pid)
            t0 = time.time()
            next_sample = t0 + 1.0
            tick = 0
            script = [(t0 + frac * args.duration, key) for frac, key in REMOVALS]
            while time.time() - t0 < args.duration:
                now = time.time()
                for at, key in script:
                    if now >= at and truth.objs[key].present:
                        truth.objs[key].present = False
                        truth.removed_at[key] = now
                        fleet_sim.apply_truth(
                            oracle, f"{fleet_sim.PREFIX}<urn:truth:{key}> twin:removed true .".encode()
                        )
                (ax, ay), (bx, by) = PERSON_PATH
                leg = math.dist(PERSON_PATH[0], PERSON_PATH[1])
                s = (0.5 * (now - t0)) % (2 * leg)
                s = s if s <= leg else 2 * leg - s
                truth.person_xy = (ax + (bx - ax) * s / leg, ay + (by - ay) * s / leg)
                for rig in RIGS:
                    x, y, yaw = rig.viewpoints[int((now - t0) / DWELL_S) % len(rig.viewpoints)]
                    pose = camera_pose(rig, x, y, yaw)
                    cam = Camera.from_pose(pose, optical=False, hfov_rad=rig.hfov, vfov_rad=rig.vfov,
                                           range_m=RANGE_M)  # fmt: skip
                    present = [k for k, o in truth.objs.items() if o.present]
                    seen = {k: truth.seen_points(cam, truth.objs[k]) >= 5 for k in present}
                    person_seen = truth.seen_points(cam, truth.person()) >= 1
                    for key in [k for k in truth.removed_at if k not in first_view]:
                        truth.objs[key].present = True  # would it have been seen, were it there?
                        if truth.seen_points(cam, truth.objs[key]) >= 5:
                            first_view[key] = now
                        truth.objs[key].present = False
                    dets = [k for k in present if seen[k] and rng.random() >= args.p_miss]
                    stamp = time.time_ns()
                    boxes = []
                    for k in dets:
                        o = truth.objs[k]
                        dx, dy, dyaw = (rng.gauss(0, 0.02) for _ in range(3))
                        noisy = (o.x + dx, o.y + dy, o.sz / 2, o.sx, o.sy, o.sz, o.yaw + dyaw)
                        boxes.append((f"urn:sim:{rig.name}:trk-{k}", noisy))
                    person = truth.person_xy if person_seen else None
                    doc = _document(kind, rig, cam, pose, boxes, person, grid, stamp)
                    if doc is not None:
                        client.observe(rig.name, doc)
                        observations += 1
                if now >= next_sample:
                    next_sample += 1.0
                    samples.append(_sample(client, oracle, truth, t0, gone_at, false_removed))
                tick += 1
                time.sleep(max(0.0, t0 + tick / RATE_HZ - time.time()))
            cpu = fleet_sim.cpu_seconds(daemon.pid) - cpu0
            time.sleep(1.0)
            samples.append(_sample(client, oracle, truth, t0, gone_at, false_removed))
    finally:
        daemon.terminate()
        daemon.wait(timeout=30)
        oracle.store.close()
        shutil.rmtree(work, ignore_errors=True)
    viewed = [k for k in truth.removed_at if k in first_view]
    hits = [k for k in viewed if k in gone_at and gone_at[k] - first_view[k] <= RECALL_S]
    return {
        "set": kind,
        "duration_s": args.duration,
        "observations": observations,
        "false_free_cells_max": max(s["false_free_cells"] for s in samples),
        "false_free_samples": sum(s["false_free_cells"] > 0 for s in samples),
        "samples": len(samples),
        "removals": len(truth.removed_at),
        "removals_viewed": len(viewed),
        "removal_recall_10s": len(hits) / len(viewed) if viewed else float("nan"),
        "removal_precision": len(hits) / (len(hits) + len(false_removed))
        if hits or false_removed
        else float("nan"),
        "false_removals": sorted(false_removed),
        "removal_s_after_first_view": {k: round(gone_at[k] - first_view[k], 2) for k in hits},
        "daemon_cpu_ms_per_observation": round(1e3 * cpu / max(1, observations), 2),
        "series": samples,
    }


Box = tuple[float, float, float, float, float, float, float]


def _document(  # noqa: PLR0917
    kind: str,
    rig: Rig,
    cam: Any,
    pose: np.ndarray,
    boxes: list[tuple[str, Box]],
    person: tuple[float, float] | None,
    grid: Any,
    stamp: int,
) -> bytes | None:
    """One observation of what ``rig`` saw, as the set ``kind`` writes it (see the module's docstring)."""
    from adapters.ros.detections import DetectionContext, DetectionSettings, translate_detections
    from adapters.ros.observation_doc import BoxReport, ViewReport, observation_turtle
    from adapters.ros.tf import TfBuffer, decode_tf_message
    from adapters.ros.view import camera_view, visibility_polygon
    from tests.adapters.ros_reports import Det, Tf, cdr_detections, cdr_tf

    if kind == "ros":
        tf = TfBuffer()
        t = Tf(
            "map",
            "camera_link",
            (float(pose[0, 3]), float(pose[1, 3]), float(pose[2, 3])),
            _quaternion(pose[:3, :3]),
            stamp,
        )
        tf.add(decode_tf_message(cdr_tf([t])), static=False)
        arr = [
            Det((("box", 0.9),), b[:3], b[3:6], _yaw_q(b[6]), id=iri.rsplit(":", 1)[1]) for iri, b in boxes
        ]
        if person is not None:
            arr.append(Det((("person", 0.9),), (person[0], person[1], PERSON[2] / 2), PERSON))
        settings = DetectionSettings(
            robot=rig.name, classes={"box": "IfcFurniture"}, fov_rad=rig.hfov, vfov_rad=rig.vfov,
            range_m=RANGE_M, band_m=BAND, sensor_frame="camera_link",
        )  # fmt: skip
        ctx = DetectionContext(STOREY, 0.0, stamp, tf, grid, True, True)
        return translate_detections(cdr_detections(stamp, "map", arr), settings, ctx).document
    reports = [BoxReport(iri, "IfcFurniture", STOREY, b) for iri, b in boxes]
    if kind == "flat":  # the view as the ROS adapter built it before: a flat wedge cut by the structure
        heading = math.atan2(float(pose[1, 0]), float(pose[0, 0]))
        wedge = visibility_polygon(
            grid,
            (float(pose[0, 3]), float(pose[1, 3])),
            heading_rad=heading,
            fov_rad=rig.hfov,
            range_m=RANGE_M,
        )
        view = ViewReport(STOREY, (wedge,), ("IfcFurniture",)) if wedge else None
        return observation_turtle(boxes=reports, view=view, sense_ns=stamp)
    holes = _shadow_holes(cam, person) if person is not None else ()
    floor = camera_view(grid, cam, band_m=BAND)
    view = (
        ViewReport(STOREY, floor.polygons, ("IfcFurniture",), floor.holes + holes, origin=cam.position)
        if floor is not None
        else None
    )
    return observation_turtle(boxes=reports, view=view, sense_ns=stamp)


def _shadow_holes(cam: Any, person: tuple[float, float]) -> tuple[tuple[tuple[float, float], ...], ...]:
    """The person's shadow as a hole: the wedge behind its footprint, out to the range."""
    px, py = person
    ox, oy = cam.position[0], cam.position[1]
    hx, hy = PERSON[0] / 2 + 0.05, PERSON[1] / 2 + 0.05
    corners = [(px - hx, py - hy), (px + hx, py - hy), (px + hx, py + hy), (px - hx, py + hy)]
    angles = [math.atan2(cy - oy, cx - ox) for cx, cy in corners]
    centre = math.atan2(py - oy, px - ox)
    rel = [math.remainder(a - centre, 2 * math.pi) for a in angles]
    lo, hi = min(rel) + centre, max(rel) + centre
    near = min(math.dist((ox, oy), c) for c in corners)
    far = RANGE_M / math.cos(min(abs(hi - lo) / 2, 1.2)) + 0.5
    ring = [(ox + near * math.cos(a), oy + near * math.sin(a)) for a in (lo, hi)]
    ring += [(ox + far * math.cos(a), oy + far * math.sin(a)) for a in np.linspace(hi, lo, 5)]
    return (tuple(ring),)


def _quaternion(r: np.ndarray) -> tuple[float, float, float, float]:
    w = math.sqrt(max(0.0, 1 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + r[0, 0] - r[1, 1] - r[2, 2])) / 2, r[2, 1] - r[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1 - r[0, 0] + r[1, 1] - r[2, 2])) / 2, r[0, 2] - r[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1 - r[0, 0] - r[1, 1] + r[2, 2])) / 2, r[1, 0] - r[0, 1])
    return (x, y, z, w)


def _yaw_q(yaw: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def _sample(  # noqa: PLR0917
    client: Any, oracle: Any, truth: Truth, t0: float, gone_at: dict[int, float], false_removed: set[int]
) -> dict[str, Any]:
    now = time.time()
    elements = fleet_sim.twin_elements(client, STOREY)
    for k, o in truth.objs.items():
        if f"urn:seed:{k}" not in elements:
            if o.present:
                false_removed.add(k)
            else:
                gone_at.setdefault(k, now)
    grid, _, _ = client.get_map(STOREY, NAV)
    true_map = oracle.live_maps.skill_maps[(STOREY, NAV)].data
    false_free = int(((true_map == 100) & (grid.data == 0)).sum())
    return {"t": round(now - t0, 1), "elements": len(elements), "false_free_cells": false_free}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--duration", type=float, default=60.0)
    p.add_argument(
        "--set",
        choices=["zenoh", "ros", "flat", "both"],
        default="both",
        help="both: zenoh and ros; flat: the flat wedge the ROS adapter sent before (no origin)",
    )
    p.add_argument("--p-miss", type=float, default=0.05)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--json", type=Path)
    a = p.parse_args()
    results = [run_set(k, a) for k in (("zenoh", "ros") if a.set == "both" else (a.set,))]
    brief = [{k: v for k, v in r.items() if k != "series"} for r in results]
    print(json.dumps(brief, indent=1))
    if a.json:
        a.json.write_text(json.dumps(results, indent=1))
    ok = all(
        r["false_free_cells_max"] == 0 and not r["false_removals"] for r in results if r["set"] != "flat"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
