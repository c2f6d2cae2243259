"""Peer map builders for the benchmark: the typical trimesh and manifold3d ways of making a slab map.

Both start from the same world triangles as ``twin.maps.render`` (the scene's selected elements, pre-filtered
by the same AABB test against the frame and slab, which favours the peers) and rasterise with Pillow
on the plan's grid frame: cell ``(row, col)`` has its centre at pixel ``(col, row)``, so row 0 is the
lowest y, as in ``nav_msgs/OccupancyGrid``.

- trimesh, localization: ``trimesh.intersections.mesh_plane`` at the lidar height -> segments ->
  ``ImageDraw.line``.
- trimesh, navigation: ``slice_faces_plane`` twice (keep ``z_lo <= z <= z_hi``) -> every remaining
  triangle projected to XY -> ``ImageDraw.polygon`` (fill + outline).
- manifold3d (both skills): one ``Manifold`` from the merged mesh of the *closed* elements (open meshes
  cannot be a Manifold; if the merged mesh is still rejected, elements are checked one by one and the
  rejected ones dropped), intersected with a slab box over the frame, ``project()`` -> ``CrossSection``
  -> ``to_polygons()`` -> outer contours filled, holes cleared, all contours outlined.

Example::

    result = trimesh_map(scene, plan)
    print(result.occupied.sum(), result.seconds)
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from PIL import Image, ImageDraw

from twin.maps.grid import GridFrame
from twin.maps.render import MapPlan
from twin.maps.scene import IndexArray, Scene, SlabBox

FloatArray = npt.NDArray[np.float64]
BoolGrid = npt.NDArray[np.bool_]


@dataclass(slots=True)
class PeerResult:
    """A peer's occupancy (``(height, width) bool``), its timed seconds and untimed preparation seconds."""

    occupied: BoolGrid
    seconds: float
    prep_seconds: float = 0.0
    info: dict[str, Any] = field(default_factory=dict)
    kept: IndexArray | None = None  # the elements the peer actually used, where it drops some


@dataclass(frozen=True, slots=True)
class Welded:
    """An indexed mesh of several elements: element ``e`` owns vertices ``vstart[e]:vstart[e+1]``."""

    vertices: FloatArray
    faces: npt.NDArray[np.uint32]
    vstart: npt.NDArray[np.intp]
    fstart: npt.NDArray[np.intp]


# --- gathering -------------------------------------------------------------------------------------


def near_elements(scene: Scene, plan: MapPlan, ids: IndexArray | None = None) -> IndexArray:
    """The selected elements whose AABB meets the frame and the slab (the same test as
    ``twin.maps.render``)."""
    f = plan.frame
    box = SlabBox(
        xmin=f.origin_x,
        ymin=f.origin_y,
        xmax=f.origin_x + f.width * f.resolution_m,
        ymax=f.origin_y + f.height * f.resolution_m,
        z_lo=plan.z_lo,
        z_hi=plan.z_hi,
    )
    return scene.elements.overlapping(plan.selected if ids is None else ids, box)


# --- rasterising with Pillow -----------------------------------------------------------------------


def _to_pixels(xy: FloatArray, frame: GridFrame) -> FloatArray:
    """World XY -> Pillow pixel coordinates (cell centres at integers)."""
    out = np.empty_like(xy, dtype=np.float64)
    out[..., 0] = (xy[..., 0] - frame.origin_x) / frame.resolution_m - 0.5
    out[..., 1] = (xy[..., 1] - frame.origin_y) / frame.resolution_m - 0.5
    return out


def _canvas(frame: GridFrame) -> tuple[Image.Image, ImageDraw.ImageDraw]:
    image = Image.new("L", (frame.width, frame.height), 0)
    return image, ImageDraw.Draw(image)


def _occupied(image: Image.Image) -> BoolGrid:
    grid: BoolGrid = np.asarray(image) > 0
    return grid


def raster_segments(segments: FloatArray, frame: GridFrame) -> BoolGrid:
    """``(m, 2, 2)`` world XY segments drawn as 1-pixel lines."""
    image, draw = _canvas(frame)
    for a, b in _to_pixels(segments, frame).tolist():
        draw.line([tuple(a), tuple(b)], fill=255, width=1)
    return _occupied(image)


def raster_triangles(triangles: FloatArray, frame: GridFrame) -> BoolGrid:
    """``(m, 3, 2)`` world XY triangles, each filled and outlined (degenerate ones become lines)."""
    image, draw = _canvas(frame)
    for tri in _to_pixels(triangles, frame).tolist():
        draw.polygon([tuple(p) for p in tri], fill=255, outline=255)
    return _occupied(image)


def _signed_area(poly: FloatArray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def raster_polygons(contours: Iterable[FloatArray], frame: GridFrame) -> BoolGrid:
    """Contours of a polygon set (CCW outers, CW holes): outers filled, holes cleared, all outlined."""
    pixels = [(_signed_area(c), _to_pixels(c, frame).tolist()) for c in contours if len(c) >= 2]
    image, draw = _canvas(frame)
    for area, pts in sorted(pixels, key=lambda item: item[0] < 0):  # outers first, then holes
        draw.polygon([tuple(p) for p in pts], fill=255 if area >= 0 else 0)
    for _, pts in pixels:
        draw.polygon([tuple(p) for p in pts], outline=255)
    return _occupied(image)


# --- trimesh ---------------------------------------------------------------------------------------


def trimesh_map(scene: Scene, plan: MapPlan) -> PeerResult:
    """The map of ``plan`` the trimesh way (all timed: gather, mesh, slice, rasterise)."""
    import trimesh
    from trimesh.intersections import mesh_plane, slice_faces_plane

    t0 = time.perf_counter()
    ids = near_elements(scene, plan)
    triangles, _ = scene.elements.triangles_of(ids)
    vertices = triangles.reshape(-1, 3)
    faces = np.arange(len(vertices), dtype=np.int64).reshape(-1, 3)
    info: dict[str, Any] = {"elements": len(ids), "triangles_in": len(faces)}
    if plan.skill.kind == "localization":
        mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
        height = (plan.z_lo + plan.z_hi) / 2
        lines = mesh_plane(mesh, [0.0, 0.0, 1.0], [0.0, 0.0, height]) if len(faces) else np.zeros((0, 2, 3))
        info["segments"] = len(lines)
        t_raster = time.perf_counter()
        occupied = raster_segments(np.asarray(lines)[:, :, :2], plan.frame)
    else:
        v, f = vertices, faces
        if len(f):
            v, f = slice_faces_plane(v, f, np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, plan.z_lo]))[:2]
        if len(f):
            v, f = slice_faces_plane(v, f, np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.0, plan.z_hi]))[:2]
        info["triangles_drawn"] = len(f)
        t_raster = time.perf_counter()
        occupied = raster_triangles(np.asarray(v)[np.asarray(f)][:, :, :2], plan.frame)
    t_end = time.perf_counter()
    info |= {"slice_s": t_raster - t0, "raster_s": t_end - t_raster}
    return PeerResult(occupied, t_end - t0, 0.0, info)


# --- manifold3d ------------------------------------------------------------------------------------


def weld_per_element(triangles: FloatArray, owner: IndexArray, count: int) -> Welded:
    """Index a triangle soup, merging equal positions only within an element (elements stay apart)."""
    n = len(triangles)
    key = np.empty((3 * n, 4), dtype=np.float64)
    key[:, 0] = np.repeat(owner, 3)
    key[:, 1:] = triangles.reshape(-1, 3)
    unique, inverse = np.unique(key, axis=0, return_inverse=True)
    vstart = np.searchsorted(unique[:, 0], np.arange(count + 1, dtype=np.float64)).astype(np.intp)
    fstart = np.searchsorted(owner, np.arange(count + 1)).astype(np.intp)
    faces = inverse.reshape(-1, 3).astype(np.uint32)
    return Welded(np.ascontiguousarray(unique[:, 1:]), faces, vstart, fstart)


def _manifold(vertices: FloatArray, faces: npt.NDArray[np.uint32]) -> Any:
    import manifold3d

    mesh = manifold3d.Mesh(
        vert_properties=np.ascontiguousarray(vertices, dtype=np.float32),
        tri_verts=np.ascontiguousarray(faces, dtype=np.uint32),
    )
    return manifold3d.Manifold(mesh)


def _solid_of(welded: Welded, count: int) -> tuple[Any, list[int], str]:
    """The merged Manifold; if rejected, rebuilt from the elements accepted one by one."""
    import manifold3d

    solid = _manifold(welded.vertices, welded.faces)
    status = str(solid.status()).rsplit(".", 1)[-1]
    if solid.status() == manifold3d.Error.NoError:
        return solid, [], status
    keep_v: list[FloatArray] = []
    keep_f: list[npt.NDArray[np.uint32]] = []
    rejected: list[int] = []
    offset = 0
    for e in range(count):
        v0, v1 = int(welded.vstart[e]), int(welded.vstart[e + 1])
        f = welded.faces[welded.fstart[e] : welded.fstart[e + 1]] - np.uint32(v0)
        v = welded.vertices[v0:v1]
        if _manifold(v, f).status() != manifold3d.Error.NoError:
            rejected.append(e)
            continue
        keep_v.append(v)
        keep_f.append(f + np.uint32(offset))
        offset += len(v)
    if not keep_v:
        return manifold3d.Manifold(), rejected, status
    return _manifold(np.concatenate(keep_v), np.concatenate(keep_f)), rejected, status


def manifold_map(scene: Scene, plan: MapPlan) -> PeerResult:
    """The map of ``plan`` the manifold3d way.

    Timed: gathering, Manifold construction (and the per-element fallback), slab intersection,
    projection and rasterising. Not timed (``prep_seconds``): welding the scene's triangle soup into
    indexed meshes, which a manifold3d user reading IFC would get from the geometry kernel.
    """
    import manifold3d

    t0 = time.perf_counter()
    ids = near_elements(scene, plan)
    closed_ids = ids[scene.elements.closed[ids]]
    triangles, owner = scene.elements.triangles_of(closed_ids)
    gather = time.perf_counter() - t0
    welded = weld_per_element(triangles, owner, len(closed_ids))
    prep = time.perf_counter() - t0 - gather

    t1 = time.perf_counter()
    solid, rejected, first_status = _solid_of(welded, len(closed_ids))
    t2 = time.perf_counter()
    f = plan.frame
    box = manifold3d.Manifold.cube(
        (f.width * f.resolution_m, f.height * f.resolution_m, max(plan.z_hi - plan.z_lo, 1e-6))
    ).translate((f.origin_x, f.origin_y, plan.z_lo))
    contours = (solid ^ box).project().to_polygons()
    t3 = time.perf_counter()
    occupied = raster_polygons([np.asarray(c, dtype=np.float64) for c in contours], f)
    t4 = time.perf_counter()
    seconds = gather + t4 - t1
    info = {
        "elements": len(ids),
        "closed_elements": len(closed_ids),
        "dropped_open": len(ids) - len(closed_ids),
        "dropped_rejected": len(rejected),
        "merged_status": first_status,
        "final_status": str(solid.status()).rsplit(".", 1)[-1],
        "contours": len(contours),
        "triangles_in": len(triangles),
        "gather_s": gather,
        "build_s": t2 - t1,
        "boolean_s": t3 - t2,
        "raster_s": t4 - t3,
    }
    kept = np.delete(closed_ids, np.asarray(rejected, dtype=np.intp))
    return PeerResult(occupied, seconds, prep, info, kept)
