"""One kernel pass in a child process: mesh a set of products with ifcopenshell's geometry iterator and
stream the shapes back over a pipe, each as a ready :class:`~twin.records.Mesh`.

The child makes the meshes itself (closedness, welding, orientation), so the calling process only
collects. A shape is ``(product id, geometry id, mesh | None, the mesh's reach, placement matrix)``;
instances that share a representation get the mesh once, then ``None`` with the same geometry id.

The child answers a ``"stop"`` sent on the pipe between two batches of shapes: it has sent what it
meshed, it sends :data:`STOPPED` and leaves; the parent gives what is left to other children
(:mod:`adapters.ifc.geometry`). A kernel error is sent as a text; a kernel crash closes the pipe.

Example::

    receiver, sender = mp.get_context("fork").Pipe()
    child = ctx.Process(target=run_kernel, args=(f, ids, "manifold", sender), daemon=True)
"""

from __future__ import annotations

import faulthandler
import time
from multiprocessing.connection import Connection
from typing import Any

import ifcopenshell
import ifcopenshell.geom
import ifcopenshell.util.shape
import numpy as np

from twin.errors import ModelError
from twin.meshops import are_closed, is_closed, orient_faces
from twin.records import Mesh

Shape = tuple[int, str, Mesh | None, float, Any]  # product, geometry id, new mesh | None, its reach, matrix
STOP = "stop"
STOPPED = "stopped"
_BATCH_SHAPES = 32  # small: what a crashing kernel had meshed is kept; a stop is heard between batches
_BATCH_SECONDS = 0.05

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


def make_mesh(vertices: np.ndarray, faces: np.ndarray) -> Mesh:
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


def iterator_settings() -> Any:
    """Local meshes (the placement apart) with welded vertices: what every kernel pass uses."""
    s = ifcopenshell.geom.settings()
    s.set("use-world-coords", False)
    s.set("weld-vertices", True)
    return s


def _raw(geom: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(n, 3) float64`` vertices and ``(m, 3) int32`` faces of an iterator geometry."""
    verts = np.asarray(ifcopenshell.util.shape.get_vertices(geom), dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(ifcopenshell.util.shape.get_faces(geom), dtype=np.int32).reshape(-1, 3)
    return verts, faces


def _meshes(raw: list[tuple[np.ndarray, np.ndarray]]) -> list[tuple[Mesh | None, float]]:
    """(the Mesh, its largest absolute coordinate) of each raw mesh; (None, 0) if it has no triangles or
    invalid coordinates, so that the next kernel tries. Closedness is tested for all at once (the
    common case, a closed solid, then needs nothing more)."""
    closed = are_closed([faces for _, faces in raw])
    out: list[tuple[Mesh | None, float]] = []
    for (verts, faces), is_solid in zip(raw, closed, strict=True):
        if not len(faces):
            out.append((None, 0.0))
            continue
        try:
            mesh = Mesh(verts, faces, True) if is_solid else make_mesh(verts, faces)
        except ModelError:  # NaN or infinite coordinates
            out.append((None, 0.0))
            continue
        out.append((mesh, float(np.abs(mesh.vertices).max(initial=0.0))))
    return out


def _send(conn: Connection, batch: list[tuple[int, str, tuple[np.ndarray, np.ndarray] | None, Any]]) -> None:
    made = iter(_meshes([raw for _, _, raw, _ in batch if raw is not None]))
    shapes: list[Shape] = []
    for pid, geom_id, raw, matrix in batch:
        mesh, reach = next(made) if raw is not None else (None, 0.0)
        shapes.append((pid, geom_id, mesh, reach, matrix))
    conn.send(shapes)


def _stop_asked(conn: Connection) -> bool:
    return bool(conn.poll()) and conn.recv() == STOP


def run_kernel(f: Any, ids: list[int], kernel: str, conn: Connection) -> None:
    """Child process: mesh ``ids`` with ``kernel`` (one thread); send batches of shapes, then None, or
    :data:`STOPPED` when the parent asked it to stop, or a text naming the error."""
    faulthandler.disable()  # a kernel crash is expected and handled by the parent: no dump on stderr
    try:
        it = ifcopenshell.geom.iterator(
            iterator_settings(),
            f,
            1,
            include=[f.by_id(i) for i in ids],
            geometry_library=kernel,  # type: ignore[arg-type]  # validated by the iterator itself
        )
        seen: set[str] = set()
        batch: list[tuple[int, str, tuple[np.ndarray, np.ndarray] | None, Any]] = []
        sent = time.monotonic()
        more = bool(it.initialize())
        while more:
            shape = it.get()
            geom = shape.geometry
            raw = None
            if geom.id not in seen:  # instances sharing a representation: send the mesh once
                seen.add(geom.id)
                raw = _raw(geom)
            matrix = np.asarray(ifcopenshell.util.shape.get_shape_matrix(shape), dtype=np.float64)
            batch.append((int(shape.id), str(geom.id), raw, matrix))
            if len(batch) >= _BATCH_SHAPES or time.monotonic() - sent > _BATCH_SECONDS:
                _send(conn, batch)
                batch, sent = [], time.monotonic()
                if _stop_asked(conn):
                    conn.send(STOPPED)
                    return
            more = bool(it.next())
        _send(conn, batch)
        conn.send(None)
    except Exception as err:  # report, the parent falls back to the next kernel
        conn.send(f"{type(err).__name__}: {err}")
    finally:
        conn.close()
