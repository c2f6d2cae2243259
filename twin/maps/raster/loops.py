"""Closed sections: is an element's section at a height made of closed loops?

A solid's mesh is not always watertight: a kernel that triangulates each face of a B-rep on its own
leaves T-junctions (one face's edge split at a vertex of its neighbour, the neighbour's edge whole),
bodies of one element touch along faces, two copies of a vertex lie a rounding error apart. Such a
mesh fails the edge test (:func:`twin.maps.meshops.is_closed`), yet its section at a height is still made
of closed loops, up to rounding: every point where a section segment ends is where another begins.
Then the section can be filled exactly like a watertight mesh's, by the winding number of its
segments (their orientation comes from the faces).

The test works on the section, not on the mesh: endpoints are joined within ``Tolerances.join_m``
and, at every joint, as many oriented segments must arrive as leave. A section with a loose end (a
surface, a face the kernel lost) or with faces turned inside out is not filled: the element keeps
its outline, as an open surface does.

Example::

    fill = closed | (solid & closed_sections(triangles, element, len(closed), z=0.75))
"""

from __future__ import annotations

import numpy as np

from twin.maps.raster.clip import _min_max, _section
from twin.maps.raster.settings import BoolArray, FloatArray, IndexArray
from twin.tolerances import TOLERANCES, Tolerances

_SHIFT = 0.318309886  # joints are cells of a grid shifted off round numbers (model coordinates often are)


def closed_sections(
    triangles: FloatArray, element: IndexArray, count: int, z: float, *, tol: Tolerances = TOLERANCES
) -> BoolArray:
    """Which of ``count`` elements have a non-empty section at height ``z`` made of closed loops.

    Args:
        triangles: ``(n, 3, 3) float64`` world xyz of each triangle's vertices, metres: all the
            triangles of the elements asked about (those not crossing ``z`` are skipped).
        element: ``(n,) intp`` element of each triangle, in ``[0, count)``.
        count: number of elements.
        z: the section's height (world z, metres); a vertex exactly at ``z`` counts as above it, as
            when the section is filled (:mod:`twin.maps.raster.clip`).
        tol: ``join_m``: section endpoints this close (on a grid of that pitch) are one joint.

    Returns:
        ``(count,) bool``: True where at every joint of the element's section as many segments
        (oriented with the solid on their left) arrive as leave.
    """
    out = np.zeros(count, dtype=np.bool_)
    if not len(triangles):
        return out
    zmin, zmax = _min_max(triangles, 2)
    crossing = np.flatnonzero((zmin < z) & (zmax >= z))
    if not len(crossing):
        return out
    seg, winding = _section(triangles[crossing], z)
    owner = element[crossing].astype(np.int64)
    up = winding > 0  # the segment runs from its lower endpoint to its upper one
    tail = np.where(up, seg[:2], seg[2:])
    head = np.where(up, seg[2:], seg[:2])
    cells = np.floor(np.concatenate([tail, head], axis=1) / tol.join_m + _SHIFT).astype(np.int64)
    keys = np.stack([np.concatenate([owner, owner]), cells[0], cells[1]], axis=1)
    _, joint = np.unique(keys, axis=0, return_inverse=True)
    joint = joint.reshape(-1)
    s = len(crossing)
    flow = np.bincount(joint, weights=np.repeat([1.0, -1.0], s))  # leaving minus arriving
    unbalanced = np.zeros(count, dtype=np.bool_)
    unbalanced[np.concatenate([owner, owner])[flow[joint] != 0]] = True
    out[np.unique(owner)] = True
    return out & ~unbalanced
