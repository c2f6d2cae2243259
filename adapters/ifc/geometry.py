"""Mesh IFC products with ifcopenshell's geometry iterator, falling back between kernels.

The fast kernel (manifold, ~10x opencascade) meshes almost everything; the products it cannot mesh are
given to the next kernel, so no geometry is lost and no product is meshed twice. A kernel can also
*crash* the process on some models (manifold segfaults on the Duplex sample), so each kernel pass runs
in a child process forked from the calling thread, which streams shapes back over a pipe that a
thread drains: if the child dies or stalls, what it had not delivered goes to the next kernel.

Parallelism is by processes, not by the iterator's own threads: each child runs a single-threaded
iterator (with two threads, ifcopenshell 0.9's iterator spends 35 % more CPU on Janesville and 5x
more on a generated 12,000-element building), and the products are spread over ``threads`` children
(:func:`_shard_counts`). A child also makes the :class:`~twin.records.Mesh` (closedness, welding,
orientation), so the calling process only collects.

Meshes are local (``use-world-coords`` off) with the placement as a separate matrix; instances that
share a representation share one :class:`~twin.records.Mesh` (decoded once).

Example::

    with start_meshing(f, products, kernels=("manifold", "opencascade")) as job:
        ...                                   # read the structure meanwhile
        result = job.result()
    geometry = result.geometry[product.id()]
"""

from __future__ import annotations

import faulthandler
import logging
import multiprocessing as mp
import threading
import time
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from types import TracebackType
from typing import Any, Self

import ifcopenshell
import ifcopenshell.geom
import ifcopenshell.util.shape
import numpy as np

from adapters.ifc.kernel_choice import REFERENCE_KERNEL
from twin.errors import ModelError
from twin.meshops import is_closed, orient_faces
from twin.records import Geometry, Mesh, check_placement

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None]
Shape = tuple[int, str, Mesh | None, float, Any]  # product, geometry id, new mesh | None, its reach, matrix
DEFAULT_KERNELS = ("manifold", "opencascade")
_BATCH_SHAPES = 8  # small: what a crashing kernel had meshed is kept
_BATCH_SECONDS = 0.05
STALL_SECONDS = 300.0
MAX_COORDINATE_M = 1e8
"""A body farther than this from the origin (or not finite) is refused: the bad placement or
coordinates of a broken file, which would stretch a storey's map over the whole planet."""


@dataclass(slots=True)
class MeshResult:
    """Geometry by product id (``ifc.id()``), which kernel meshed what, and what no kernel could mesh.

    ``fallbacks`` are the products meshed by another kernel than the first of their route.
    """

    geometry: dict[int, Geometry] = field(default_factory=dict)
    kernel_of: dict[int, str] = field(default_factory=dict)
    unmeshed: list[int] = field(default_factory=list)
    fallbacks: set[int] = field(default_factory=set)


NEAR_WELD_M = 1e-9
"""Second try at welding an open mesh: vertices this close are one vertex. OpenCASCADE's boolean
results (a wall with its openings cut out) can leave the two copies of a vertex 1e-12 m apart, so a
bitwise weld leaves the solid open and its section unfilled in the maps (LargeBuilding's outside wall
1F6umJ5H50aeL3A1As_wTm). Only a second try: it also joins touching bodies of one element (a skylight's
frame and curb) at edges that four faces then share, which the bitwise weld keeps apart."""


def weld(vertices: np.ndarray, faces: np.ndarray, *, near_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices with identical coordinates; positions are unchanged, indices remapped.

    With ``near_m``, vertices in one grid cell of that pitch are merged (into the first copy), and
    faces that collapse to a line or a point are dropped.
    """
    if len(vertices) == 0:
        return vertices, faces
    if near_m <= 0:
        unique, inverse = np.unique(vertices, axis=0, return_inverse=True)
        if len(unique) == len(vertices):
            return vertices, faces
        return unique, inverse.reshape(-1)[faces].astype(np.int32)
    _, first, inverse = np.unique(np.round(vertices / near_m), axis=0, return_index=True, return_inverse=True)
    if len(first) == len(vertices):
        return vertices, faces
    f = inverse.reshape(-1)[faces].astype(np.int32)
    kept = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    return vertices[first], f[kept]


def _closed_mesh(vertices: np.ndarray, faces: np.ndarray) -> Mesh | None:
    """The mesh as a consistently oriented solid (faces flipped where needed), or None if not watertight."""
    if is_closed(faces):
        return Mesh(vertices, faces, True)
    oriented = orient_faces(faces)
    return Mesh(vertices, oriented, True) if oriented is not None else None


def _make_mesh(vertices: np.ndarray, faces: np.ndarray) -> Mesh:
    """A Mesh with its closedness. Only when the kernel's output is not a consistently oriented solid
    are its vertices welded (bitwise, then within ``NEAR_WELD_M``) and, if it is watertight, its faces
    re-oriented."""
    if is_closed(faces):
        return Mesh(vertices, faces, True)
    v, f = weld(vertices, faces)
    closed = _closed_mesh(v, f)
    if closed is None:
        closed = _closed_mesh(*weld(v, f, near_m=NEAR_WELD_M))
    return closed if closed is not None else Mesh(v, f, False)


def _geometry(mesh: Mesh, matrix: Any, reach: float) -> Geometry:
    """``mesh`` placed by ``matrix``; raise ModelError when the result is not finite or absurdly far.

    ``reach`` is the largest absolute vertex coordinate of the mesh (NaN if any is NaN).
    """
    placement = check_placement(matrix)
    bound = float(np.abs(placement[:3, :3]).sum(axis=1).max()) * reach + float(np.abs(placement[:3, 3]).max())
    if not bound <= MAX_COORDINATE_M:  # NaN too
        msg = f"its body reaches {bound:.3g} m from the origin (limit {MAX_COORDINATE_M:.0e} m)"
        raise ModelError(msg)
    return Geometry(mesh, placement)


def _settings() -> Any:
    s = ifcopenshell.geom.settings()
    s.set("use-world-coords", False)
    s.set("weld-vertices", True)
    return s


def _child_mesh(geom: Any) -> tuple[Mesh | None, float]:
    """(the Mesh of an iterator geometry, its largest absolute coordinate); (None, 0) if it has no
    triangles or invalid coordinates, so that the next kernel tries."""
    verts = np.asarray(ifcopenshell.util.shape.get_vertices(geom), dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(ifcopenshell.util.shape.get_faces(geom), dtype=np.int32).reshape(-1, 3)
    if not len(faces):
        return None, 0.0
    try:
        mesh = _make_mesh(verts, faces)
    except ModelError:  # NaN or infinite coordinates
        return None, 0.0
    return mesh, float(np.abs(mesh.vertices).max(initial=0.0))


def _run_kernel(f: Any, ids: list[int], kernel: str, threads: int, conn: Connection) -> None:
    """Child process: mesh ``ids`` with ``kernel``; send batches of shapes, then None."""
    faulthandler.disable()  # a kernel crash is expected and handled by the parent: no dump on stderr
    try:
        it = ifcopenshell.geom.iterator(
            _settings(),
            f,
            threads,
            include=[f.by_id(i) for i in ids],
            geometry_library=kernel,  # type: ignore[arg-type]  # validated by the iterator itself
        )
        seen: set[str] = set()
        batch: list[Shape] = []
        sent = time.monotonic()
        more = bool(it.initialize())
        while more:
            shape = it.get()
            geom = shape.geometry
            mesh, reach = None, 0.0
            if geom.id not in seen:  # instances sharing a representation: send the mesh once
                seen.add(geom.id)
                mesh, reach = _child_mesh(geom)
            matrix = np.asarray(ifcopenshell.util.shape.get_shape_matrix(shape), dtype=np.float64)
            batch.append((int(shape.id), str(geom.id), mesh, reach, matrix))
            if len(batch) >= _BATCH_SHAPES or time.monotonic() - sent > _BATCH_SECONDS:
                conn.send(batch)
                batch, sent = [], time.monotonic()
            more = bool(it.next())
        conn.send(batch)
        conn.send(None)
    except Exception as err:  # report, the parent falls back to the next kernel
        conn.send(f"{type(err).__name__}: {err}")
    finally:
        conn.close()


class _KernelRun:
    """One kernel pass: a child forked from the calling thread, its pipe drained by a thread."""

    def __init__(
        self, f: Any, ids: list[int], kernel: str, threads: int, on_shapes: Callable[[int], None]
    ) -> None:
        ctx = mp.get_context("fork")
        self.kernel = kernel
        self._receiver, sender = ctx.Pipe(duplex=False)
        self._child = ctx.Process(target=_run_kernel, args=(f, ids, kernel, threads, sender), daemon=True)
        self._child.start()
        sender.close()
        self._on_shapes = on_shapes
        self.meshed: list[Shape] = []
        self.finished = False
        self.error: str | None = None
        self._thread = threading.Thread(target=self._drain, name=f"twin-mesh-{kernel}", daemon=True)
        self._thread.start()

    def _drain(self) -> None:
        while True:
            if not self._receiver.poll(STALL_SECONDS):
                self.error = f"no shape for {STALL_SECONDS:.0f} s (stalled)"
                self._child.kill()
                break
            try:
                message = self._receiver.recv()
            except EOFError:
                break
            if message is None:
                self.finished = True
                break
            if isinstance(message, str):
                self.error = message
                break
            self.meshed.extend(message)
            self._on_shapes(len(message))
        self._receiver.close()

    def wait(self) -> None:
        self._thread.join()
        self._child.join()

    def kill(self) -> None:
        if self._child.is_alive():
            self._child.kill()
        self._thread.join()
        self._child.join()

    @property
    def exitcode(self) -> int | None:
        return self._child.exitcode


class _Route:
    """Products meshed by one chain of kernels, tried in order on what the previous one left."""

    def __init__(self, ids: set[int], kernels: Sequence[str], threads: int) -> None:
        self.pending = set(ids)
        self.kernels = list(kernels)
        self.first = self.kernels[0] if self.kernels else ""
        self.threads = threads
        self.run: _KernelRun | None = None


def _shard_counts(routed: int, rest: int, threads: int) -> tuple[int, int]:
    """How many children mesh the routed products and the rest, given ``threads`` cores.

    Every non-empty route gets at least one child. With both routes and two cores, one child each: the
    calling process reads the structure meanwhile, so a third child only adds CPU (dealing the rest
    of the 12,000-element building over two manifold children cost 0.3 s more CPU, no less time).
    """
    cores = max(threads, 1)
    if not routed or not rest:
        return (cores if routed else 0), (cores if rest else 0)
    n_routed = max(1, min(cores - 1, round(cores * routed / (routed + rest))))
    return n_routed, max(1, cores - n_routed)


def _shards(ids: set[int], n: int) -> list[set[int]]:
    """``ids`` dealt round-robin in id order into ``n`` sets (contiguous ranges are unequal work: the
    file groups products by kind)."""
    ordered = sorted(ids)
    return [set(ordered[i :: max(n, 1)]) for i in range(max(n, 1))]


class MeshingJob:
    """Meshing in progress: each route's first kernel starts at once; :meth:`result` finishes the rest.

    Products whose body the fast kernel gets wrong (:func:`~adapters.ifc.kernel_choice.reference_reason`)
    go to the reference kernel first, in children of their own that run beside the fast one's; each
    route is dealt into shards, one single-threaded child each (:func:`_shard_counts`).
    Use it as a context manager: leaving it on an error (or Ctrl-C) kills the kernel processes.
    """

    def __init__(
        self,
        f: Any,
        products: Sequence[Any],
        *,
        kernels: Sequence[str],
        threads: int,
        progress: Progress | None,
        routed: Sequence[Any] = (),
        skip: Collection[int] = (),
    ) -> None:
        self._f = f
        self._progress = progress
        with_body = {p.id() for p in products if getattr(p, "Representation", None) is not None}
        self._skipped = sorted(with_body & set(skip))
        with_body -= set(skip)
        routed_ids = {p.id() for p in routed} & with_body if REFERENCE_KERNEL in kernels else set()
        self._total = len(with_body)
        self._received = 0
        self._lock = threading.Lock()
        self._result = MeshResult()
        self._refused: set[int] = set()
        reference_first = [REFERENCE_KERNEL, *(k for k in kernels if k != REFERENCE_KERNEL)]
        rest_ids = with_body - routed_ids
        n_routed, n_rest = _shard_counts(len(routed_ids), len(rest_ids), threads)
        self._routes = [
            _Route(shard, chain, 1)
            for ids, chain, n in ((routed_ids, reference_first, n_routed), (rest_ids, kernels, n_rest))
            for shard in _shards(ids, n)
            if shard
        ]
        for route in self._routes:
            self._next_kernel(route)

    def _shapes_arrived(self, n: int) -> None:
        with self._lock:
            self._received = min(self._received + n, self._total)
            done = self._received
        if self._progress is not None:
            self._progress(done, self._total)

    def _next_kernel(self, route: _Route) -> None:
        route.run = None
        if route.pending and route.kernels:
            kernel = route.kernels.pop(0)
            route.run = _KernelRun(
                self._f, sorted(route.pending), kernel, route.threads, self._shapes_arrived
            )

    def _collect(self, route: _Route, run: _KernelRun) -> None:
        run.wait()
        meshes: dict[str, Mesh] = {}
        reach: dict[str, float] = {}
        result = self._result
        for pid, geom_id, mesh, mesh_reach, matrix in run.meshed:
            if mesh is not None:  # an empty mesh is no mesh: the next kernel tries
                meshes[geom_id] = mesh
                reach[geom_id] = mesh_reach
            if pid in route.pending and geom_id in meshes:
                try:
                    result.geometry[pid] = _geometry(meshes[geom_id], matrix, reach[geom_id])
                except ModelError as err:  # left pending: the next kernel tries, then it is unmeshed
                    if pid not in self._refused:
                        self._refused.add(pid)
                        product = self._f.by_id(pid)
                        log.warning(
                            "%s %s %s: %s; its geometry is refused",
                            product.is_a(),
                            product.GlobalId,
                            product.Name or "",
                            err,
                        )
                    continue
                result.kernel_of[pid] = run.kernel
                if run.kernel != route.first:
                    result.fallbacks.add(pid)
                route.pending.discard(pid)
        with self._lock:
            self._received = len(result.geometry)
        left = len(route.pending)
        if run.error is not None:
            log.warning(
                "Geometry kernel %s failed: %s; %d product(s) left for the next kernel",
                run.kernel,
                run.error,
                left,
            )
        elif not run.finished:
            log.warning(
                "Geometry kernel %s crashed (exit code %s); %d product(s) left for the next kernel",
                run.kernel,
                run.exitcode,
                left,
            )
        elif left:
            log.info("%d product(s) not meshed by %s; trying the next kernel", left, run.kernel)

    def result(self) -> MeshResult:
        """Wait for the running kernels, then run the fallbacks on what is left; return everything."""
        for route in self._routes:
            while route.run is not None:
                self._collect(route, route.run)
                self._next_kernel(route)
        self._result.unmeshed = sorted(
            [*self._skipped, *(pid for route in self._routes for pid in route.pending)]
        )
        if self._progress is not None and self._total:
            self._progress(self._total, self._total)
        return self._result

    def cancel(self) -> None:
        for route in self._routes:
            if route.run is not None:
                route.run.kill()
                route.run = None

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.cancel()


def start_meshing(
    f: Any,
    products: Sequence[Any],
    *,
    kernels: Sequence[str] = DEFAULT_KERNELS,
    threads: int = 2,
    progress: Progress | None = None,
    routed: Sequence[Any] = (),
    skip: Collection[int] = (),
) -> MeshingJob:
    """Start meshing ``products`` (ifcopenshell entities) in the background; see :class:`MeshingJob`.

    ``routed`` products (a subset) go to the reference kernel first, when it is among ``kernels``.
    Products whose id is in ``skip`` are not meshed: they are listed as unmeshed. ``threads`` is the
    number of cores to use: the number of kernel children, or more when both routes need one.
    """
    return MeshingJob(
        f, products, kernels=kernels, threads=threads, progress=progress, routed=routed, skip=skip
    )
