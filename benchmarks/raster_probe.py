"""Time ``twin.maps.raster`` on the Janesville restaurant: full navigation and localization maps and 5x5
m windows.

Usage::

    .venv/bin/python benchmarks/raster_probe.py [--ifc PATH] [--cache FILE.npz] [--runs N]

The model is meshed by ifcopenshell's manifold kernel in world coordinates. The iterator already
outputs metres (it applies the file's unit scale: Janesville is in feet and its walls come out
3.7465 m high); storey elevations are attributes in file units and are scaled here. An element is
flagged closed when every undirected edge of its position-welded mesh is shared by exactly two
faces. ``--cache`` stores the triangle arrays so that later runs skip the meshing (about 10 s).

Columns: ``full`` rasterize_slab on every triangle; ``window`` the same for 5x5 m windows (median
over 9 windows spread over the building; ``max`` the slowest); ``elements`` those windows from only
the triangles of the elements whose bounds meet them (selection included: what a daemon re-slicing
one window after a change would do); ``prepare`` slab_geometry once per slab; ``prepared``
rasterize(prepared geometry, window). Every window is checked bit for bit against the full map.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from twin.maps.grid import GridFrame, Window
from twin.maps.raster import rasterize, rasterize_slab, slab_geometry

JANESVILLE = Path("/work/shared/data/ifc/revit2012_janesville_restaurant.ifc")


def is_closed(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """Every undirected edge of the position-welded mesh is used by exactly two faces."""
    if len(faces) == 0:
        return False
    _, weld = np.unique(vertices, axis=0, return_inverse=True)
    f = weld.reshape(-1)[faces]
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return bool((counts == 2).all())


def load(ifc: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``(triangles (n,3,3), element (n,), closed (k,), lowest storey elevation in metres)``."""
    import ifcopenshell
    import ifcopenshell.geom
    import ifcopenshell.util.shape
    import ifcopenshell.util.unit

    model = ifcopenshell.open(str(ifc))
    scale = ifcopenshell.util.unit.calculate_unit_scale(model)
    elevation = min(s.Elevation or 0.0 for s in model.by_type("IfcBuildingStorey")) * scale
    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)
    include = [
        e for e in model.by_type("IfcElement") if not e.is_a("IfcOpeningElement") and not e.is_a("IfcSpace")
    ]
    it = ifcopenshell.geom.iterator(settings, model, 2, include=include, geometry_library="manifold")
    tris, elements, closed = [], [], []
    if it.initialize():
        while True:
            shape = it.get()
            v = ifcopenshell.util.shape.get_vertices(shape.geometry)  # world metres
            f = ifcopenshell.util.shape.get_faces(shape.geometry)
            if len(f):
                tris.append(v[f])
                elements.append(np.full(len(f), len(closed), dtype=np.intp))
                closed.append(is_closed(v, f))
            if not it.next():
                break
    return np.concatenate(tris), np.concatenate(elements), np.array(closed), elevation


def element_index(tri: np.ndarray, el: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per element: ``(k, 2)`` triangle ranges (triangles come grouped by element), ``(k, 4)`` XY bounds."""
    starts = np.flatnonzero(np.r_[True, el[1:] != el[:-1]])
    assert len(starts) == len(np.unique(el)), "triangles must be grouped by element"
    xy = tri[:, :, :2]
    lo, hi = np.minimum.reduceat(xy.min(axis=1), starts), np.maximum.reduceat(xy.max(axis=1), starts)
    ranges = np.zeros((el.max() + 1, 2), dtype=np.intp)
    boxes = np.full((el.max() + 1, 4), np.nan)
    ranges[el[starts]] = np.stack([starts, np.r_[starts[1:], len(el)]], axis=1)
    boxes[el[starts]] = np.concatenate([lo, hi], axis=1)
    return ranges, boxes


def near_window(
    tri: np.ndarray, el: np.ndarray, index: tuple[np.ndarray, np.ndarray], frame: GridFrame, window: Window
) -> tuple[np.ndarray, np.ndarray]:
    """The triangles (and their elements) of the elements whose bounds meet the window grown by a cell."""
    ranges, boxes = index
    res = frame.resolution_m
    x0, y0 = frame.origin_x + (window.col0 - 1) * res, frame.origin_y + (window.row0 - 1) * res
    x1, y1 = frame.origin_x + (window.col1 + 1) * res, frame.origin_y + (window.row1 + 1) * res
    hit = np.flatnonzero(
        (boxes[:, 2] >= x0) & (boxes[:, 3] >= y0) & (boxes[:, 0] <= x1) & (boxes[:, 1] <= y1)
    )
    if not len(hit):
        return tri[:0], el[:0]
    idx = np.concatenate([np.arange(*ranges[e]) for e in hit])
    return tri[idx], el[idx]


def timed(fn: Callable[[], object], runs: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(runs):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times)), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ifc", type=Path, default=JANESVILLE)
    ap.add_argument("--cache", type=Path)
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args()

    if args.cache and args.cache.exists():
        data = np.load(args.cache)
        tri, el, closed, elevation = data["tri"], data["el"], data["closed"], float(data["elevation"])
    else:
        t = time.perf_counter()
        tri, el, closed, elevation = load(args.ifc)
        print(f"meshed in {time.perf_counter() - t:.1f} s")
        if args.cache:
            np.savez(args.cache, tri=tri, el=el, closed=closed, elevation=elevation)
    lo, hi = tri.reshape(-1, 3).min(axis=0), tri.reshape(-1, 3).max(axis=0)
    frame = GridFrame.around(lo[0], lo[1], hi[0], hi[1], resolution_m=0.05, margin_m=1.0)
    index = element_index(tri, el)
    print(
        f"{len(tri):,} triangles, {len(closed)} elements ({int(closed.sum())} closed), "
        f"grid {frame.height}x{frame.width} at 0.05 m, lowest storey at {elevation:.4f} m"
    )
    windows = [
        frame.window_for(cx - 2.5, cy - 2.5, cx + 2.5 - 1e-9, cy + 2.5 - 1e-9)
        for cx in np.linspace(lo[0] + 5, hi[0] - 5, 3)
        for cy in np.linspace(lo[1] + 5, hi[1] - 5, 3)
    ]
    slabs = {
        "nav 0.05..1.5": (elevation + 0.05, elevation + 1.5),
        "loc 0.5+-0.01": (elevation + 0.49, elevation + 0.51),
    }
    header = (
        "slab",
        "in slab",
        "occupied",
        "full",
        "window",
        "max",
        "elements",
        "max",
        "prepare",
        "prepared",
        "max",
    )
    print(f"{header[0]:<14}" + "".join(f"{h:>10}" for h in header[1:]))
    z = tri[:, :, 2]
    for name, (z0, z1) in slabs.items():
        n_in = int(((z.max(axis=1) >= z0) & (z.min(axis=1) <= z1)).sum())
        t_full, full = timed(lambda z0=z0, z1=z1: rasterize_slab(tri, el, closed, z0, z1, frame), args.runs)
        t_prep, geom = timed(lambda z0=z0, z1=z1: slab_geometry(tri, el, closed, z0, z1, frame), args.runs)
        t_win, t_near, t_wprep = [], [], []
        for w in windows:
            want = full[w.row0 : w.row1, w.col0 : w.col1]
            t, got = timed(
                lambda w=w, z0=z0, z1=z1: rasterize_slab(tri, el, closed, z0, z1, frame, w), args.runs
            )
            assert np.array_equal(got, want), "window differs from the full map"
            t_win.append(t)

            def near(w: Window = w, z0: float = z0, z1: float = z1) -> np.ndarray:
                t_, e_ = near_window(tri, el, index, frame, w)
                return rasterize_slab(t_, e_, closed, z0, z1, frame, w)

            t, got = timed(near, args.runs * 4)
            assert np.array_equal(got, want), "window from nearby elements differs from the full map"
            t_near.append(t)
            t, got = timed(lambda w=w, g=geom: rasterize(g, frame, w), args.runs * 4)
            assert np.array_equal(got, want), "window from prepared geometry differs from the full map"
            t_wprep.append(t)
        times = (
            t_full,
            np.median(t_win),
            max(t_win),
            np.median(t_near),
            max(t_near),
            t_prep,
            np.median(t_wprep),
            max(t_wprep),
        )
        print(f"{name:<14}{n_in:>10,}{int(full.sum()):>10,}" + "".join(f"{t * 1e3:>8.1f}ms" for t in times))


if __name__ == "__main__":
    main()
