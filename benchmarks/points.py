"""Points-map benchmark (issue 32): the full cloud of each storey, one element's change, memory.

Measures, for a points skill with the shipped localization skill's selection (no glass, no furniture,
no openings) at ``--resolution`` (default 0.1 m):

- the full cloud of every storey from the triangles (:func:`twin.maps.points.build_points`): wall and CPU
  seconds, points;
- the live maps (:class:`twin.live.live_points.LivePoints`, every storey): build time and the RSS they
  add; then single-element changes on the busiest storey (walls, doors, slabs moved by 5 cm, doors
  opened, then closed again), each through :meth:`twin.live.live_maps.LiveMaps.redraw` (the live
  scene's bookkeeping and the points maps; no 2D map is kept here): p50 / p90 / p99 / max milliseconds
  (wall; p50 / p90 CPU), and the moves over 10 ms of CPU with the moved element's IFC class, voxels
  and triangles; and that the changed clouds still equal a full rebuild voxel for voxel.

Usage::

    python benchmarks/points.py --store STORE_DIR [--resolution 0.1] [--changes 40] [--json OUT.json]
    python benchmarks/points.py --model PATH.ifc        # imports into a temporary store first
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from twin.graph.rdf import literal_value  # noqa: E402
from twin.graph.store import EmbeddedStore  # noqa: E402
from twin.graph.vocab import TWIN_IFC_CLASS  # noqa: E402
from twin.live.live_maps import LiveMaps  # noqa: E402
from twin.maps.points import build_points, plan_points  # noqa: E402
from twin.maps.scene import load_scene  # noqa: E402
from twin.records import GeometryChange  # noqa: E402
from twin.selection.skill_selection import selection_query  # noqa: E402
from twin.selection.skills import parse_skill  # noqa: E402

LIDAR = {
    "kind": "points",
    "exclude_types": ["IfcOpeningElement", "IfcFurnishingElement"],
    "exclude_materials": ["glass"],
}


def rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def run(store_dir: Path, resolution: float, changes: int, seed: int) -> dict[str, Any]:
    store = EmbeddedStore.open(store_dir, read_only=True)
    t = time.perf_counter()
    scene = load_scene(store)
    out: dict[str, Any] = {"triangles": len(scene.elements.triangles), "load_s": time.perf_counter() - t}
    skill = parse_skill("lidar3d", {**LIDAR, "resolution_m": resolution})
    iris = [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]
    storeys = []
    for s in scene.storeys:
        w, c = time.perf_counter(), time.process_time()
        plan = plan_points(scene, skill, s.key, iris)
        cloud = build_points(scene, plan)
        storeys.append(
            {
                "storey": s.key,
                "points": len(cloud),
                "wall_s": time.perf_counter() - w,
                "cpu_s": time.process_time() - c,
            }
        )
        print(f"  {s.key}: {len(cloud):,} points, {storeys[-1]['wall_s']:.2f} s", flush=True)
    out["storeys"] = storeys
    out["full_wall_s"] = sum(s["wall_s"] for s in storeys)
    out["full_cpu_s"] = sum(s["cpu_s"] for s in storeys)
    before = rss_mb()
    live = LiveMaps(scene, margin_m=1.0)
    w = time.perf_counter()
    for s in scene.storeys:
        live.points.add_map(skill, s.key, iris)
    out["live_build_s"] = time.perf_counter() - w
    out["live_rss_added_mb"] = rss_mb() - before
    out["rss_mb"] = rss_mb()
    out["max_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    busiest = max(live.points.clouds.values(), key=len)
    classes = {
        literal_value(r["e"]) or "": literal_value(r["c"]) or ""
        for r in store.select(f"SELECT ?e ?c WHERE {{ ?e <{TWIN_IFC_CLASS}> ?c }}")
    }
    rng = np.random.default_rng(seed)
    names = sorted(busiest.parts)
    picks = rng.choice(len(names), size=min(changes, len(names)), replace=False)
    times: list[float] = []
    cpu: list[float] = []
    opened: list[float] = []
    closed: list[float] = []
    slow: list[dict[str, Any]] = []
    for n in picks:
        iri = names[int(n)]
        shape = live.shape_of(iri)
        if shape is None:
            continue
        mesh, placement = shape
        moved = placement.copy()
        moved[0, 3] += 0.05
        w, c = time.perf_counter(), time.process_time()
        live.redraw([GeometryChange(iri, (mesh, moved))], {"lidar3d": {iri: True}})
        times.append(time.perf_counter() - w)
        cpu.append(time.process_time() - c)
        if cpu[-1] > 0.010:  # CPU time: on a shared machine, wall time also counts the others' work
            voxels = len(busiest.parts[iri]) if iri in busiest.parts else 0
            slow.append({"class": classes.get(iri, "?"), "voxels": voxels, "triangles": len(mesh.faces)})
            slow[-1] |= {"cpu_ms": round(cpu[-1] * 1e3, 1), "wall_ms": round(times[-1] * 1e3, 1)}
        w = time.perf_counter()
        live.redraw([], {"lidar3d": {iri: False}})  # like a door observed open: out of the skill
        opened.append(time.perf_counter() - w)
        w = time.perf_counter()
        live.redraw([], {"lidar3d": {iri: True}})  # and closed again
        closed.append(time.perf_counter() - w)
    ms = np.array(times) * 1e3
    off = np.array(opened) * 1e3
    on = np.array(closed) * 1e3
    out["change"] = {
        "storey": busiest.plan.storey.key,
        "n": len(ms),
        "move_p50_ms": float(np.percentile(ms, 50)),
        "move_p90_ms": float(np.percentile(ms, 90)),
        "move_p99_ms": float(np.percentile(ms, 99)),
        "move_max_ms": float(ms.max()),
        "move_cpu_p50_ms": float(np.percentile(np.array(cpu) * 1e3, 50)),
        "move_cpu_p90_ms": float(np.percentile(np.array(cpu) * 1e3, 90)),
        "deselect_p50_ms": float(np.percentile(off, 50)),
        "deselect_max_ms": float(off.max()),
        "reselect_p50_ms": float(np.percentile(on, 50)),
        "reselect_max_ms": float(on.max()),
        "over_10ms_cpu": sorted(slow, key=lambda x: -x["cpu_ms"]),
    }
    cloud, ref = busiest.cloud(), live.points.rebuild(busiest)
    out["equal_to_rebuild"] = bool(
        np.array_equal(cloud.keys, ref.keys) and np.array_equal(cloud.xyz, ref.xyz)
    )
    store.close()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--store", type=Path, help="an imported store directory")
    ap.add_argument("--model", type=Path, help="an IFC file (imported into a temporary store)")
    ap.add_argument("--resolution", type=float, default=0.1)
    ap.add_argument("--changes", type=int, default=40)
    ap.add_argument("--seed", type=int, default=32)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        store = args.store
        if store is None:
            store = Path(tmp) / "store"
            subprocess.run(
                [sys.executable, "-m", "adapters.cli", "import", "--store", str(store), str(args.model)],
                check=True,
                cwd=ROOT,
            )
        result = run(store, args.resolution, args.changes, args.seed)
    print(json.dumps(result, indent=2))
    if args.json:
        args.json.write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
