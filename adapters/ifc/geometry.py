"""Mesh IFC products with ifcopenshell's geometry iterator, falling back between kernels.

The fast kernel (manifold, ~10x opencascade) meshes almost everything; the products it cannot mesh are
given to the next kernel, so no geometry is lost and no product is meshed twice. A kernel can also
*crash* the process on some models (manifold segfaults on the Duplex sample), so each kernel pass runs
in a forked child process that streams shapes back over a pipe: if the child dies, what it had not
delivered goes to the next kernel.

Meshes are local (``use-world-coords`` off) with the placement as a separate matrix; instances that
share a representation share one :class:`~twin.records.Mesh` (decoded once).

Example::

    result = mesh_products(f, products, kernels=("manifold", "opencascade"))
    geometry = result.geometry[product.id()]
"""

from __future__ import annotations

import faulthandler
import logging
import multiprocessing as mp
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any

import ifcopenshell
import ifcopenshell.geom
import ifcopenshell.util.shape
import numpy as np

from twin.records import Geometry, Mesh, check_placement, is_closed

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None]
DEFAULT_KERNELS = ("manifold", "opencascade")
_BATCH = 64


@dataclass(slots=True)
class MeshResult:
    """Geometry by product id (``ifc.id()``), which kernel meshed what, and what no kernel could mesh."""

    geometry: dict[int, Geometry] = field(default_factory=dict)
    kernel_of: dict[int, str] = field(default_factory=dict)
    unmeshed: list[int] = field(default_factory=list)
    crashed: list[str] = field(default_factory=list)


def weld(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices with identical coordinates; positions are unchanged, indices remapped."""
    if len(vertices) == 0:
        return vertices, faces
    unique, inverse = np.unique(vertices, axis=0, return_inverse=True)
    if len(unique) == len(vertices):
        return vertices, faces
    return unique, inverse.reshape(-1)[faces].astype(np.int32)


def _make_mesh(vertices: np.ndarray, faces: np.ndarray) -> Mesh:
    """A Mesh with its closedness; vertices are welded only when the kernel's output is not closed."""
    if is_closed(faces):
        return Mesh(vertices, faces, True)
    v, f = weld(vertices, faces)
    return Mesh(v, f, is_closed(f) if len(v) != len(vertices) else False)


def _settings() -> Any:
    s = ifcopenshell.geom.settings()
    s.set("use-world-coords", False)
    s.set("weld-vertices", True)
    return s


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
        batch: list[tuple[int, str, Any, Any, Any]] = []
        more = bool(it.initialize())
        while more:
            shape = it.get()
            geom = shape.geometry
            verts = faces = None
            if geom.id not in seen:  # instances sharing a representation: send the mesh once
                seen.add(geom.id)
                verts = np.asarray(ifcopenshell.util.shape.get_vertices(geom), dtype=np.float64).reshape(
                    -1, 3
                )
                faces = np.asarray(ifcopenshell.util.shape.get_faces(geom), dtype=np.int32).reshape(-1, 3)
            matrix = np.asarray(ifcopenshell.util.shape.get_shape_matrix(shape), dtype=np.float64)
            batch.append((int(shape.id), str(geom.id), verts, faces, matrix))
            if len(batch) >= _BATCH:
                conn.send(batch)
                batch = []
            more = bool(it.next())
        conn.send(batch)
        conn.send(None)
    except Exception as err:  # report, the parent falls back to the next kernel
        conn.send(f"{type(err).__name__}: {err}")
    finally:
        conn.close()


def mesh_products(
    f: Any,
    products: Sequence[Any],
    *,
    kernels: Sequence[str] = DEFAULT_KERNELS,
    threads: int = 2,
    progress: Progress | None = None,
) -> MeshResult:
    """Mesh ``products`` (ifcopenshell entities); each kernel gets only what the previous ones missed."""
    result = MeshResult()
    pending = {p.id() for p in products if getattr(p, "Representation", None) is not None}
    total, done = len(pending), 0
    ctx = mp.get_context("fork")
    for kernel in kernels:
        if not pending:
            break
        receiver, sender = ctx.Pipe(duplex=False)
        child = ctx.Process(
            target=_run_kernel, args=(f, sorted(pending), kernel, threads, sender), daemon=True
        )
        child.start()
        sender.close()
        # Drain first, process after: a parent busy welding would block the child on a full pipe.
        batches: list[list[tuple[int, str, Any, Any, Any]]] = []
        finished = False
        error: str | None = None
        while True:
            try:
                message = receiver.recv()
            except EOFError:
                break
            if message is None:
                finished = True
                break
            if isinstance(message, str):
                error = message
                break
            batches.append(message)
        meshes: dict[str, Mesh] = {}
        for batch in batches:
            for pid, geom_id, verts, faces, matrix in batch:
                if verts is not None and len(faces):  # an empty mesh is no mesh: the next kernel tries
                    meshes[geom_id] = _make_mesh(verts, faces)
                if pid in pending and geom_id in meshes:
                    result.geometry[pid] = Geometry(meshes[geom_id], check_placement(matrix))
                    result.kernel_of[pid] = kernel
                    pending.discard(pid)
                    done += 1
                    if progress is not None:
                        progress(done, total)
        receiver.close()
        child.join()
        if error is not None:
            log.warning(
                "Geometry kernel %s failed: %s; %d product(s) left for the next kernel",
                kernel,
                error,
                len(pending),
            )
        elif not finished:
            result.crashed.append(kernel)
            log.warning(
                "Geometry kernel %s crashed (exit code %s); %d product(s) left for the next kernel",
                kernel,
                child.exitcode,
                len(pending),
            )
        elif pending:
            log.info("%d product(s) not meshed by %s; trying the next kernel", len(pending), kernel)
    result.unmeshed = sorted(pending)
    if progress is not None and total:
        progress(total, total)
    return result
