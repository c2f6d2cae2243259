"""An independent reference for slab maps: trimesh plane slicing + shapely polygons + per-cell tests.

Slow and simple on purpose (shapely per element, no shared code with ``twin.raster``): it is what the
fast rasteriser is checked against.
"""

from __future__ import annotations

import numpy as np
import shapely
import trimesh

from twin.grid import GridFrame


def slab_geometry(vertices: np.ndarray, faces: np.ndarray, closed: bool, z_lo: float, z_hi: float):
    """The XY projection of one mesh's part within ``[z_lo, z_hi]`` (filled for closed meshes)."""
    v, f = vertices, faces
    v, f = trimesh.intersections.slice_faces_plane(v, f, np.array([0.0, 0, 1]), np.array([0, 0, z_lo]))[:2]
    if len(f):
        v, f = trimesh.intersections.slice_faces_plane(v, f, np.array([0.0, 0, -1]), np.array([0, 0, z_hi]))[
            :2
        ]
    parts = []
    for tri in v[f][:, :, :2] if len(f) else ():
        poly = shapely.Polygon(tri)
        parts.append(poly if poly.area > 1e-12 else shapely.LineString(tri).simplify(0))
    if closed:
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        z_mid = (z_lo + z_hi) / 2 + 1.234567e-7
        lines = trimesh.intersections.mesh_plane(mesh, [0, 0, 1], [0, 0, z_mid])
        if len(lines):  # the same edge cut from its two triangles may differ in the last bits: snap
            filled = shapely.Polygon()
            for poly in shapely.get_parts(
                shapely.polygonize(shapely.linestrings(np.round(lines[:, :, :2], 7)))
            ):
                filled = filled.symmetric_difference(poly)
            parts.append(filled)
    return shapely.union_all(parts) if parts else shapely.Polygon()


def rasterize_reference(geometry, frame: GridFrame, *, grow: float) -> np.ndarray:
    """Cells whose square, grown by ``grow`` metres (negative shrinks), intersects ``geometry``."""
    xs = frame.origin_x + np.arange(frame.width) * frame.resolution_m
    ys = frame.origin_y + np.arange(frame.height) * frame.resolution_m
    gx, gy = np.meshgrid(xs, ys)
    r = frame.resolution_m
    boxes = shapely.box(gx - grow, gy - grow, gx + r + grow, gy + r + grow)
    shapely.prepare(geometry)
    return shapely.intersects(geometry, boxes)
