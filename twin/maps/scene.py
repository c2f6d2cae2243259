"""The scene: world-space triangles of every element (and space) with geometry, indexed for slicing.

Loaded once from the store; each distinct mesh literal is decoded once. Triangles are grouped by
element (``start[i]:start[i+1]``) and every element has a world AABB, so a map window is recomputed
from only the elements that overlap it.

Example::

    scene = load_scene(store)
    ids = scene.elements.indices_of(iris)            # selected elements
    near = scene.elements.overlapping(ids, SlabBox(0.0, 0.0, 5.0, 5.0, z_lo=0.05, z_hi=1.5))
    tris, owner = scene.elements.triangles_of(near)
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Self

import numpy as np
import numpy.typing as npt

from twin.errors import MapError
from twin.graph.extents import parse_extent
from twin.graph.meshcodec import decode_mesh, decode_placement
from twin.graph.rdf import literal_value
from twin.graph.store import GraphStore
from twin.records import Mesh, to_world

log = logging.getLogger(__name__)

IndexArray = npt.NDArray[np.intp]


@dataclass(frozen=True, slots=True)
class SlabBox:
    """A world box: an XY rectangle and a z slab, metres (what a map window depends on)."""

    xmin: float
    ymin: float
    xmax: float
    ymax: float
    z_lo: float
    z_hi: float


NORMAL_STEPS = float(2**20)
"""Triangle normals' components are multiples of 1 / this (:func:`unit_normals`)."""


def unit_normals(c: npt.NDArray[np.float64]) -> npt.NDArray[np.float32]:
    """Vectors ``c (n, 3)`` made unit ``float32`` normals: zero where ``c`` is; components rounded to
    multiples of 2**-20 (about 1e-6, a microradian) before float32 takes them (a small component's own
    float32 step is far finer); no negative zeros, so equal normals have equal bits."""
    c = np.array(c, dtype=np.float64)
    length = np.sqrt(c[:, 0] * c[:, 0] + c[:, 1] * c[:, 1] + c[:, 2] * c[:, 2])
    ok = length > 0.0
    c[ok] /= length[ok, None]
    c[~ok] = 0.0
    c = np.rint(c * NORMAL_STEPS) / NORMAL_STEPS
    out: npt.NDArray[np.float32] = (c + 0.0).astype(np.float32)
    return out


def _cross(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), dtype=np.float64)
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def placed_normals(mesh: Mesh, placement: npt.NDArray[np.float64]) -> npt.NDArray[np.float32]:
    """The world unit normals ``(m, 3) float32`` of ``mesh``'s triangles put in the world by ``placement``,
    by their winding (:func:`unit_normals`), from the local mesh: the local edges' cross products taken
    through the placement's cofactor matrix (the linear part's, so a mirror keeps the world winding), so
    that where the building sits (the placement's translation, 10 km away) never changes a last bit."""
    if not mesh.triangle_count:
        return np.empty((0, 3), dtype=np.float32)
    t = mesh.vertices[mesh.faces]
    local = _cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    m = np.asarray(placement, dtype=np.float64)[:3, :3]
    c0, c1, c2 = m[:, 0], m[:, 1], m[:, 2]
    cof = np.stack([_cross(c1, c2), _cross(c2, c0), _cross(c0, c1)], axis=1)  # cross(Ma, Mb) = cof (a x b)
    return unit_normals(local @ cof.T)


@dataclass(frozen=True, eq=False, slots=True)
class MeshSet:
    """World triangles of ``k`` nodes (elements or spaces).

    Attributes:
        iris: ``k`` node IRIs; ``index[iri]`` is the node's position.
        triangles: ``(n, 3, 3) float64`` world xyz, grouped by node.
        start: ``(k + 1,) intp``: node ``i`` owns ``triangles[start[i]:start[i+1]]``.
        closed: ``(k,) bool`` watertight meshes (filled when sliced).
        solid: ``(k,) bool`` bodies the source model calls solid (their open meshes are filled where
            the section is made of closed loops; see :func:`twin.maps.render.filled`).
        bounds: ``(k, 6) float64`` world AABB ``xmin, ymin, zmin, xmax, ymax, zmax`` (NaN if empty).
        triangle_bounds: ``(n, 6) float32`` each triangle's AABB, rounded outwards (a superset filter).
        normals: ``(n, 3) float32`` each triangle's unit normal from its local mesh
            (:func:`placed_normals`), or None (then points maps take them from the world triangles).
    """

    iris: tuple[str, ...]
    index: dict[str, int]
    triangles: npt.NDArray[np.float64]
    start: IndexArray
    closed: npt.NDArray[np.bool_]
    solid: npt.NDArray[np.bool_]
    bounds: npt.NDArray[np.float64]
    triangle_bounds: npt.NDArray[np.float32]
    normals: npt.NDArray[np.float32] | None = None

    @classmethod
    def build(cls, items: list[tuple[str, Mesh, npt.NDArray[np.float64]]]) -> Self:
        """From ``(iri, local mesh, (4, 4) placement)`` items."""
        iris = tuple(i for i, _, _ in items)
        counts = np.array([m.triangle_count for _, m, _ in items], dtype=np.intp)
        start = np.zeros(len(items) + 1, dtype=np.intp)
        np.cumsum(counts, out=start[1:])
        triangles = np.empty((int(start[-1]), 3, 3), dtype=np.float64)
        normals = np.empty((int(start[-1]), 3), dtype=np.float32)
        for i, (_, mesh, placement) in enumerate(items):
            world = to_world(mesh.vertices, placement)
            triangles[start[i] : start[i + 1]] = world[mesh.faces]
            normals[start[i] : start[i + 1]] = placed_normals(mesh, placement)
        closed = np.array([m.closed for _, m, _ in items], dtype=np.bool_)
        solid = np.array([m.solid for _, m, _ in items], dtype=np.bool_)
        # whole arrays at once: a triangle's bounds, then each node's as the reduction over its rows
        lo = np.minimum(np.minimum(triangles[:, 0], triangles[:, 1]), triangles[:, 2])
        hi = np.maximum(np.maximum(triangles[:, 0], triangles[:, 1]), triangles[:, 2])
        bounds = np.full((len(items), 6), np.nan)  # NaN bounds never overlap: empty meshes drop out
        nonempty = np.flatnonzero(counts > 0)
        if len(nonempty):
            bounds[nonempty, :3] = np.minimum.reduceat(lo, start[nonempty], axis=0)
            bounds[nonempty, 3:] = np.maximum.reduceat(hi, start[nonempty], axis=0)
        pad = 1e-3 + 1e-6 * max(float(np.abs(lo).max(initial=0.0)), float(np.abs(hi).max(initial=0.0)))
        triangle_bounds = np.empty((len(triangles), 6), dtype=np.float32)
        triangle_bounds[:, :3] = lo - pad
        triangle_bounds[:, 3:] = hi + pad
        index = {iri: i for i, iri in enumerate(iris)}
        return cls(iris, index, triangles, start, closed, solid, bounds, triangle_bounds, normals)

    def __len__(self) -> int:
        return len(self.iris)

    def indices_of(self, iris: list[str] | tuple[str, ...]) -> IndexArray:
        """Positions of ``iris`` that have geometry here (others are ignored), sorted."""
        return np.array(sorted({self.index[i] for i in iris if i in self.index}), dtype=np.intp)

    def overlapping(self, ids: IndexArray, box: SlabBox) -> IndexArray:
        """The subset of ``ids`` whose AABB meets ``box`` (closed intervals; empty meshes never do)."""
        b = self.bounds[ids]
        keep = (
            (b[:, 0] <= box.xmax)
            & (b[:, 3] >= box.xmin)
            & (b[:, 1] <= box.ymax)
            & (b[:, 4] >= box.ymin)
            & (b[:, 2] <= box.z_hi)
            & (b[:, 5] >= box.z_lo)
        )
        return ids[keep]

    def _rows_of(self, ids: IndexArray) -> tuple[IndexArray, IndexArray]:
        """``(rows, owner)``: triangle rows of ``ids`` and, per row, its position in ``ids``."""
        counts = self.start[ids + 1] - self.start[ids]
        total = int(counts.sum())
        owner = np.repeat(np.arange(len(ids), dtype=np.intp), counts)
        offsets = np.zeros(len(ids), dtype=np.intp)
        np.cumsum(counts[:-1], out=offsets[1:])
        rows = np.arange(total, dtype=np.intp) - offsets[owner] + self.start[ids][owner]
        return rows, owner

    def triangles_of(self, ids: IndexArray) -> tuple[npt.NDArray[np.float64], IndexArray]:
        """``(triangles (m, 3, 3), owner (m,))``: the triangles of ``ids``; ``owner`` indexes into ``ids``."""
        rows, owner = self._rows_of(ids)
        return self.triangles[rows], owner

    def triangles_for_window(
        self, ids: IndexArray, box: SlabBox, *, filled: npt.NDArray[np.bool_] | None = None
    ) -> tuple[npt.NDArray[np.float64], IndexArray]:
        """Like :meth:`triangles_of`, but only the triangles a slab map of the box can depend on.

        Kept: triangles meeting the box and the slab, and, of filled elements (``filled``, one flag
        per ``ids``; default: the closed ones), triangles in the box's y-range that cross the slab's
        mid-height (their section crossings set the fill's winding number inside the box, wherever
        they lie in x).
        """
        rows, owner = self._rows_of(ids)
        tb = self.triangle_bounds[rows]
        z_f = 0.5 * (box.z_lo + box.z_hi)
        in_rows = (
            (tb[:, 1] <= box.ymax) & (tb[:, 4] >= box.ymin) & (tb[:, 2] <= box.z_hi) & (tb[:, 5] >= box.z_lo)
        )
        in_box = (tb[:, 0] <= box.xmax) & (tb[:, 3] >= box.xmin)
        fill = self.closed[ids] if filled is None else filled
        crosses_fill = fill[owner] & (tb[:, 2] <= z_f) & (tb[:, 5] >= z_f)
        keep = in_rows & (in_box | crosses_fill)
        return self.triangles[rows[keep]], owner[keep]


@dataclass(frozen=True, slots=True)
class StoreyInfo:
    """A storey of the scene: its stable key, name, elevation and XY extent (for the grid frame)."""

    iri: str
    key: str
    name: str
    elevation_m: float
    extent: tuple[float, float, float, float]


@dataclass(frozen=True, eq=False, slots=True)
class Scene:
    """Elements and spaces with geometry, storeys, and each element's local mesh and placement
    (``shapes``: elements that share a mesh literal share one :class:`Mesh` object)."""

    elements: MeshSet
    spaces: MeshSet
    storeys: tuple[StoreyInfo, ...]
    space_storey: dict[str, str]
    shapes: dict[str, tuple[Mesh, npt.NDArray[np.float64]]] = field(default_factory=dict)

    def storey(self, key: str) -> StoreyInfo:
        for s in self.storeys:
            if s.key == key:
                return s
        known = ", ".join(s.key for s in self.storeys) or "none"
        msg = f"Unknown storey {key!r}; storeys of this model: {known}."
        raise MapError(msg)


STOREY_MEMBER = "(bot:containsElement|bot:hasSpace/bot:containsElement)/bot:hasSubElement*"
"""A SPARQL property path from a storey to every element on it: contained directly or in one of its
spaces, and the parts of those (openings, fillings, aggregated parts)."""

_GEOMETRY = """SELECT ?node ?ply ?placement ?closed WHERE {{
  ?node a {kind} ; omg:hasGeometry ?g .
  ?g fog:asPly_v1.0-binaryLE ?ply ; twin:placement ?placement ; twin:closedMesh ?closed .
}}"""


def _mesh_items(store: GraphStore, kind: str) -> list[tuple[str, Mesh, npt.NDArray[np.float64]]]:
    decoded: dict[str, Mesh] = {}
    items = []
    for row in store.iter_select(_GEOMETRY.format(kind=kind)):
        text = row["ply"] or ""
        mesh = decoded.get(text)
        if mesh is None:
            mesh = decoded[text] = decode_mesh(text)
        items.append((row["node"] or "", mesh, decode_placement(row["placement"] or "")))
    items.sort(key=lambda item: item[0])
    return items


def _extent(sets: list[tuple[MeshSet, IndexArray]]) -> tuple[float, float, float, float] | None:
    boxes = [ms.bounds[ids] for ms, ids in sets if len(ids)]
    b = np.concatenate(boxes) if boxes else np.empty((0, 6))
    b = b[~np.isnan(b).any(axis=1)]
    if not len(b):
        return None
    return (float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 3].max()), float(b[:, 4].max()))


def load_scene(store: GraphStore) -> Scene:
    """Read every element's and space's geometry and every storey from ``store``."""
    items = _mesh_items(store, "bot:Element")
    elements = MeshSet.build(items)
    spaces = MeshSet.build(_mesh_items(store, "bot:Space"))
    if len(elements) == 0:
        msg = "The store holds no element with geometry: import a model first."
        raise MapError(msg)
    members: dict[str, list[str]] = {}
    for row in store.select(
        f"""SELECT ?st ?el WHERE {{
             ?st a bot:Storey .
             ?st {STOREY_MEMBER} ?el .
           }}"""
    ):
        members.setdefault(literal_value(row["st"]) or "", []).append(literal_value(row["el"]) or "")
    space_storey: dict[str, str] = {}
    storey_spaces: dict[str, list[str]] = {}
    for row in store.select("SELECT ?st ?sp WHERE { ?st a bot:Storey ; bot:hasSpace ?sp }"):
        st, sp = literal_value(row["st"]) or "", literal_value(row["sp"]) or ""
        space_storey[sp] = st
        storey_spaces.setdefault(st, []).append(sp)
    everything = _extent([(elements, np.arange(len(elements), dtype=np.intp))])
    if everything is None:
        msg = "Every element's mesh in the store is empty: there is nothing to map."
        raise MapError(msg)
    storeys = []
    for row in store.select(
        "SELECT ?st ?key ?name ?elev ?extent WHERE { ?st a bot:Storey ; twin:storeyKey ?key ; "
        "twin:elevation ?elev . OPTIONAL { ?st rdfs:label ?name } OPTIONAL { ?st twin:extent ?extent } } "
        "ORDER BY ?elev ?key"
    ):
        iri = literal_value(row["st"]) or ""
        ext = parse_extent(row["extent"] or "") or _extent(  # stored at import; older stores: computed
            [
                (elements, elements.indices_of(members.get(iri, []))),
                (spaces, spaces.indices_of(storey_spaces.get(iri, []))),
            ]
        )
        storeys.append(
            StoreyInfo(
                iri=iri,
                key=literal_value(row["key"]) or "",
                name=literal_value(row["name"]) or "",
                elevation_m=float(literal_value(row["elev"]) or 0.0),
                extent=ext or everything,
            )
        )
    log.info(
        "Scene: %d elements (%d triangles), %d spaces, %d storeys",
        len(elements),
        len(elements.triangles),
        len(spaces),
        len(storeys),
    )
    return Scene(elements, spaces, tuple(storeys), space_storey, {i: (m, p) for i, m, p in items})
