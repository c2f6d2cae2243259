"""One measurement per process: the tasks ``run.py --child`` runs (each returns a JSON-able dict).

Tasks:
    bare      ifcopenshell.open + a single-threaded geometry iterator (manifold kernel, the default
              settings, which are ours) over every IfcElement and IfcSpace with a representation,
              pulling vertices, faces and matrix of each.
    bare-routed  the same with our kernel routing: the products ``adapters.ifc.kernel_choice`` sends to
              OpenCASCADE meshed by it while manifold meshes the rest (one single-threaded iterator
              each, in two threads of one process): the geometry our import must compute, nothing else.
    import    ``adapters.ifc.read_model`` + ``twin.graph.import_model.import_model`` into an on-disk store.
    stats     ``twin.graph.stats.model_stats`` of the store an ``import`` child left behind (the paper's
    Table 1).
    map       setup (in-memory import, scene, selection, plan), then one method: ``twin-full``,
              ``twin-region``, ``trimesh`` or ``manifold3d``.
    storey-maps  the full map of every configured skill on every storey of the store an ``import``
              child left behind (``neuron.py``), each built ``repeat`` times.

Memory in map children: the setup dominates the process peak, so the method's own peak is measured by
resetting the kernel's high-water mark (``/proc/self/clear_refs``) after setup and reading ``VmHWM``.
"""

from __future__ import annotations

import gc
import resource
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

BASE_IRI = "https://example.org/b#"
SITE = "b"
THREADS = 1
"""The bare iterator is single-threaded (the issue's baseline); the import may use both cores."""
REGION_M = 5.0
REGION_WINDOWS = 20
REGION_SEED = 20261122
PEER_BUDGET_S = 20.0  # a slow peer repeats only while its runs stay within this budget
MAP_METHODS = ("twin-full", "twin-region", "twin-region-prepared", "trimesh", "manifold3d")


# --- memory ----------------------------------------------------------------------------------------


def _status_mb(name: str) -> float:
    """A ``/proc/self/status`` field (``VmRSS``, ``VmHWM``) in MiB; 0.0 where unavailable."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith(name + ":"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return 0.0


def reset_peak() -> bool:
    """Reset this process's peak RSS (``VmHWM``) to its current RSS; False if the kernel refuses."""
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as fh:
            fh.write("5")
    except OSError:
        return False
    return True


def peak_self_and_children_mb() -> float:
    """Peak RSS of this process and of its reaped children (e.g. the meshing child), in MiB."""
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    kids = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return max(own, kids) / 1024


@dataclass(slots=True)
class MethodMemory:
    """RSS before a method and the peak while it ran (MiB)."""

    baseline_mb: float
    reset: bool

    @classmethod
    def start(cls) -> MethodMemory:
        gc.collect()
        reset = reset_peak()
        return cls(_status_mb("VmRSS"), reset)

    def report(self) -> dict[str, float | None]:
        if not self.reset:
            return {"method_peak_mb": None, "method_extra_mb": None}
        peak = _status_mb("VmHWM")
        return {"method_peak_mb": peak, "method_extra_mb": max(peak - self.baseline_mb, 0.0)}


# --- timing helpers --------------------------------------------------------------------------------


def timed_runs(fn: Callable[[], Any], repeat: int, budget_s: float = float("inf")) -> tuple[list[float], Any]:
    """Run ``fn`` up to ``repeat`` times (at least once; stop early past ``budget_s``): times, last result."""
    times: list[float] = []
    result: Any = None
    for _ in range(max(repeat, 1)):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
        if sum(times) > budget_s:
            break
    return times, result


def summary(times: list[float]) -> dict[str, Any]:
    return {
        "median_s": statistics.median(times),
        "min_s": min(times),
        "first_s": times[0],
        "runs": len(times),
    }


# --- import tasks ----------------------------------------------------------------------------------


def bare_iterator(path: Path) -> dict[str, Any]:
    """The geometry iterator alone (one thread), same kernel and settings as ``adapters.ifc.geometry``."""
    import ifcopenshell

    t0 = time.perf_counter()
    f = ifcopenshell.open(str(path))
    t_open = time.perf_counter() - t0
    products = [p for p in (*f.by_type("IfcElement"), *f.by_type("IfcSpace")) if p.Representation is not None]
    shapes, triangles = _iterate(f, products, "manifold", THREADS)
    return {
        "seconds": time.perf_counter() - t0,
        "open_s": t_open,
        "products": len(products),
        "shapes": shapes,
        "triangles": triangles,
    }


def _iterate(f: Any, products: list[Any], kernel: str, threads: int) -> tuple[int, int]:
    """Run one geometry iterator, pulling every shape's vertices, faces and matrix: (shapes, triangles)."""
    import ifcopenshell.geom
    import ifcopenshell.util.shape

    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", False)
    settings.set("weld-vertices", True)
    it = ifcopenshell.geom.iterator(settings, f, threads, include=products, geometry_library=kernel)
    shapes = triangles = 0
    more = bool(it.initialize()) if products else False
    while more:
        shape = it.get()
        ifcopenshell.util.shape.get_vertices(shape.geometry)
        faces = ifcopenshell.util.shape.get_faces(shape.geometry)
        ifcopenshell.util.shape.get_shape_matrix(shape)
        shapes += 1
        triangles += len(faces)  # (n, 3)
        more = bool(it.next())
    return shapes, triangles


def bare_routed_iterator(path: Path) -> dict[str, Any]:
    """The bare iterators with our kernel routing: the reference kernel beside manifold, in threads."""
    import threading

    import ifcopenshell

    from adapters.ifc.kernel_choice import REFERENCE_KERNEL, KernelChoice

    t0 = time.perf_counter()
    f = ifcopenshell.open(str(path))
    t_open = time.perf_counter() - t0
    products = [p for p in (*f.by_type("IfcElement"), *f.by_type("IfcSpace")) if p.Representation is not None]
    router = KernelChoice()
    routed = [p for p in products if router.reason(p) is not None]
    routed_ids = {p.id() for p in routed}
    rest = [p for p in products if p.id() not in routed_ids]
    counts: dict[str, tuple[int, int]] = {}

    def run(kernel: str, chosen: list[Any], threads: int) -> None:
        counts[kernel] = _iterate(f, chosen, kernel, threads)

    runs = [
        threading.Thread(target=run, args=("manifold", rest, THREADS)),
        threading.Thread(target=run, args=(REFERENCE_KERNEL, routed, THREADS)),
    ]
    for t in runs:
        t.start()
    for t in runs:
        t.join()
    return {
        "seconds": time.perf_counter() - t0,
        "open_s": t_open,
        "products": len(products),
        "routed": len(routed),
        "shapes": sum(n for n, _ in counts.values()),
        "triangles": sum(t for _, t in counts.values()),
    }


def twin_import(path: Path, store_dir: Path) -> dict[str, Any]:
    """Our full import (``twin import``'s :func:`~adapters.cli.import_file.import_ifc`) into an on-disk
    store at ``store_dir`` (closed afterwards)."""
    from adapters.cli.import_file import import_ifc
    from twin.config import load_config
    from twin.graph.store import EmbeddedStore

    cfg = load_config()
    meshed: list[float] = []

    def progress(done: int, total: int) -> None:
        if done >= total and not meshed:
            meshed.append(time.perf_counter())

    t0 = time.perf_counter()
    store = EmbeddedStore.open(store_dir)
    try:
        summary_ = import_ifc(
            path,
            store,
            base_iri=BASE_IRI,
            site=SITE,
            static_types=cfg.import_.static_types,
            kernels=cfg.import_.kernels,
            threads=cfg.import_.threads,
            progress=progress,
        )
    finally:
        store.close()
    t1 = time.perf_counter()
    return {
        "seconds": t1 - t0,
        "meshed_s": (meshed[0] - t0) if meshed else None,
        "elements": summary_.elements,
        "meshes": summary_.meshes,
        "kernel_fallbacks": len(summary_.kernel_fallbacks),
        "mesh_failures": len(summary_.mesh_failures),
        "triples": summary_.triples,
        "in_child_peak_mb": peak_self_and_children_mb(),
    }


def table1(store_dir: Path) -> dict[str, Any]:
    """The paper's Table 1 numbers of an imported store."""
    from twin.graph.stats import model_stats
    from twin.graph.store import EmbeddedStore

    t0 = time.perf_counter()
    with EmbeddedStore.open(store_dir, read_only=True) as store:
        stats = model_stats(store)
    return {
        "seconds": time.perf_counter() - t0,
        "ifc_lines": stats.ifc_lines,
        "triples": stats.triples,
        "turtle_bytes": stats.turtle_bytes,
        "elements": stats.elements,
        "meshes": stats.meshes,
        "triangles": stats.triangles,
        "storeys": [{"key": s.key, "elements": s.elements} for s in stats.storeys],
    }


# --- map tasks -------------------------------------------------------------------------------------


def storey_maps(store_dir: Path, repeat: int) -> dict[str, Any]:
    """Full-map time of every (storey, skill) of an imported store, as the daemon builds them at start."""
    from twin.config import load_config
    from twin.graph.rdf import literal_value
    from twin.graph.store import EmbeddedStore
    from twin.maps.render import build_map, plan_map
    from twin.maps.scene import load_scene
    from twin.selection.skill_selection import selection_query

    cfg = load_config()
    t0 = time.perf_counter()
    with EmbeddedStore.open(store_dir, read_only=True) as store:
        scene = load_scene(store)
        selections = {
            name: [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]
            for name, skill in cfg.skills.items()
        }
    load_s = time.perf_counter() - t0
    maps = []
    for storey in scene.storeys:
        for name, skill in cfg.skills.items():
            plan = plan_map(scene, skill, storey.key, selections[name], margin_m=cfg.margin_m)
            times, grid = timed_runs(lambda plan=plan: build_map(scene, plan), repeat)
            maps.append(
                {
                    "storey": storey.key,
                    "skill": name,
                    **summary(times),
                    "grid": [plan.frame.width, plan.frame.height],
                    "selected": len(plan.selected),
                    "occupied": int(grid.occupied().sum()),
                }
            )
    return {"seconds": time.perf_counter() - t0, "scene_load_s": load_s, "maps": maps}


@dataclass(frozen=True, slots=True)
class MapSetup:
    scene: Any
    plan: Any
    info: dict[str, Any]


def busiest_storey(scene: Any, navigation: Any) -> str:
    """The storey whose navigation slab (``navigation.z_range`` above its elevation, over its extent)
    meets the most element bounding boxes: the busiest floor a robot drives on. First one on ties."""
    from twin.maps.scene import SlabBox

    everything = np.arange(len(scene.elements), dtype=np.intp)
    lo, hi = navigation.z_range

    def cut(storey: Any) -> int:
        xmin, ymin, xmax, ymax = storey.extent
        z0 = storey.elevation_m
        near = scene.elements.overlapping(
            everything, SlabBox(xmin, ymin, xmax, ymax, z_lo=z0 + lo, z_hi=z0 + hi)
        )
        return len(near)

    return str(max(scene.storeys, key=cut).key)


def map_setup(path: Path, skill_name: str) -> MapSetup:
    """In-memory import, scene, selection and plan on the busiest storey (the same for both skills)."""
    from adapters.ifc import read_model
    from twin.config import load_config
    from twin.graph.import_model import import_model
    from twin.graph.rdf import literal_value
    from twin.graph.store import EmbeddedStore
    from twin.maps.render import plan_map
    from twin.maps.scene import load_scene
    from twin.selection.skill_selection import selection_query

    cfg = load_config()
    skill = cfg.skill(skill_name)
    store = EmbeddedStore.open(None)
    t0 = time.perf_counter()
    import_model(store, read_model(path, static_types=cfg.import_.static_types), base_iri=BASE_IRI, site=SITE)
    t1 = time.perf_counter()
    scene = load_scene(store)
    t2 = time.perf_counter()
    iris = [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]
    storey = busiest_storey(scene, cfg.skill("navigation"))
    plan = plan_map(scene, skill, storey, iris, margin_m=1.0)
    info = {
        "import_s": t1 - t0,
        "scene_load_s": t2 - t1,
        "storey": storey,
        "selected": len(plan.selected),
        "scene_triangles": len(scene.elements.triangles),
        "grid": [plan.frame.width, plan.frame.height],
        "z_lo": plan.z_lo,
        "z_hi": plan.z_hi,
    }
    return MapSetup(scene, plan, info)


def _twin_occupied(setup: MapSetup) -> np.ndarray:
    from twin.maps.render import build_map

    occupied: np.ndarray = build_map(setup.scene, setup.plan).occupied()
    return occupied


def _diff(peer: np.ndarray, ours: np.ndarray) -> dict[str, int]:
    return {
        "xor_cells": int(np.count_nonzero(peer ^ ours)),
        "missed_cells": int(np.count_nonzero(ours & ~peer)),
        "extra_cells": int(np.count_nonzero(peer & ~ours)),
        "peer_occupied": int(np.count_nonzero(peer)),
    }


def map_twin_full(setup: MapSetup, repeat: int) -> dict[str, Any]:
    from twin.maps.render import build_map

    memory = MethodMemory.start()
    times, grid = timed_runs(lambda: build_map(setup.scene, setup.plan), repeat)
    return {**summary(times), **memory.report(), "occupied": int(grid.occupied().sum())}


def region_windows(occupied: np.ndarray, cells: int, count: int, seed: int) -> list[Any]:
    """``count`` windows of ``cells x cells`` centred on random occupied cells (fixed seed)."""
    from twin.maps.grid import Window

    where = np.argwhere(occupied)
    if len(where) == 0:
        return []
    rng = np.random.default_rng(seed)
    picks = where[rng.choice(len(where), size=min(count, len(where)), replace=False)]
    half = cells // 2
    return [
        Window(int(r) - half, int(c) - half, int(r) - half + cells, int(c) - half + cells) for r, c in picks
    ]


def map_twin_region(setup: MapSetup, repeat: int, *, prepared: bool = False) -> dict[str, Any]:
    """5 m x 5 m windows; ``prepared``: from the slab clipped once (``twin.maps.render.prepare_slab``)."""
    from twin.maps.grid import OCCUPIED
    from twin.maps.render import prepare_slab, render_window

    full = _twin_occupied(setup)
    frame = setup.plan.frame
    cells = round(REGION_M / frame.resolution_m)
    windows = region_windows(full, cells, REGION_WINDOWS, REGION_SEED)
    memory = MethodMemory.start()
    t0 = time.perf_counter()
    slab = prepare_slab(setup.scene, setup.plan) if prepared else None
    prepare_s = time.perf_counter() - t0
    medians: list[float] = []
    mismatched = 0
    for w in windows:
        times, data = timed_runs(lambda w=w: render_window(setup.scene, setup.plan, w, prepared=slab), repeat)
        medians.append(statistics.median(times))
        clipped = w.intersect(frame.full)
        expected = full[clipped.row0 : clipped.row1, clipped.col0 : clipped.col1]
        mismatched += int(np.count_nonzero((data == OCCUPIED) != expected))
    out: dict[str, Any] = {**memory.report(), "windows": len(windows), "window_cells": cells}
    if prepared:
        out["prepare_s"] = prepare_s
    if medians:
        out |= {"median_s": statistics.median(medians), "max_s": max(medians), "runs": repeat}
    out["xor_cells"] = mismatched  # against the same window of the full map: must be 0
    return out


def map_peer(setup: MapSetup, repeat: int, which: str) -> dict[str, Any]:
    import peers

    build = peers.trimesh_map if which == "trimesh" else peers.manifold_map
    memory = MethodMemory.start()
    results: list[peers.PeerResult] = []

    def run_once() -> float:
        results.append(build(setup.scene, setup.plan))
        return results[-1].seconds

    # The peers time themselves (manifold3d leaves its welding prep out), so repeat on their clocks.
    seconds: list[float] = []
    for _ in range(max(repeat, 1)):
        seconds.append(run_once())
        if sum(seconds) > PEER_BUDGET_S:
            break
    mem = memory.report()
    last = results[-1]
    ours = _twin_occupied(setup)
    out = {
        **summary(seconds),
        **mem,
        "prep_s": last.prep_seconds,
        **last.info,
        **_diff(last.occupied, ours),
        "occupied": int(np.count_nonzero(last.occupied)),
    }
    if last.kept is not None:
        out["twin_same_input_s"] = twin_on_subset(setup, last.kept, repeat)
    return out


def twin_on_subset(setup: MapSetup, ids: np.ndarray, repeat: int) -> float:
    """Median seconds of ``twin.maps.raster.rasterize_slab`` on just ``ids`` (as closed solids, full frame):
    our rasteriser on exactly the input a peer that drops elements kept."""
    from twin.maps.raster import rasterize_slab

    plan = setup.plan
    triangles, owner = setup.scene.elements.triangles_of(ids)
    closed = np.ones(len(ids), dtype=np.bool_)
    times, _ = timed_runs(
        lambda: rasterize_slab(triangles, owner, closed, plan.z_lo, plan.z_hi, plan.frame), repeat
    )
    return statistics.median(times)


def run_map(path: Path, skill: str, method: str, repeat: int) -> dict[str, Any]:
    setup = map_setup(path, skill)
    if method == "twin-full":
        result = map_twin_full(setup, repeat)
    elif method == "twin-region":
        result = map_twin_region(setup, repeat)
    elif method == "twin-region-prepared":
        result = map_twin_region(setup, repeat, prepared=True)
    elif method in ("trimesh", "manifold3d"):
        result = map_peer(setup, repeat, method)
    else:
        msg = f"unknown map method {method!r}; expected one of {', '.join(MAP_METHODS)}"
        raise ValueError(msg)
    return {"setup": setup.info, **result}
