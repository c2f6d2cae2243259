"""One kernel pass in a child process: mesh a set of products with ifcopenshell's geometry iterator and
stream the shapes back over a pipe, each as a ready :class:`~twin.records.Mesh`.

The child makes the meshes itself (closedness, welding, orientation, whether the body is a solid:
:mod:`adapters.ifc.body_kind`, or a surface that closes around a volume: :func:`make_mesh`) and
checks the placements, so the calling process only collects. A :data:`Shape` carries a mesh the
first time, then ``None`` for the instances sharing it.

With ``routing`` set, the child first asks :class:`~adapters.ifc.kernel_choice.KernelChoice` which of its
elements the reference kernel must mesh, sends their ids (:data:`ROUTED`) and leaves them to other
children: the routing then costs no time before the children start, and is shared by the cores.

The child looks at a stop flag it shares with the parent after each shape: once set, it sends what
it has meshed and :data:`STOPPED`, and leaves; the parent gives what is left to other children
(:mod:`adapters.ifc.geometry`). A kernel error is sent as a text; a kernel crash closes the pipe.

Example::

    ctx = mp.get_context("fork")
    receiver, sender = ctx.Pipe(duplex=False)
    stop = ctx.RawValue("b", 0)
    child = ctx.Process(target=run_kernel, args=(f, ids, "manifold", sender, stop), daemon=True)
"""

from __future__ import annotations

import faulthandler
import gc
import time
from collections.abc import Iterator
from multiprocessing.connection import Connection
from typing import Any, Protocol

import ifcopenshell
import ifcopenshell.geom
import ifcopenshell.util.shape
import numpy as np

from adapters.ifc.attributes import Attributes, Representations
from adapters.ifc.body_kind import BodyKind
from adapters.ifc.errors import ENTITY_ERRORS
from adapters.ifc.kernel_choice import KernelChoice
from twin.errors import ModelError
from twin.maps.meshops import (
    are_closed,
    closes_around,
    is_closed,
    orient_faces,
    orient_outward,
    orient_shells,
    seal_t_junctions,
    signed_volumes,
)
from twin.records import Mesh, check_placement

Shape = tuple[int, str, Mesh | None, np.ndarray | None, bool, str | None, str | None]
"""Product id, geometry id, the mesh (the first time this child meshes the geometry, else None), the
checked placement (None if refused), whether the product's body is a solid (or a surface whose mesh
closes around a volume), why the placement was refused, why the body could not be inspected."""
MAX_COORDINATE_M = 1e8
"""A body farther than this from the origin (or not finite) is refused: the bad placement or
coordinates of a broken file, which would stretch a storey's map over the whole planet."""
STOPPED = "stopped"
ROUTED = "routed"
"""First message of a routing child: ``(ROUTED, ids the reference kernel meshes first, [(id, why its
body cannot be inspected)])``."""
_BATCH_SHAPES = 32  # small: what a crashing kernel had meshed is kept
_BATCH_SECONDS = 0.05

NEAR_WELD_M = 1e-9
"""Second try at welding an open mesh: vertices this close are one vertex. OpenCASCADE's boolean
results (a wall with its openings cut out) can leave the two copies of a vertex 1e-12 m apart, so a
bitwise weld leaves the solid open and its section unfilled in the maps (LargeBuilding's outside wall
1F6umJ5H50aeL3A1As_wTm). Only a second try: it also joins touching bodies of one element (a skylight's
frame and curb) at edges that four faces then share, which the bitwise weld keeps apart."""


def _unique_rows(v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``np.unique(v, axis=0, return_index=True, return_inverse=True)`` for ``(n, 3)`` rows, the same
    arrays (rows in lexicographic order, the first index of each), about 5x faster: a lexsort of the
    columns instead of a sort of the rows as records."""
    order = np.lexsort((v[:, 2], v[:, 1], v[:, 0]))
    ordered = v[order]
    new = np.ones(len(v), dtype=bool)
    new[1:] = np.any(ordered[1:] != ordered[:-1], axis=1)
    inverse = np.empty(len(v), dtype=np.intp)
    inverse[order] = np.cumsum(new) - 1
    return ordered[new], order[new], inverse


def weld(vertices: np.ndarray, faces: np.ndarray, *, near_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices with identical coordinates; positions are unchanged, indices remapped.

    With ``near_m``, vertices in one grid cell of that pitch are merged (into the first copy), and
    faces that collapse to a line or a point are dropped.
    """
    if len(vertices) == 0:
        return vertices, faces
    if near_m <= 0:
        unique, _, inverse = _unique_rows(vertices)
        if len(unique) == len(vertices):
            return vertices, faces
        return unique, inverse[faces].astype(np.int32)
    _, first, inverse = _unique_rows(np.round(vertices / near_m))
    if len(first) == len(vertices):
        return vertices, faces
    f = inverse[faces].astype(np.int32)
    kept = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    return vertices[first], f[kept]


def _closed_mesh(vertices: np.ndarray, faces: np.ndarray, solid: bool) -> Mesh | None:
    """The mesh as a consistently oriented solid (faces flipped where needed), or None if not watertight."""
    if is_closed(faces):
        return Mesh(vertices, faces, True, solid)
    oriented = orient_faces(faces)
    return Mesh(vertices, oriented, True, solid) if oriented is not None else None


def make_mesh(
    vertices: np.ndarray, faces: np.ndarray, *, solid: bool = False, known_open: bool = False
) -> Mesh:
    """A Mesh with its closedness and ``solid``: what the file says the body is, or whether its faces
    close around a volume. Only when the kernel's output is not a consistently oriented solid
    (``known_open``: already found not to be) are its vertices welded (bitwise, then within
    ``NEAR_WELD_M``) and, if it is watertight, its faces re-oriented.

    A surface (not a solid by the file) whose open mesh closes around a volume up to T-junctions
    (:func:`~twin.maps.meshops.closes_around`: a surface model whose faces enclose a lift's car) is a solid:
    its T-junctions are split and the faces of each of its shells oriented alike (a surface model
    need not orient them), which makes it watertight; failing that it stays open, marked solid."""
    if not known_open and is_closed(faces):
        return Mesh(vertices, faces, True, solid)
    v, f = weld(vertices, faces)
    closed = _closed_mesh(v, f, solid)
    if closed is None:
        closed = _closed_mesh(*weld(v, f, near_m=NEAR_WELD_M), solid)
    if closed is not None:
        return closed
    if solid or not closes_around(v, f):
        return Mesh(v, f, False, solid)
    oriented = orient_shells(seal_t_junctions(v, f))
    return Mesh(v, oriented, True, True) if oriented is not None else Mesh(v, f, False, True)


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


_Raw = tuple[np.ndarray, np.ndarray, bool]  # vertices, faces, solid


def _meshes(raw: list[_Raw]) -> list[tuple[Mesh | None, float]]:
    """(the Mesh, its largest absolute coordinate) of each raw ``(vertices, faces, solid)``; (None, 0)
    if it has no triangles or invalid coordinates, so that the next kernel tries. Closedness is tested
    for all at once (the common case, a closed solid, then needs nothing more), and so is the turn of
    the shells of closed surfaces and of closed solids that come inside out: each is turned outward
    (:func:`~twin.maps.meshops.orient_outward`)."""
    closed = are_closed([faces for _, faces, _ in raw])
    out: list[tuple[Mesh | None, float]] = []
    for (verts, faces, solid), is_closed_ in zip(raw, closed, strict=True):
        if not len(faces):
            out.append((None, 0.0))
            continue
        try:
            mesh = (
                Mesh(verts, faces, True, solid)
                if is_closed_
                else make_mesh(verts, faces, solid=solid, known_open=True)
            )
        except ModelError:  # NaN or infinite coordinates
            out.append((None, 0.0))
            continue
        out.append((mesh, float(np.abs(mesh.vertices).max(initial=0.0))))
    # a kernel's solid comes outward, unless it is inside out; a surface's shells may turn either way
    closed_meshes = [(k, m) for k, (m, _) in enumerate(out) if m is not None and m.closed]
    volumes = signed_volumes([(m.vertices, m.faces) for _, m in closed_meshes])
    closed_meshes = [km for km, vol in zip(closed_meshes, volumes, strict=True) if vol < 0 or not km[1].solid]
    outward = orient_outward([(m.vertices, m.faces) for _, m in closed_meshes])
    for (k, m), faces in zip(closed_meshes, outward, strict=True):
        if faces is not m.faces:
            out[k] = (Mesh(m.vertices, faces, m.closed, m.solid), out[k][1])
    return out


def placed(matrix: Any, reach: float) -> np.ndarray:
    """The placement ``matrix`` checked (:func:`~twin.records.check_placement`); ModelError when the body
    (its largest absolute local coordinate ``reach``, NaN if any is NaN) lands absurdly far."""
    placement = check_placement(matrix)
    bound = float(np.abs(placement[:3, :3]).sum(axis=1).max()) * reach + float(np.abs(placement[:3, 3]).max())
    if not bound <= MAX_COORDINATE_M:  # NaN too
        msg = f"its body reaches {bound:.3g} m from the origin (limit {MAX_COORDINATE_M:.0e} m)"
        raise ModelError(msg)
    return placement


class _Batch:
    """Shapes meshed and not yet sent: made into Meshes, placed and sent together."""

    def __init__(self) -> None:
        self.items: list[
            tuple[int, str, tuple[np.ndarray, np.ndarray, bool] | None, Any, bool, str | None]
        ] = []
        self.reach: dict[str, float] = {}  # geometry id -> its mesh's largest absolute coordinate
        self.encloses: set[str] = set()  # geometry ids of surfaces whose open meshes close around a volume

    def send(self, conn: Connection) -> None:
        made = iter(_meshes([raw for _, _, raw, _, _, _ in self.items if raw is not None]))
        meshes: list[Mesh | None] = []
        for _, geom_id, raw, _, _, _ in self.items:
            mesh = None
            if raw is not None:
                mesh, reach = next(made)
                if mesh is not None:
                    self.reach[geom_id] = reach
                    if mesh.solid and not raw[2]:
                        self.encloses.add(geom_id)
            meshes.append(mesh)
        placements = _placements(
            [
                (matrix, self.reach[geom_id])
                for _, geom_id, _, matrix, _, _ in self.items
                if geom_id in self.reach
            ]
        )
        shapes: list[Shape] = []
        for (pid, geom_id, _, _, solid, note), mesh in zip(self.items, meshes, strict=True):
            placement, refused = next(placements) if geom_id in self.reach else (None, None)
            shapes.append((pid, geom_id, mesh, placement, solid or geom_id in self.encloses, refused, note))
        conn.send(shapes)
        self.items = []


def _placements(placed_: list[tuple[Any, float]]) -> Iterator[tuple[np.ndarray | None, str | None]]:
    """:func:`placed` of each ``(matrix, reach)`` as (the placement, None) or (None, why it is refused),
    checked all at once: only a matrix that fails is checked again alone, to name what is wrong."""
    if not placed_:
        return iter(())
    try:
        m = np.array([matrix for matrix, _ in placed_], dtype=np.float64)
    except ValueError:  # matrices of different shapes
        m = np.empty((0, 4, 4))
    if m.shape != (len(placed_), 4, 4):
        return (_placed_alone(matrix, reach) for matrix, reach in placed_)
    reach = np.array([r for _, r in placed_], dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        last = np.abs(m[:, 3, :3]).sum(axis=1) + np.abs(m[:, 3, 3] - 1.0)
        bound = np.abs(m[:, :3, :3]).sum(axis=2).max(axis=1) * reach + np.abs(m[:, :3, 3]).max(axis=1)
        ok = np.isfinite(m).all(axis=(1, 2)) & (last <= 1e-9) & (bound <= MAX_COORDINATE_M)
    return ((m[i], None) if ok[i] else _placed_alone(matrix, r) for i, (matrix, r) in enumerate(placed_))


def _placed_alone(matrix: Any, reach: float) -> tuple[np.ndarray | None, str | None]:
    try:
        return placed(matrix, reach), None
    except ModelError as err:
        return None, str(err)


def _body_is_solid(kind: BodyKind, product: Any) -> tuple[bool, str | None]:
    """(whether ``product``'s body is a solid, why it could not be told)."""
    try:
        return kind.is_solid(product), None
    except ENTITY_ERRORS as err:
        return False, f"its body cannot be inspected ({type(err).__name__}: {err})"


class StopFlag(Protocol):
    """A flag shared with the parent (``multiprocessing.RawValue("b")``): non-zero asks the child to stop."""

    value: int


def route(products: dict[int, Any], router: KernelChoice) -> tuple[list[int], list[tuple[int, str]]]:
    """(the ids of the elements among ``products`` that the reference kernel meshes first, (id, why)
    of those whose body cannot be inspected: they are not routed). Spaces are never routed."""
    routed: list[int] = []
    notes: list[tuple[int, str]] = []
    is_element: dict[str, bool] = {}
    for pid, product in products.items():
        name = product.is_a()
        element = is_element.get(name)
        if element is None:
            element = is_element[name] = bool(product.is_a("IfcElement"))
        if not element:
            continue
        try:
            if router.reason(product) is not None:
                routed.append(pid)
        except ENTITY_ERRORS as err:
            notes.append((pid, f"its body cannot be inspected ({type(err).__name__}: {err})"))
    return routed, notes


def run_kernel(
    f: Any, ids: list[int], kernel: str, conn: Connection, stop: StopFlag, *, routing: bool = False
) -> None:
    """Child process: mesh ``ids`` with ``kernel`` (one thread); send batches of shapes, then None, or
    :data:`STOPPED` when the parent set ``stop`` (read after each shape), or a text naming the error.
    With ``routing``, first send :data:`ROUTED` and leave those products out."""
    gc.disable()  # inherited objects: a collection would walk (and copy) every page of them
    faulthandler.disable()  # a kernel crash is expected and handled by the parent: no dump on stderr
    try:
        products = {i: f.by_id(i) for i in ids}
        attributes = Attributes()
        representations = Representations(attributes)  # read once for the routing and the body kinds
        kind = BodyKind(representations, attributes)
        if routing:
            routed, notes = route(products, KernelChoice(representations, attributes))
            conn.send((ROUTED, routed, notes))
            for pid in routed:
                del products[pid]
            if not products:
                conn.send(None)
                return
        it = ifcopenshell.geom.iterator(
            iterator_settings(),
            f,
            1,
            include=list(products.values()),
            geometry_library=kernel,  # type: ignore[arg-type]  # validated by the iterator itself
        )
        seen: set[str] = set()
        batch = _Batch()
        sent = time.monotonic()
        more = bool(it.initialize())
        while more:
            shape = it.get()
            pid, geom = int(shape.id), shape.geometry
            geom_id = str(geom.id)
            product = products.get(pid)
            solid, note = _body_is_solid(kind, product) if product is not None else (False, None)
            raw = None
            if geom_id not in seen:  # instances sharing a representation: send the mesh once
                seen.add(geom_id)
                raw = (*_raw(geom), solid)
            matrix = np.asarray(ifcopenshell.util.shape.get_shape_matrix(shape), dtype=np.float64)
            batch.items.append((pid, geom_id, raw, matrix, solid, note))
            if stop.value:
                batch.send(conn)
                conn.send(STOPPED)
                return
            if len(batch.items) >= _BATCH_SHAPES or time.monotonic() - sent > _BATCH_SECONDS:
                batch.send(conn)
                sent = time.monotonic()
            more = bool(it.next())
        batch.send(conn)
        conn.send(None)
    except Exception as err:  # report, the parent falls back to the next kernel
        conn.send(f"{type(err).__name__}: {err}")
    finally:
        conn.close()
