"""Primitive shapes as meshes: the oriented box robots report for what they detect.

A box is given as its centre, its sizes and a yaw about +z (metres, radians). Its mesh is the unit
cube scaled to the sizes, centred on the local origin; its placement rotates by the yaw and moves to
the centre, so a moved box keeps its mesh and changes only its placement, as imported elements do.

Example::

    mesh = box_mesh(1.2, 0.8, 0.75)                       # a table, local frame
    placement = box_placement(2.0, 3.0, 0.375, yaw=0.3)   # world-from-local
"""

from __future__ import annotations

import math

import numpy as np

from twin.records import FloatArray, Mesh

# The unit cube's corners (x, y, z in {-0.5, 0.5}) and 12 outward-facing triangles.
_CORNERS = np.array(
    [[x, y, z] for z in (-0.5, 0.5) for y in (-0.5, 0.5) for x in (-0.5, 0.5)], dtype=np.float64
)
_FACES = np.array(
    [
        [0, 2, 1], [1, 2, 3],  # bottom (-z)
        [4, 5, 6], [5, 7, 6],  # top (+z)
        [0, 1, 4], [1, 5, 4],  # front (-y)
        [2, 6, 3], [3, 6, 7],  # back (+y)
        [0, 4, 2], [2, 4, 6],  # left (-x)
        [1, 3, 5], [3, 7, 5],  # right (+x)
    ],
    dtype=np.int32,
)  # fmt: skip


def box_mesh(sx: float, sy: float, sz: float) -> Mesh:
    """A closed, outward-oriented box mesh of sizes ``sx, sy, sz`` centred on the local origin."""
    return Mesh(_CORNERS * np.array([sx, sy, sz], dtype=np.float64), _FACES.copy(), closed=True)


def box_placement(cx: float, cy: float, cz: float, *, yaw: float = 0.0) -> FloatArray:
    """``(4, 4) float64`` world-from-local: rotate by ``yaw`` about +z, then move to the centre."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0, cx], [s, c, 0.0, cy], [0.0, 0.0, 1.0, cz], [0.0, 0.0, 0.0, 1.0]])
