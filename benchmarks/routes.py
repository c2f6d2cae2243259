"""Route graph quality and speed (issue 41): safe, complete, short, covering, fast.

For a model (the sample lab, ``--lab``, or an IFC file, ``--model``) and robot radii (default 0.25 m and
0.45 m, each a navigation skill like the shipped one with that ``inflation_radius_m``), builds a routes
skill's graph storey by storey (:func:`twin.routes.build.build_routes`, one storey at a time, timed)
and measures it against the cells it was made from (:func:`twin.routes.build.routable_cells`: the
inflated navigation map with doors open and lift cars exempt, over the storey's floor):

- **safe**: lanes whose centre line crosses a blocked cell (the sampling of ``twin.routes.lines``);
- **complete**: free regions (8-connected) without a vertex, graph components that join two regions,
  regions split over several graph components; spaces with free cells but no vertex;
- **short**: ``--pairs`` random reachable pairs, uniform over the pairs of free cells the map connects
  (50 sources, each drawn with a weight of its region's size, 20 targets uniform in its region:
  ``--per-cell-sources`` draws sources uniform over free cells instead, as before 2026-11-28, which
  over-weights small regions), the route through the graph (each end joined straight to the best of
  the 16 nearest vertices it sees) over the shortest 8-connected grid path (diagonal sqrt 2): median
  and 95th percentile (target 1.15 and 1.3), of all pairs and of the pairs at least 2 m apart;
  ``--show-bad N`` prints the N worst pairs over 1.3 (their region's area and vertices, the vertices
  both ends join);
- **covering**: the farthest free cell from a lane (target <= max_lane_m), and the share of 2,000
  random free cells that see a vertex among their 32 nearest;
- **fast**: seconds per storey, wall and CPU (the median of ``--repeat`` builds; the navigation map's
  rendering included; ``cells_cpu_s``: the CPU seconds of the routable cells alone, the map's rendering
  included, measured again apart).

Usage::

    python benchmarks/routes.py --lab [--png-dir benchmarks] [--json OUT.json]
    python benchmarks/routes.py --model /work/shared/data/ifc/AC20-FZK-Haus.ifc [--radius 0.25 0.45]
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree
from skimage.graph import MCP_Geometric

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from adapters.ifc import read_model  # noqa: E402
from adapters.ifc.sample_lab import write_lab  # noqa: E402
from twin.config import load_config  # noqa: E402
from twin.config.routes import parse_routes  # noqa: E402
from twin.errors import RouteError  # noqa: E402
from twin.graph.import_model import import_model  # noqa: E402
from twin.graph.store import EmbeddedStore, GraphStore  # noqa: E402
from twin.maps.grid import GridFrame  # noqa: E402
from twin.maps.scene import load_scene  # noqa: E402
from twin.routes.build import RouteContext, build_routes, prepare_routes, routable_cells  # noqa: E402
from twin.routes.graph import DoorCrossing, RouteGraph, StoreyRoutes  # noqa: E402
from twin.routes.lines import segments_free  # noqa: E402

NOTES_SHOWN = 5
LABELS_SHOWN = 30
"""A storey's picture names its named vertices when it has at most this many."""
BAD_RATIO = 1.3
"""A pair routed more than this many times its grid path is listed (``--show-bad``)."""
LONG_PAIR_M = 2.0
"""Pairs at least this far apart (grid path) are also reported on their own: closer pairs are within a
lattice spacing or two, where joining the graph at both ends dominates the route."""


def free_cells(ctx: RouteContext, storey: str) -> tuple[np.ndarray, GridFrame]:
    """The cells the graph is made from (:func:`twin.routes.build.routable_cells`)."""
    plan, free = routable_cells(ctx, storey)
    return free, plan.frame


def to_cells(frame: GridFrame, xy: np.ndarray) -> np.ndarray:
    res = frame.resolution_m
    return np.stack(
        [(xy[:, 1] - frame.origin_y) / res - 0.5, (xy[:, 0] - frame.origin_x) / res - 0.5], axis=1
    )


def measure(
    storey: StoreyRoutes,
    free: np.ndarray,
    frame: GridFrame,
    *,
    pairs: int,
    max_lane_m: float,
    seed: int,
    uniform_pairs: bool = True,
) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    res = frame.resolution_m
    xy = np.array([(v.x, v.y) for v in storey.vertices])
    cells = to_cells(frame, xy)
    a = np.array([lane.a for lane in storey.lanes], dtype=np.int64)
    b = np.array([lane.b for lane in storey.lanes], dtype=np.int64)
    out: dict[str, Any] = {"vertices": len(xy), "lanes": len(a)}
    out["unsafe_lanes"] = int((~segments_free(free, cells[a], cells[b])).sum()) if len(a) else 0
    # complete: regions against graph components
    labels, regions = ndimage.label(free, structure=np.ones((3, 3)))
    rc = np.rint(np.round(cells, 6)).astype(np.int64)  # as segments_free rounds a vertex's cell
    region_of = labels[rc[:, 0], rc[:, 1]]
    n = len(xy)
    weights = np.hypot(*(cells[a] - cells[b]).T)  # cells, as the grid paths
    adjacency = coo_matrix((np.r_[weights, weights] + 1e-9, (np.r_[a, b], np.r_[b, a])), shape=(n, n)).tocsr()
    _, component = connected_components(adjacency, directed=False)
    joined = sum(len(set(region_of[component == c])) > 1 for c in np.unique(component))
    split = sum(len(set(component[region_of == r])) > 1 for r in range(1, regions + 1))
    empty = regions - len(set(region_of[region_of > 0]))
    out |= {
        "regions": regions,
        "regions_without_vertex": empty,
        "components_joining_regions": int(joined),
        "regions_split": int(split),
        "vertices_off_free": int((region_of == 0).sum()),
    }
    # covering: distance from lanes, and sight of a vertex
    lane_mask = np.zeros_like(free)
    for s in range(len(a)):
        steps = max(2, int(np.ceil(np.hypot(*(cells[b[s]] - cells[a[s]])) * 2)) + 1)
        t = np.linspace(0.0, 1.0, steps)[:, None]
        p = np.rint(cells[a[s]] + (cells[b[s]] - cells[a[s]]) * t).astype(np.int64)
        lane_mask[p[:, 0], p[:, 1]] = True
    lane_mask[rc[:, 0], rc[:, 1]] = True
    dist = ndimage.distance_transform_edt(~lane_mask) * res
    out["farthest_from_lane_m"] = round(float(dist[free].max()), 3) if free.any() else 0.0
    out["cells_beyond_max_lane"] = int((dist[free] > max_lane_m).sum())
    free_idx = np.flatnonzero(free)
    tree = cKDTree(cells)
    sample = rng.choice(free_idx, size=min(2000, len(free_idx)), replace=False)
    pts = np.stack(np.divmod(sample, free.shape[1]), axis=1).astype(np.float64)
    k = min(32, n)
    _, near = tree.query(pts, k=k)
    near = near.reshape(len(pts), -1)
    seen = segments_free(free, np.repeat(pts, near.shape[1], axis=0), cells[near.ravel()]).reshape(near.shape)
    out["cells_seeing_a_vertex"] = round(float(seen.any(axis=1).mean()), 4)
    # short: graph route over the 8-connected grid path, pairs in one region
    ratios: list[float] = []
    lengths: list[float] = []
    mcp_cost = np.where(free, 1.0, np.inf)
    # pairs uniform over the reachable pairs (the words): a source cell weighted by the size of
    # its region (a region of n cells holds n^2 of them), its targets uniform in that region
    sizes = np.bincount(labels.ravel())
    weight = sizes[labels.ravel()[free_idx]].astype(np.float64)
    sources = rng.choice(
        free_idx,
        size=min(max(1, pairs // 20), len(free_idx)),
        replace=False,
        p=weight / weight.sum() if uniform_pairs else None,
    )
    per_source = max(1, pairs // len(sources))
    bad: list[dict[str, Any]] = []
    for src in sources:
        s_rc = np.array(divmod(int(src), free.shape[1]))
        region = labels[s_rc[0], s_rc[1]]
        same = np.flatnonzero(labels.ravel() == region)
        if len(same) < 2:
            continue
        targets = rng.choice(same, size=min(per_source, len(same)), replace=False)
        mcp = MCP_Geometric(mcp_cost, fully_connected=True)
        cum, _ = mcp.find_costs([tuple(s_rc)])
        s_join = _joins(tree, free, cells, s_rc.astype(np.float64))
        if not s_join:
            continue
        src_dist = dijkstra(adjacency, directed=False, indices=[j for j, _ in s_join])
        best_from_src = np.min(src_dist + np.array([d for _, d in s_join])[:, None], axis=0)
        for tgt in targets:
            t_rc = np.array(divmod(int(tgt), free.shape[1]))
            grid_len = float(cum[t_rc[0], t_rc[1]])
            if not np.isfinite(grid_len) or grid_len < 1.0:
                continue
            t_join = _joins(tree, free, cells, t_rc.astype(np.float64))
            if not t_join:
                ratios.append(np.inf)
                lengths.append(grid_len * res)
                continue
            route, via_t = min((best_from_src[j] + d, j) for j, d in t_join)
            ratios.append(route / grid_len)
            lengths.append(grid_len * res)
            if route / grid_len > BAD_RATIO:
                via_s = min(s_join, key=lambda jd: src_dist[s_join.index(jd), via_t] + jd[1])[0]
                bad.append(
                    {
                        "ratio": round(float(route / grid_len), 3),
                        "grid_m": round(grid_len * res, 3),
                        "source_xy": _xy(frame, s_rc),
                        "target_xy": _xy(frame, t_rc),
                        "region_cells": int(sizes[region]),
                        "region_m2": round(float(sizes[region]) * res * res, 3),
                        "region_vertices": int((region_of == region).sum()),
                        "joins": (via_s, via_t),
                    }
                )
    r, far = np.array(ratios), np.array(lengths) >= LONG_PAIR_M
    out["bad_pairs"] = bad
    out["pairs"] = len(r)
    out["long_pairs"] = int(far.sum())
    out["unjoined_pairs"] = int((~np.isfinite(r)).sum())
    for key, sel in (("", np.isfinite(r)), ("_long", np.isfinite(r) & far)):
        out[f"ratio{key}_p50"] = round(float(np.median(r[sel])), 3) if sel.any() else None
        out[f"ratio{key}_p95"] = round(float(np.percentile(r[sel], 95)), 3) if sel.any() else None
    return out


def _xy(frame: GridFrame, rc: np.ndarray) -> tuple[float, float]:
    res = frame.resolution_m
    return (
        round(frame.origin_x + (float(rc[1]) + 0.5) * res, 2),
        round(frame.origin_y + (float(rc[0]) + 0.5) * res, 2),
    )


def _joins(
    tree: cKDTree, free: np.ndarray, cells: np.ndarray, p: np.ndarray, k: int = 16
) -> list[tuple[int, float]]:
    """The vertices among the ``k`` nearest that ``p`` sees, with their distances (cells)."""
    k = min(k, len(cells))
    d, near = tree.query(p, k=k)
    near, d = np.atleast_1d(near), np.atleast_1d(d)
    ok = segments_free(free, np.repeat(p[None], len(near), axis=0), cells[near])
    return [(int(j), float(dd)) for j, dd, o in zip(near, d, ok, strict=True) if o]


def draw(graph: RouteGraph, frees: dict[str, tuple[np.ndarray, GridFrame]], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # about 10 pixels a metre at 90 dpi, 9 to 20 inches wide: a long building stays readable
    spans = [(f.width * f.resolution_m, f.height * f.resolution_m) for _, f in frees.values()]
    wide, tall = max(w for w, _ in spans), max(h for _, h in spans)
    width_in = min(max(9.0, wide / 9.0), 20.0)
    row_in = min(max(width_in * tall / wide + 0.6, 2.0), 9.0)
    fig, axes = plt.subplots(
        len(graph.storeys), 1, figsize=(width_in, row_in * len(graph.storeys)), squeeze=False
    )
    for ax, s in zip(axes[:, 0], graph.storeys, strict=True):
        free, f = frees[s.storey]
        named = sum(1 for v in s.vertices if v.name)
        ext = (
            f.origin_x,
            f.origin_x + f.width * f.resolution_m,
            f.origin_y,
            f.origin_y + f.height * f.resolution_m,
        )
        ax.imshow(np.where(free, 1.0, 0.25), origin="lower", cmap="gray", vmin=0, vmax=1, extent=ext)
        for lane in s.lanes:
            va, vb = s.vertices[lane.a], s.vertices[lane.b]
            ax.plot(
                [va.x, vb.x], [va.y, vb.y], color="red" if lane.door else "tab:blue", lw=2 if lane.door else 1
            )
        ax.plot([v.x for v in s.vertices], [v.y for v in s.vertices], ".", color="tab:blue", ms=3)
        for v in s.vertices:
            if v.name:
                ax.plot([v.x], [v.y], "o", color="tab:orange", ms=5)
                if named > LABELS_SHOWN:
                    continue  # many spaces: the dots only, names would cover the graph
                ax.annotate(
                    v.name,
                    (v.x, v.y),
                    fontsize=7,
                    color="tab:orange",
                    xytext=(3, 3),
                    textcoords="offset points",
                )
        for d in graph.doors:
            if d.storey == s.storey:
                (x0, y0), (x1, y1) = d.endpoints
                ax.plot([x0, x1], [y0, y1], color="green" if d.passable else "magenta", lw=3)
        ax.set_title(f"{title}: {s.storey} ({len(s.vertices)} vertices, {len(s.lanes)} lanes)", fontsize=9)
        ax.set_aspect("equal")
        ax.tick_params(labelsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    shrink_png(path)


def shrink_png(path: Path, colors: int = 64) -> None:
    """Rewrite the picture ``path`` with a palette of ``colors``: a few times smaller in git."""
    from PIL import Image

    with Image.open(path) as image:
        small = image.convert("RGB").quantize(colors=colors)
    small.save(path, optimize=True)


def run(store: GraphStore, name: str, radii: list[float], args: argparse.Namespace) -> list[dict[str, Any]]:
    cfg = load_config()
    scene = load_scene(store)
    base = cfg.skills[args.navigation]
    rows = []
    for radius in radii:
        nav = replace(base, name="nav", inflation_radius_m=radius)
        skills = {**cfg.skills, "nav": nav}
        frees: dict[str, tuple[np.ndarray, GridFrame]] = {}
        storeys: list[StoreyRoutes] = []
        doors: list[DoorCrossing] = []
        graph = None
        for storey in scene.storeys:
            if args.storey and storey.key not in args.storey:
                continue
            routes = parse_routes(
                "fleet",
                {"kind": "routes", "navigation": "nav", "storeys": [storey.key], "max_lane_m": args.max_lane},
            )
            walls, cpus = [], []
            try:
                for _ in range(args.repeat):
                    t0, c0 = time.perf_counter(), time.process_time()
                    graph = build_routes(store, scene, routes, skills, margin_m=cfg.margin_m)
                    walls.append(time.perf_counter() - t0)
                    cpus.append(time.process_time() - c0)
            except RouteError as err:
                rows.append({"model": name, "radius_m": radius, "storey": storey.key, "error": str(err)})
                continue
            wall, cpu = float(np.median(walls)), float(np.median(cpus))
            (s,) = graph.storeys
            storeys.append(s)
            doors += graph.doors
            row = {
                "model": name,
                "radius_m": radius,
                "storey": storey.key,
                "wall_s": round(wall, 3),
                "cpu_s": round(cpu, 3),
            }
            if args.repeat > 1:
                row |= {"walls_s": [round(t, 3) for t in walls], "cpus_s": [round(t, 3) for t in cpus]}
            c1 = time.process_time()
            free, frame = free_cells(
                prepare_routes(store, scene, routes, skills, margin_m=cfg.margin_m), storey.key
            )
            row["cells_cpu_s"] = round(time.process_time() - c1, 3)
            frees[storey.key] = (free, frame)
            row |= measure(
                s,
                free,
                frame,
                pairs=args.pairs,
                max_lane_m=args.max_lane,
                seed=args.seed,
                uniform_pairs=not args.per_cell_sources,
            )
            row["doors"] = f"{sum(d.passable for d in graph.doors)}/{len(graph.doors)}"
            row["notes"] = list(graph.notes)
            rows.append(row)
        if args.png_dir and graph is not None and storeys:
            whole = replace(graph, storeys=tuple(storeys), doors=tuple(doors))
            path = Path(args.png_dir) / f"routes-{name}-{int(radius * 100):02d}.png"
            draw(whole, frees, path, f"{name}, radius {radius} m")
            print(f"wrote {path}")
    return rows


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--lab", action="store_true", help="the two-storey sample lab")
    src.add_argument("--model", type=Path, help="an IFC file (imported into a store in memory)")
    p.add_argument("--radius", type=float, nargs="+", default=[0.25, 0.45])
    p.add_argument("--navigation", help="the navigation skill to copy (default: lab-navigation / navigation)")
    p.add_argument("--max-lane", type=float, default=3.0)
    p.add_argument("--pairs", type=int, default=1000)
    p.add_argument("--seed", type=int, default=41)
    p.add_argument(
        "--per-cell-sources",
        action="store_true",
        help="sources uniform over free cells (before 2026-11-28), not pairs uniform over reachable pairs",
    )
    p.add_argument("--repeat", type=int, default=1, help="build each storey's graph this many times (median)")
    p.add_argument("--storey", nargs="+", help="only these storeys (keys)")
    p.add_argument("--show-bad", type=int, default=0, help="print this many of each run's worst pairs")
    p.add_argument("--png-dir", help="write a picture of each profile's graph over its maps here")
    p.add_argument("--json", type=Path)
    args = p.parse_args()
    logging.basicConfig(level=logging.WARNING)
    cfg = load_config()
    if args.lab:
        args.navigation = args.navigation or "lab-navigation"
        with tempfile.TemporaryDirectory() as tmp:
            write_lab(Path(tmp) / "lab.ifc", storeys=2)
            model = read_model(Path(tmp) / "lab.ifc", static_types=cfg.import_.static_types)
        name = "lab"
    else:
        args.navigation = args.navigation or "navigation"
        t = time.perf_counter()
        model = read_model(args.model, static_types=cfg.import_.static_types)
        print(f"read {args.model.name} in {time.perf_counter() - t:.1f} s")
        name = args.model.stem
    store = EmbeddedStore.open(None)
    import_model(store, model, base_iri="https://example.org/bench#", site="bench")
    rows = run(store, name, args.radius, args)
    keys = [
        "radius_m",
        "storey",
        "wall_s",
        "cpu_s",
        "cells_cpu_s",
        "vertices",
        "lanes",
        "doors",
        "unsafe_lanes",
        "regions",
        "regions_without_vertex",
        "components_joining_regions",
        "regions_split",
        "ratio_p50",
        "ratio_p95",
        "long_pairs",
        "ratio_long_p50",
        "ratio_long_p95",
        "unjoined_pairs",
        "farthest_from_lane_m",
        "cells_seeing_a_vertex",
    ]
    print("| " + " | ".join(keys) + " |")
    print("|" + "---|" * len(keys))
    for row in rows:
        if "error" in row:
            print(f"| {row['radius_m']} | {row['storey']} | error: {row['error']} |")
            continue
        print("| " + " | ".join(str(row.get(k, "")) for k in keys) + " |")
        bad = row.pop("bad_pairs")
        if args.show_bad and bad:
            print(
                f"  {len(bad)} pairs over {BAD_RATIO}: "
                f"median {np.median([b['grid_m'] for b in bad]):.2f} m apart, "
                f"in regions of median {np.median([b['region_m2'] for b in bad]):.2f} m2 "
                f"(largest {max(b['region_m2'] for b in bad):.2f} m2; storey's regions: {row['regions']})"
            )
            for b in sorted(bad, key=lambda b: -b["ratio"])[: args.show_bad]:
                print(f"  bad: {b}")
        if "walls_s" in row:
            print(f"  builds: wall {row['walls_s']} s, CPU {row['cpus_s']} s")
        for note in row["notes"][:NOTES_SHOWN]:
            print(f"  note: {note}")
        if len(row["notes"]) > NOTES_SHOWN:
            print(f"  ... and {len(row['notes']) - NOTES_SHOWN} more notes (--json has them all)")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
