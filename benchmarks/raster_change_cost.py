"""A 2D map's per-change cost, this code against another checkout, alternated in one run.

What a change costs the 2D maps: an observed upright box (a 1.2 x 0.8 m table, random place and turn)
drawn by its fast path (:func:`twin.maps.raster.boxes.footprint_cells`) and by the general rasteriser
(its 12 triangles through :func:`twin.maps.raster.rasterize_slab`, as a non-box element is), and the
re-slice of a 5 x 5 m window of the static base on Janesville's navigation band from prepared geometry
(:func:`twin.maps.raster.rasterize`, what the daemon redraws where an observation hides an element)
and from the triangles of the elements near it. Each side runs in its own process (``PYTHONPATH`` set
to its checkout); rounds alternate the sides so that a loaded machine weighs on both alike. Medians.

Usage (the triangle cache is ``raster_probe.py --cache``'s)::

    python benchmarks/raster_change_cost.py --cache jv.npz --against /path/to/old/checkout [--rounds 3]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _median_us(fn: Callable[[], object], runs: int) -> float:
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times)) * 1e6


def child(cache: Path, runs: int) -> dict[str, float]:
    """Timings of the code on ``sys.path`` (microseconds)."""
    from twin.maps.grid import GridFrame, Window
    from twin.maps.raster import rasterize, rasterize_slab, slab_geometry
    from twin.maps.raster.boxes import box_footprint, footprint_cells
    from twin.maps.shapes import box_mesh, box_placement

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from raster_probe import element_index, near_window

    data = np.load(cache)
    tri, el, closed = data["tri"], data["el"], data["closed"]
    lo, hi = tri[:, :, :2].min(axis=(0, 1)), tri[:, :, :2].max(axis=(0, 1))
    frame = GridFrame.around(*lo, *hi, resolution_m=0.05)
    z0 = float(data["elevation"]) + 0.05
    z1 = z0 + 1.45
    rng = np.random.default_rng(7)
    mesh = box_mesh(1.2, 0.8, 0.75)
    boxes = []
    for _ in range(200):
        cx, cy = rng.uniform(lo + 2, hi - 2)
        p = box_placement(cx, cy, z0 + 0.3, yaw=rng.uniform(-np.pi, np.pi))
        b = (mesh.vertices @ p[:3, :3].T + p[:3, 3])[mesh.faces]
        win = frame.window_for(cx - 0.8, cy - 0.8, cx + 0.8, cy + 0.8)
        boxes.append((box_footprint(mesh.vertices, p), b, win))
    owner, one = np.zeros(12, dtype=np.intp), np.ones(1, dtype=np.bool_)
    fast = np.median([_median_us(lambda f=f, w=w: footprint_cells(f, frame, w), runs) for f, _, w in boxes])
    general = np.median(
        [
            _median_us(lambda b=b, w=w: rasterize_slab(b, owner, one, z0, z1, frame, w), runs)
            for _, b, w in boxes
        ]
    )
    try:
        geometry = slab_geometry(tri, el, closed, z0, z1, frame)  # type: ignore[call-arg]
    except TypeError:  # the code before issue 40: grid-independent geometry
        geometry = slab_geometry(tri, el, closed, z0, z1)  # type: ignore[call-arg]
    index = element_index(tri, el)
    windows = []
    for fy in (0.25, 0.5, 0.75):
        for fx in (0.25, 0.5, 0.75):
            x, y = lo + (hi - lo) * (fx, fy)
            windows.append(frame.window_for(x - 2.5, y - 2.5, x + 2.5, y + 2.5))
    prepared = np.median([_median_us(lambda w=w: rasterize(geometry, frame, w), runs) for w in windows])

    def near(w: Window) -> object:
        t, e = near_window(tri, el, index, frame, w)
        return rasterize_slab(t, e, closed, z0, z1, frame, w)

    nearby = np.median([_median_us(lambda w=w: near(w), max(runs // 4, 1)) for w in windows])
    return {"box_fast_us": fast, "box_general_us": general, "prepared_us": prepared, "nearby_us": nearby}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", type=Path, required=True)
    ap.add_argument("--against", type=Path, help="the other checkout (its root, holding twin/)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(child(args.cache, args.runs)))
        return
    sides = {"this": ROOT, "other": args.against}
    results: dict[str, list[dict[str, float]]] = {name: [] for name in sides}
    for _ in range(args.rounds):
        for name, path in sides.items():
            env = {**os.environ, "PYTHONPATH": str(path)}
            cmd = [sys.executable, __file__, "--child", "--cache", str(args.cache), "--runs", str(args.runs)]
            out = subprocess.run(cmd, env=env, check=True, capture_output=True, text=True).stdout
            results[name].append(json.loads(out.strip().splitlines()[-1]))
    keys = list(results["this"][0])
    print(f"{'side':<8}" + "".join(f"{k:>16}" for k in keys))
    for name, runs in results.items():
        print(f"{name:<8}" + "".join(f"{np.median([r[k] for r in runs]):>16.1f}" for k in keys))


if __name__ == "__main__":
    main()
