"""An independent reference for slab maps: trimesh plane slicing + shapely polygons + per-cell tests.

Simple on purpose (shapely per element, no shared code with ``twin.maps.raster``): it is what the fast
rasteriser is checked against. Only the numpy plumbing around shapely and trimesh is vectorised.

Example::

    geometry = slab_geometry(vertices, faces, closed, z_lo=0.05, z_hi=1.5)
    cells = rasterize_element(geometry, frame, grow=-0.01)  # None, or (window, (rows, cols) bool)
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import shapely
import trimesh

from twin.maps.grid import GridFrame, Window

BoolArray = npt.NDArray[np.bool_]


def is_solid(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """True if the mesh encloses a volume: every edge is used by an even number of faces, or the edges
    used an odd number of times cancel along their line.

    The second case is a T-junction: a kernel that triangulates each face of a solid on its own (as
    OpenCASCADE does) splits one face's edge at a vertex of its neighbours and not the other's, so the
    long edge ``a-c`` and the short ones ``a-b``, ``b-c`` are each used once, yet cover their line
    twice. ``vertices (n, 3) float64`` welded, ``faces (m, 3) int``.
    """
    f = np.asarray(faces)
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    if not len(f):
        return False
    edges = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    keys, counts = np.unique(edges, axis=0, return_counts=True)
    odd = keys[counts % 2 == 1]
    if not len(odd):
        return True
    a, b = vertices[odd[:, 0]], vertices[odd[:, 1]]
    d = (b - a) / np.linalg.norm(b - a, axis=1)[:, None]
    first = np.argmax(np.abs(d) > 1e-9, axis=1)
    d *= np.sign(d[np.arange(len(d)), first])[:, None]  # one direction per line
    ta, tb = (a * d).sum(axis=1), (b * d).sum(axis=1)
    foot = a - ta[:, None] * d  # the line's point nearest the origin
    line = np.round(np.hstack([d, foot]) * 1e6).astype(np.int64)
    _, group = np.unique(line, axis=0, return_inverse=True)
    for g in np.unique(group):
        lo, hi = np.minimum(ta, tb)[group == g], np.maximum(ta, tb)[group == g]
        cuts = np.unique(np.round(np.concatenate([lo, hi]), 9))
        mids = (cuts[1:] + cuts[:-1]) / 2
        cover = ((lo[None, :] < mids[:, None]) & (mids[:, None] < hi[None, :])).sum(axis=1)
        if (cover % 2).any():
            return False
    return True


def _section(vertices: np.ndarray, faces: np.ndarray, z: float) -> shapely.Geometry:
    """The filled section of a closed mesh at height ``z``: even-odd within each connected shell,
    union over shells (two shells of one element that overlap stay filled where they overlap)."""
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    lines, face_index = trimesh.intersections.mesh_plane(mesh, [0, 0, 1], [0, 0, z], return_faces=True)
    if not len(lines):
        return shapely.Polygon()
    shell = np.zeros(len(faces), dtype=np.intp)
    for i, part in enumerate(
        trimesh.graph.connected_components(mesh.face_adjacency, nodes=np.arange(len(faces)))
    ):
        shell[part] = i
    filled = []
    for s in np.unique(shell[face_index]):
        # the same edge cut from its two triangles may differ in the last bits: snap
        mine = np.round(lines[shell[face_index] == s][:, :, :2], 7)
        area = shapely.Polygon()
        # polygonize gives every face of the arrangement (a ring *and* its hole): even-odd fill is the
        # symmetric difference of their outlines
        for poly in shapely.get_parts(shapely.polygonize(shapely.linestrings(mine))):
            area = area.symmetric_difference(shapely.Polygon(poly.exterior))
        filled.append(area)
    return shapely.union_all(filled)


def slab_geometry(
    vertices: np.ndarray, faces: np.ndarray, closed: bool, z_lo: float, z_hi: float
) -> shapely.Geometry:
    """The XY projection of one mesh's part within ``[z_lo, z_hi]`` (filled for closed meshes).

    ``vertices (n, 3) float64``, ``faces (m, 3) int``. A closed mesh's interior is its section at the
    slab's mid-height (what a solid wall between the two heights covers); open meshes are surfaces.
    A z within 1 um of the band's end is on it; a closed mesh that only touches the end then occupies
    no space in the band (trimesh keeps no face on the cut plane that faces out of it), an open one
    lying on the end is in the band.
    """
    v = np.array(vertices, dtype=np.float64)
    # the contract's tie rule: a z within 1 um of the band's bottom or top is on it (docs/maps.md)
    v[np.abs(v[:, 2] - z_lo) <= 1e-6, 2] = z_lo
    v[np.abs(v[:, 2] - z_hi) <= 1e-6, 2] = z_hi
    f = np.asarray(faces)
    z = v[f][:, :, 2] if len(f) else np.empty((0, 3))
    f = f[(z.max(axis=1, initial=-np.inf) >= z_lo - 1e-6) & (z.min(axis=1, initial=np.inf) <= z_hi + 1e-6)]
    areas: list[shapely.Geometry] = []
    lines: list[shapely.Geometry] = []
    if len(f):
        up, down = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0])
        v2, f2 = trimesh.intersections.slice_faces_plane(v, f, up, np.array([0.0, 0.0, z_lo]))[:2]
        if len(f2):
            v2, f2 = trimesh.intersections.slice_faces_plane(v2, f2, down, np.array([0.0, 0.0, z_hi]))[:2]
        if len(f2):
            tri = v2[f2][:, :, :2]
            e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
            flat = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) / 2 <= 1e-12
            areas.extend(shapely.polygons(tri[~flat]))
            # a vertical face seen from above is a segment (or a point): keep it as a line
            lines.extend(shapely.simplify(shapely.linestrings(tri[flat]), 0))
    if not closed and len(f):  # an open surface lying on the band's end is in it, whichever way it faces
        zf = v[f][:, :, 2]
        on_end = ((zf == z_lo).all(axis=1) | (zf == z_hi).all(axis=1)) & (z_lo < z_hi)
        tri = v[f[on_end]][:, :, :2]
        e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        flat = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) / 2 <= 1e-12
        areas.extend(shapely.polygons(tri[~flat]))
        lines.extend(shapely.simplify(shapely.linestrings(tri[flat]), 0))
    z_mid = (z_lo + z_hi) / 2 + 1.234567e-7
    if closed and len(f) and v[:, 2].min() <= z_mid <= v[:, 2].max():
        areas.append(_section(vertices, faces, z_mid))
    # no union: a cell meets the geometry iff it meets one of its parts, and unioning thousands of
    # small triangles and segments (furniture) takes up to a minute per element
    parts = [*areas, *lines]
    return shapely.geometrycollections(parts) if parts else shapely.Polygon()


def _meets(geometry: shapely.Geometry, frame: GridFrame, window: Window, grow: float) -> BoolArray:
    """``(rows, cols) bool``: the cells of ``window`` whose square, grown by ``grow`` metres, meets a
    part of ``geometry`` (an STRtree over the parts: exact, and fast for thousands of small ones)."""
    r = frame.resolution_m
    xs = frame.origin_x + np.arange(window.col0, window.col1) * r
    ys = frame.origin_y + np.arange(window.row0, window.row1) * r
    gx, gy = np.meshgrid(xs, ys)
    boxes = shapely.box(gx - grow, gy - grow, gx + r + grow, gy + r + grow).ravel()
    hit = np.zeros(len(boxes), dtype=np.bool_)
    hit[shapely.STRtree(shapely.get_parts(geometry)).query(boxes, predicate="intersects")[0]] = True
    return hit.reshape(window.shape)


def rasterize_reference(geometry: shapely.Geometry, frame: GridFrame, *, grow: float) -> BoolArray:
    """Cells whose square, grown by ``grow`` metres (negative shrinks), intersects ``geometry``."""
    return _meets(geometry, frame, frame.full, grow)


def rasterize_element(
    geometry: shapely.Geometry, frame: GridFrame, *, grow: float
) -> tuple[Window, BoolArray] | None:
    """Like :func:`rasterize_reference`, only over the cells near ``geometry``'s bounds (fast for one
    element on a large grid): ``(window, (rows, cols) bool)``, or None when no cell meets it."""
    if geometry.is_empty:
        return None
    xmin, ymin, xmax, ymax = geometry.bounds
    pad = abs(grow) + 1e-6
    w = frame.window_for(xmin - pad, ymin - pad, xmax + pad, ymax + pad)
    if w.empty:
        return None
    hit = _meets(geometry, frame, w, grow)
    return (w, hit) if hit.any() else None


def paint(shape: tuple[int, int], rasters: Iterable[tuple[Window, BoolArray] | None]) -> BoolArray:
    """The union of per-element rasters on a ``shape`` grid (equal to rasterising the union of the
    elements' geometry: a cell meets a union iff it meets one of its parts)."""
    out = np.zeros(shape, dtype=np.bool_)
    for item in rasters:
        if item is not None:
            w, hit = item
            out[w.row0 : w.row1, w.col0 : w.col1] |= hit
    return out


@dataclass(frozen=True, slots=True)
class CellCheck:
    """A map against a reference: ``cells`` compared, ``occupied`` in the map, ``certain`` in the
    reference; ``missed`` cells the reference surely occupies and the map does not, ``extra`` cells
    the map occupies and the reference cannot (both ``(rows, cols) bool``)."""

    cells: int
    occupied: int
    certain: int
    missed: BoolArray
    extra: BoolArray

    @property
    def agrees(self) -> bool:
        return not (self.missed.any() or self.extra.any())


def check_cells(ours: BoolArray, strict: BoolArray, loose: BoolArray) -> CellCheck:
    """Compare ``ours`` with a reference given as its ``strict`` (cells shrunk) and ``loose`` (cells
    grown) rasters: every strict cell must be ours, every cell of ours must be loose."""
    return CellCheck(int(ours.size), int(ours.sum()), int(strict.sum()), strict & ~ours, ours & ~loose)
