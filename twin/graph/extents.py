"""Storey extents: the XY box each storey's maps are framed on, fixed when the model is imported.

A storey's extent covers the elements it contains (directly or in its spaces, with their parts:
openings, fillings, aggregated parts) and its spaces; a storey that contains nothing with geometry
gets the extent of every element. It is stored on the storey (``twin:extent``) so that a map's frame
never moves when robots add elements later.

Example::

    extents = storey_extents(model)      # {storey GlobalId: (xmin, ymin, xmax, ymax)}
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt

from twin.records import BuildingModel, FloatArray, Geometry, Mesh

IntArray64 = npt.NDArray[np.int64]

Extent = tuple[float, float, float, float]


def _used_vertices(mesh: Mesh) -> FloatArray:
    """``(k, 3) float64``: the vertices some face uses, in index order (``vertices[np.unique(faces)]``)."""
    used = np.zeros(len(mesh.vertices), dtype=bool)
    used[mesh.faces.ravel()] = True
    return mesh.vertices if used.all() else mesh.vertices[used]


def _rotated_xy(rows: FloatArray, rotation: FloatArray) -> tuple[FloatArray, FloatArray]:
    """x and y of ``rows @ rotation.T`` (``(k, 3)`` rows, a ``(3, 3)`` rotation), each one
    ``(r0 * a + r1 * b) + r2 * c`` with every step rounded on its own: a row's result never depends on
    the other rows (a matrix product may take another code path, and round otherwise, for another
    number of rows), so boxes worked out in parts equal boxes worked out at once, bit for bit."""
    r0, r1, r2 = rows[:, 0], rows[:, 1], rows[:, 2]
    x = r0 * rotation[0, 0] + r1 * rotation[0, 1] + r2 * rotation[0, 2]
    y = r0 * rotation[1, 0] + r1 * rotation[1, 1] + r2 * rotation[1, 2]
    return x, y


def _bounds(geometry: Geometry) -> FloatArray:
    """``(4,)``: xmin, ymin, xmax, ymax of the world coordinates of the vertices some face uses."""
    x, y = _rotated_xy(_used_vertices(geometry.mesh), geometry.placement[:3, :3])
    x, y = x + geometry.placement[0, 3], y + geometry.placement[1, 3]
    return np.array([x.min(), y.min(), x.max(), y.max()])


def _ranges(starts: IntArray64, lengths: IntArray64) -> IntArray64:
    """The indices ``starts[0] .. starts[0]+lengths[0]-1, starts[1] ..``, concatenated (lengths > 0)."""
    ends = np.cumsum(lengths)
    return np.repeat(starts - (ends - lengths), lengths) + np.arange(int(ends[-1]))


def _used_of(meshes: list[Mesh]) -> tuple[FloatArray, IntArray64, IntArray64]:
    """The used vertices of every mesh (:func:`_used_vertices`) one after the other, with where each
    mesh's run starts and how long it is."""
    counts = np.array([len(m.vertices) for m in meshes], dtype=np.int64)
    offsets = np.cumsum(counts) - counts
    faces = np.concatenate([m.faces.ravel() for m in meshes]).astype(np.int64)
    faces += np.repeat(offsets, [m.faces.size for m in meshes])
    used = np.zeros(int(counts.sum()), dtype=bool)
    used[faces] = True
    lengths = np.add.reduceat(used, offsets).astype(np.int64)  # each mesh has a triangle: no run is empty
    return np.concatenate([m.vertices for m in meshes])[used], np.cumsum(lengths) - lengths, lengths


def _instance_bounds(geometries: Sequence[Geometry]) -> FloatArray:
    """``(n, 4) float64``: :func:`_bounds` of every geometry (each mesh has a triangle), bit for bit,
    computed for all at once.

    Each distinct (rotation, mesh) pair is rotated once, the pairs of one rotation together
    (:func:`_rotated_xy`: a row's result does not depend on the other rows); the translation is added after
    the reduction, which is exact: rounding is monotonic, so ``min(fl(a + t)) == fl(min(a) + t)``.
    Where that does not fix the bits (a bound of exactly zero, whose sign depends on the order of the
    reduction), the box is computed instance by instance as :func:`_bounds` does.
    """
    n = len(geometries)
    if n == 0:
        return np.empty((0, 4))
    index: dict[int, int] = {}
    meshes: list[Mesh] = []
    mesh_of = np.empty(n, dtype=np.int64)
    for i, g in enumerate(geometries):
        k = index.get(id(g.mesh))
        if k is None:
            k = index[id(g.mesh)] = len(meshes)
            meshes.append(g.mesh)
        mesh_of[i] = k
    used, used_start, used_len = _used_of(meshes)
    placements = np.stack([g.placement for g in geometries]).astype(np.float64, copy=False)
    keys = np.ascontiguousarray(placements[:, :3, :3]).reshape(n, 9).view(np.dtype((np.void, 72))).ravel()
    _, first, rotation_of = np.unique(keys, return_index=True, return_inverse=True)  # bytewise: -0.0 != 0.0
    pairs, pair_of = np.unique(rotation_of.ravel() * len(meshes) + mesh_of, return_inverse=True)
    pair_rotation, pair_mesh = np.divmod(pairs, len(meshes))  # sorted by rotation
    lengths = used_len[pair_mesh]
    rows = used[_ranges(used_start[pair_mesh], lengths)]
    row_start = np.cumsum(lengths) - lengths
    x, y = np.empty(len(rows)), np.empty(len(rows))
    groups = np.flatnonzero(np.diff(pair_rotation, prepend=-1, append=-1))
    for lo, hi in zip(groups[:-1].tolist(), groups[1:].tolist(), strict=True):
        a = int(row_start[lo])
        b = int(row_start[hi]) if hi < len(pairs) else len(rows)
        x[a:b], y[a:b] = _rotated_xy(rows[a:b], geometries[first[pair_rotation[lo]]].placement[:3, :3])
    boxes = np.stack(
        [
            np.minimum.reduceat(x, row_start),
            np.minimum.reduceat(y, row_start),
            np.maximum.reduceat(x, row_start),
            np.maximum.reduceat(y, row_start),
        ],
        axis=1,
    )
    out: FloatArray = boxes[pair_of.ravel()] + placements[:, [0, 1, 0, 1], 3]
    for i in np.flatnonzero(~np.isfinite(out).all(axis=1) | (out == 0).any(axis=1)).tolist():
        out[i] = _bounds(geometries[i])
    return out


def _union(boxes: FloatArray) -> Extent | None:
    """The box around ``(k, 4)`` boxes, or None when there are none."""
    if not len(boxes):
        return None
    return (
        float(boxes[:, 0].min()),
        float(boxes[:, 1].min()),
        float(boxes[:, 2].max()),
        float(boxes[:, 3].max()),
    )


def geometry_bounds(items: Sequence[tuple[str, Geometry]]) -> dict[str, FloatArray]:
    """``{GlobalId: (xmin, ymin, xmax, ymax)}`` of each ``(GlobalId, geometry)`` that has a triangle, as
    :func:`storey_extents` computes them: an import works them out as the meshes come, in parts, and
    hands them to it (a row does not depend on the other geometries of the part)."""
    placed = [(guid, g) for guid, g in items if g.mesh.triangle_count]
    boxes = _instance_bounds([g for _, g in placed])
    return {guid: boxes[i] for i, (guid, _) in enumerate(placed)}


def storey_extents(model: BuildingModel, known: Mapping[str, FloatArray] | None = None) -> dict[str, Extent]:
    """``{storey GlobalId: (xmin, ymin, xmax, ymax)}`` in world metres, for every storey of ``model``.
    ``known`` holds :func:`geometry_bounds` of some of its elements and spaces (of their geometry in
    ``model``): only the others are computed."""
    nodes = [(e.guid, e.geometry) for e in model.elements] + [(s.guid, s.geometry) for s in model.spaces]
    placed = [(guid, g) for guid, g in nodes if g is not None and g.mesh.triangle_count]
    known = known or {}
    unknown = [i for i, (guid, _) in enumerate(placed) if guid not in known]
    boxes = np.empty((len(placed), 4))
    boxes[unknown] = _instance_bounds([placed[i][1] for i in unknown])
    for i, (guid, _) in enumerate(placed):
        if guid in known:
            boxes[i] = known[guid]
    row_of = {guid: i for i, (guid, _) in enumerate(placed)}  # a space's box wins over an element's
    everything = _union(boxes[[row_of[e.guid] for e in model.elements if e.guid in row_of]])
    parts: dict[str, list[str]] = {}
    for r in model.decomposed:
        parts.setdefault(r.subject, []).append(r.object)
    contained: dict[str, list[str]] = {}
    for r in model.contained:
        contained.setdefault(r.subject, []).append(r.object)
    out: dict[str, Extent] = {}
    for storey in model.storeys:
        roots = [storey.guid, *(s.guid for s in model.spaces if s.storey_guid == storey.guid)]
        seen: set[str] = set()
        todo = [m for root in roots for m in contained.get(root, [])] + roots[1:]
        while todo:
            guid = todo.pop()
            if guid not in seen:
                seen.add(guid)
                todo.extend(parts.get(guid, []))
        extent = _union(boxes[[row_of[g] for g in sorted(seen) if g in row_of]]) or everything
        if extent is not None:
            out[storey.guid] = extent
    return out


def format_extent(extent: Extent) -> str:
    return " ".join(repr(float(v)) for v in extent)


def parse_extent(text: str) -> Extent | None:
    """The extent stored on a storey, or None if the literal is not four finite numbers."""
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        return None
    if len(values) != 4 or not all(np.isfinite(values)) or values[2] < values[0] or values[3] < values[1]:
        return None
    return (values[0], values[1], values[2], values[3])
