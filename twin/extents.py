"""Storey extents: the XY box each storey's maps are framed on, fixed when the model is imported.

A storey's extent covers the elements it contains (directly or in its spaces, with their parts:
openings, fillings, aggregated parts) and its spaces; a storey that contains nothing with geometry
gets the extent of every element. It is stored on the storey (``twin:extent``) so that a map's frame
never moves when robots add elements later.

Example::

    extents = storey_extents(model)      # {storey GlobalId: (xmin, ymin, xmax, ymax)}
"""

from __future__ import annotations

import numpy as np

from twin.records import BuildingModel, FloatArray, Geometry, Mesh

Extent = tuple[float, float, float, float]


def _used_vertices(mesh: Mesh) -> FloatArray:
    """``(k, 3) float64``: the vertices some face uses, in index order (``vertices[np.unique(faces)]``)."""
    used = np.zeros(len(mesh.vertices), dtype=bool)
    used[mesh.faces.ravel()] = True
    return mesh.vertices if used.all() else mesh.vertices[used]


def _bounds(geometry: Geometry | None, used_of: dict[int, FloatArray]) -> np.ndarray | None:
    """``(4,)``: xmin, ymin, xmax, ymax of the world vertices; ``used_of`` caches used vertices per mesh."""
    if geometry is None or not geometry.mesh.triangle_count:
        return None
    used = used_of.get(id(geometry.mesh))
    if used is None:
        used = used_of[id(geometry.mesh)] = _used_vertices(geometry.mesh)
    world = used @ geometry.placement[:3, :3].T + geometry.placement[:3, 3]
    xy = np.ascontiguousarray(world[:, :2].T)  # (2, k): reducing along rows is ~4x faster than (k, 2)
    return np.concatenate([xy.min(axis=1), xy.max(axis=1)])


def _union(boxes: list[np.ndarray]) -> Extent | None:
    if not boxes:
        return None
    b = np.stack(boxes)
    return (float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()), float(b[:, 3].max()))


def storey_extents(model: BuildingModel) -> dict[str, Extent]:
    """``{storey GlobalId: (xmin, ymin, xmax, ymax)}`` in world metres, for every storey of ``model``."""
    used_of: dict[int, FloatArray] = {}  # instances share a mesh: find its used vertices once
    bounds = {e.guid: b for e in model.elements if (b := _bounds(e.geometry, used_of)) is not None}
    bounds.update({s.guid: b for s in model.spaces if (b := _bounds(s.geometry, used_of)) is not None})
    everything = _union([bounds[e.guid] for e in model.elements if e.guid in bounds])
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
        extent = _union([bounds[g] for g in sorted(seen) if g in bounds]) or everything
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
