"""Mesh IFC products with ifcopenshell's geometry iterator, falling back between kernels.

The fast kernel (manifold, ~10x opencascade) meshes almost everything; the products it cannot mesh are
given to the next kernel, so no geometry is lost and no product is meshed twice. Meshes are local
(``use-world-coords`` off) with the placement as a separate matrix; instances that share a
representation share one :class:`~twin.records.Mesh` (decoded once).

Example::

    result = mesh_products(f, products, kernels=("manifold", "opencascade"))
    geometry = result.geometry[product.id()]
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import ifcopenshell
import ifcopenshell.geom
import ifcopenshell.util.shape
import numpy as np

from twin.records import Geometry, Mesh, check_placement, is_closed

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None]
DEFAULT_KERNELS = ("manifold", "opencascade")


@dataclass(slots=True)
class MeshResult:
    """Geometry by product id (``ifc.id()``), and which kernel meshed what."""

    geometry: dict[int, Geometry] = field(default_factory=dict)
    kernel_of: dict[int, str] = field(default_factory=dict)
    unmeshed: list[int] = field(default_factory=list)


def _settings() -> Any:
    s = ifcopenshell.geom.settings()
    s.set("use-world-coords", False)
    s.set("weld-vertices", True)
    return s


def weld(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices with identical coordinates; positions are unchanged, indices remapped."""
    if len(vertices) == 0:
        return vertices, faces
    unique, inverse = np.unique(vertices, axis=0, return_inverse=True)
    if len(unique) == len(vertices):
        return vertices, faces
    return unique, inverse.reshape(-1)[faces].astype(np.int32)


def _mesh_of(shape: Any, cache: dict[str, Mesh]) -> Mesh:
    geom = shape.geometry
    mesh = cache.get(geom.id)
    if mesh is None:
        verts = np.asarray(ifcopenshell.util.shape.get_vertices(geom), dtype=np.float64).reshape(-1, 3)
        faces = np.asarray(ifcopenshell.util.shape.get_faces(geom), dtype=np.int32).reshape(-1, 3)
        verts, faces = weld(verts, faces)
        mesh = Mesh(verts, faces, is_closed(faces))
        cache[geom.id] = mesh
    return mesh


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
    pending = {p.id(): p for p in products if getattr(p, "Representation", None) is not None}
    total = len(pending)
    done = 0
    cache: dict[str, Mesh] = {}
    for kernel in kernels:
        if not pending:
            break
        try:
            it = ifcopenshell.geom.iterator(
                _settings(), f, threads, include=list(pending.values()), geometry_library=kernel
            )
        except Exception as err:  # an unknown kernel name or a broken build of one
            log.warning("Geometry kernel %r is unavailable: %s", kernel, err)
            continue
        cache.clear()  # geometry ids are per iterator run
        ok = it.initialize()
        while ok:
            shape = it.get()
            pid = int(shape.id)
            if pid in pending:
                mesh = _mesh_of(shape, cache)
                placement = check_placement(ifcopenshell.util.shape.get_shape_matrix(shape))
                result.geometry[pid] = Geometry(mesh, placement)
                result.kernel_of[pid] = kernel
                del pending[pid]
                done += 1
                if progress is not None:
                    progress(done, total)
            ok = it.next()
        if pending and kernel != kernels[-1]:
            log.info("%d product(s) not meshed by %s; trying the next kernel", len(pending), kernel)
    result.unmeshed = sorted(pending)
    return result
