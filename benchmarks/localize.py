"""Does the points map localize? A simulated 3D lidar registered to the twin's cloud (issue 32).

The world a lidar sees: every element's meshes ray cast with Open3D's ``RaycastingScene`` (all storeys),
glass transparent (left out), openings left out, and every piece of furniture moved 0.2-0.5 m in a
random direction from where the model has it, so that scans are not the map's own meshes.

Poses, where a robot can be: on each storey whose band is at least 2 m high (ceiling voids modelled as
storeys are skipped), a cell of the twin's ``navigation`` map (robot 1.5 m high, 0.1 m cells, free space
inside the model's spaces) that is at least 0.5 m from anything occupied or outside the spaces, and in
the simulated world (furniture moved) nothing within 0.5 m of the robot's body (distances at 0.6, 1.0
and 1.4 m above the floor) and a floor 0.8-1.2 m under the lidar (not over a stair or a shaft). Yaw
uniform. The lidar: 16 x 1,800 rays (vertical -15..+15 deg), 30 m range, 1 cm range noise, 1.0 m above
the floor.

Registration, the same for every cloud, coarse to fine in three stages (the scan and the map
voxel-downsampled to 0.4, 0.2 and 0.1 m; correspondences within 1.0, 0.5 and 0.25 m; a Tukey kernel
of half that, so points with no counterpart, such as moved furniture or what the lidar sees of other
storeys, stop pulling), from a start 0.3 m (random horizontal direction) and 5 deg (yaw, either sign)
off the true pose, its roll and pitch off by a resting IMU's error (normal, 0.1 deg):

- ``planar``: point-to-plane ICP in x, y and yaw (numpy Gauss-Newton on Open3D's nearest neighbours):
  a ground robot's localizer, whose lidar height is its mount and whose roll and pitch come from
  gravity; the start's z, roll and pitch are kept;
- ``planar_oriented``: the same, pairing each scan point (its normal turned to the sensor) with the
  nearest of its 4 nearest map points whose outward normal faces the same way: a wall's far face, a
  wall thickness (0.1-0.3 m) away, is no longer a match (a rejector of incompatible normals, as
  PCL's and libpointmatcher's). The map's normals are the cloud's own (the twin's PCD carries them:
  ``normal_x normal_y normal_z``); at the coarse stages the map is downsampled per voxel and normal
  direction (its dominant axis and sign: a thin wall's two faces stay two points, each with its mean
  normal). ``--map-normals mesh``: the model's instead (the surface nearest each downsampled point, by
  the meshes' winding), as this benchmark's first runs took them;
- ``p2l``: Open3D's point-to-plane ICP in 6 degrees of freedom, as ``hdl_localization`` and Autoware's
  ``ndt_scan_matcher`` estimate (with NDT, which Open3D lacks);
- ``gicp``: Open3D's generalized ICP in 6 degrees of freedom (plane-to-plane covariances);
- ``p2l_single``: the first version's robust ICP (one 0.1 m scale, 1.0, 0.5 and 0.2 m stages).

Converged: within 5 cm and 1 deg (all six degrees of freedom) of the true pose.

Clouds (0.1 m ``points`` skills):

- ``twin``: the issue's default selection (no glass, no furniture, no openings);
- ``twin_furniture``: the same with furniture kept where the model has it;
- ``baseline``: every element's surfaces (glass and furniture as modelled; openings are no surfaces).

Degenerate scans are counted apart, decided before any registration from the scan alone: over its
returns on structure (not furniture), one per 0.1 m voxel, ``sum n n^T`` of the true surface normals'
horizontal parts; when its smaller eigenvalue is under ``--degenerate`` (50: about half a square metre
of surface faces the weakest horizontal direction, e.g. along a plain corridor) the structure cannot
fix the robot's position in that direction.

Needs ``open3d`` (PyPI; not a project dependency)::

    python benchmarks/localize.py --store STORE_DIR [--poses 20] [--seed 5]
        [--methods planar_oriented,planar,p2l] [--clouds twin,twin_furniture,baseline]
        [--storeys a,b] [--degenerate 50] [--map-normals cloud|mesh] [--json OUT.json]
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import open3d as o3d  # noqa: E402

from twin.graph.rdf import literal_value  # noqa: E402
from twin.graph.store import EmbeddedStore  # noqa: E402
from twin.maps.points import build_points, plan_points  # noqa: E402
from twin.maps.render import build_map, dilate_disk, plan_map  # noqa: E402
from twin.maps.scene import Scene, StoreyInfo, load_scene  # noqa: E402
from twin.selection.skill_selection import selection_query  # noqa: E402
from twin.selection.skills import parse_skill  # noqa: E402

log = logging.getLogger("localize")

CLOUDS: dict[str, dict[str, Any]] = {
    "twin": {
        "kind": "points",
        "exclude_types": ["IfcOpeningElement", "IfcFurnishingElement"],
        "exclude_materials": ["glass"],
    },
    "twin_furniture": {
        "kind": "points",
        "exclude_types": ["IfcOpeningElement"],
        "exclude_materials": ["glass"],
    },
    "baseline": {"kind": "points", "exclude_types": ["IfcOpeningElement"]},
}
SEEN = {"kind": "points", "exclude_types": ["IfcOpeningElement"], "exclude_materials": ["glass"]}
FURNITURE = {"kind": "points", "include_types": ["IfcFurnishingElement"]}
NAVIGATION = {
    "kind": "navigation",
    "resolution_m": 0.1,
    "robot_height_m": 1.5,
    "floor_clearance_m": 0.05,
    "exclude_types": ["IfcOpeningElement"],
    "unknown_outside": True,
}
LIDAR_HEIGHT = 1.0
CLEARANCE = 0.5
RANGE = 30.0
OFFSET_M, OFFSET_DEG = 0.3, 5.0
IMU_DEG = 0.1  # roll and pitch of the start: a resting IMU's gravity direction, 1 sigma
GOOD_M, GOOD_DEG = 0.05, 1.0
RELATIVE = 1e-6  # ICP stops when fitness and RMSE change less than this (relative), or after the iterations
EPSILON = 1e-3  # generalized ICP: a plane's covariance is diag(1, 1, EPSILON) in its frame
CROP = RANGE + 2.0  # map points farther than this from the start can never be a correspondence

# (voxel m, max correspondence m, iterations) per stage; the kernel is Tukey with k = distance * KERNEL
KERNEL = 0.5
STAGES: dict[str, list[tuple[float, float, int]]] = {
    "gicp": [(0.4, 1.0, 30), (0.2, 0.5, 30), (0.1, 0.25, 30)],
    "p2l": [(0.4, 1.0, 30), (0.2, 0.5, 30), (0.1, 0.25, 30)],
    "planar": [(0.4, 1.0, 30), (0.2, 0.5, 30), (0.1, 0.25, 30)],
    "planar_oriented": [(0.4, 1.0, 30), (0.2, 0.5, 30), (0.1, 0.25, 30)],
    "p2l_single": [(0.1, 1.0, 30), (0.1, 0.5, 30), (0.1, 0.2, 30)],  # this benchmark's first version
}

Array = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]


def _iris(store: EmbeddedStore, data: dict[str, Any]) -> list[str]:
    skill = parse_skill("q", data)
    return [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]


def _rot_z(yaw: float) -> Array:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _pose(x: float, y: float, z: float, yaw: float) -> Array:
    t = np.eye(4)
    t[:3, :3] = _rot_z(yaw)
    t[:3, 3] = (x, y, z)
    return t


def _beams() -> Array:
    """The 16 x 1,800 ray directions in the sensor's frame."""
    el = np.deg2rad(np.linspace(-15.0, 15.0, 16))
    az = np.linspace(0.0, 2 * np.pi, 1800, endpoint=False)
    e, a = np.meshgrid(el, az, indexing="ij")
    return np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], axis=-1).reshape(-1, 3)


def _ray_scene(triangles: Array) -> Any:
    xyz = triangles.reshape(-1, 3)
    mesh = o3d.t.geometry.TriangleMesh()
    mesh.vertex.positions = o3d.core.Tensor(xyz.astype(np.float32))
    mesh.triangle.indices = o3d.core.Tensor(np.arange(len(xyz), dtype=np.int32).reshape(-1, 3))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(mesh)
    return scene


def _cast(scene: Any, origin: Array, dirs: Array) -> Any:
    rays = np.concatenate([np.broadcast_to(origin, dirs.shape), dirs], axis=1).astype(np.float32)
    return scene.cast_rays(o3d.core.Tensor(rays))


@dataclass(frozen=True, eq=False, slots=True)
class World:
    """What the lidar sees: a ray-casting scene and, per triangle, whether it is furniture."""

    scene: Any
    furniture: npt.NDArray[np.bool_]
    owner: IntArray
    """Per triangle, the element (its index in the scene) it belongs to."""
    closed: Any
    """The model as it is, glass and furniture in (doors closed): to tell inside from outside."""

    @classmethod
    def build(cls, store: EmbeddedStore, scene: Scene, rng: np.random.Generator) -> World:
        els = scene.elements
        seen = els.indices_of(tuple(_iris(store, SEEN)))
        furniture = set(els.indices_of(tuple(_iris(store, FURNITURE))).tolist())
        tris, flags, owners = [], [], []
        for i in seen.tolist():
            t = els.triangles[els.start[i] : els.start[i + 1]]
            moved = i in furniture
            if moved:
                angle = rng.uniform(0, 2 * np.pi)
                t = t + np.array([np.cos(angle), np.sin(angle), 0.0]) * rng.uniform(0.2, 0.5)
            tris.append(t)
            flags.append(np.full(len(t), moved))
            owners.append(np.full(len(t), i, dtype=np.intp))
        everything = els.indices_of(tuple(_iris(store, CLOUDS["baseline"])))
        closed, _ = els.triangles_of(everything)
        return cls(
            _ray_scene(np.concatenate(tris)),
            np.concatenate(flags),
            np.concatenate(owners),
            _ray_scene(closed),
        )

    def cast(self, origin: Array, dirs: Array) -> tuple[Array, IntArray, Array]:
        """``(t, triangle, normal)`` per ray (t inf and triangle -1 on a miss)."""
        hit = _cast(self.scene, origin, dirs)
        prim = hit["primitive_ids"].numpy().astype(np.int64)
        prim[prim == np.iinfo(np.uint32).max] = -1
        return (
            np.asarray(hit["t_hit"].numpy(), dtype=np.float64),
            prim.astype(np.intp),
            np.asarray(hit["primitive_normals"].numpy(), dtype=np.float64),
        )

    def enclosed(self, origin: Array) -> bool:
        """Inside the building: the model (glass in) above and around in 90 % of 72 directions."""
        a = np.linspace(0.0, 2 * np.pi, 72, endpoint=False)
        dirs = np.concatenate([np.stack([np.cos(a), np.sin(a), 0 * a], axis=1), [[0.0, 0.0, 1.0]]])
        t = _cast(self.closed, origin, dirs)["t_hit"].numpy()
        return bool(t[-1] < 10.0 and (t[:-1] < 2 * RANGE).mean() >= 0.9)

    def surface_normals(self, points: Array) -> Array:
        """The outward normal (the mesh's winding) of the model's surface nearest each point."""
        near = self.closed.compute_closest_points(o3d.core.Tensor(points.astype(np.float32)))
        return np.asarray(near["primitive_normals"].numpy(), dtype=np.float64)

    def distance(self, points: Array) -> Array:
        return np.asarray(
            self.scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy(), dtype=np.float64
        )


def plane_covariances(cov: Array, epsilon: float = EPSILON) -> Array:
    """Generalized ICP's plane-to-plane covariances: each neighbourhood's eigenvalues set to 1, 1 and
    ``epsilon`` (what Open3D does when it estimates them itself; raw ones are singular on flat maps)."""
    _, vecs = np.linalg.eigh(cov)
    scale = np.array([epsilon, 1.0, 1.0])
    return np.asarray(np.einsum("nij,j,nkj->nik", vecs, scale, vecs))


@dataclass(frozen=True, eq=False, slots=True)
class Target:
    """A map cloud per stage voxel size, with normals and covariances, and its xy for cropping."""

    levels: dict[float, tuple[Any, Array]]
    outward: dict[float, tuple[Array, Array]]
    """Per level, points with outward normals (``planar_oriented``'s map): the cloud's own normals,
    downsampled per voxel and normal direction, or the model's at the level's points."""

    @classmethod
    def build(
        cls,
        xyz: Array,
        voxels: set[float],
        *,
        covariances: bool,
        normals: Array | None = None,
        world: World | None = None,
    ) -> Target:
        """With ``normals`` (the cloud's outward normals), or else ``world`` (the model's, at the nearest
        surface), the oriented levels; the others' normals are estimated from 20 neighbours (either
        sign)."""
        full = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz))
        levels: dict[float, tuple[Any, Array]] = {}
        outward: dict[float, tuple[Array, Array]] = {}
        for v in sorted(voxels):
            pc = o3d.geometry.PointCloud(full) if v <= 0.1 + 1e-9 else full.voxel_down_sample(v)
            pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=3 * v, max_nn=20))
            if normals is not None:
                outward[v] = (xyz, normals) if v <= 0.1 + 1e-9 else downsample_oriented(xyz, normals, v)
            elif world is not None:
                pts = np.asarray(pc.points)
                outward[v] = (pts, world.surface_normals(pts))
            if covariances:
                pc.estimate_covariances(o3d.geometry.KDTreeSearchParamKNN(20))
                pc.covariances = o3d.utility.Matrix3dVector(plane_covariances(np.asarray(pc.covariances)))
            levels[v] = (pc, np.asarray(pc.points)[:, :2].copy())
        return cls(levels, outward)

    def near(self, voxel: float, xy: Array) -> Any:
        pc, pts = self.levels[voxel]
        keep = np.flatnonzero((np.abs(pts - xy) < CROP).all(axis=1))
        return pc.select_by_index(keep)

    def near_arrays(self, voxel: float, xy: Array, *, outward: bool) -> tuple[Array, Array]:
        """``(points, normals)`` within reach of ``xy``; with outward normals or the estimated ones."""
        if outward:
            points, normals = self.outward[voxel]
        else:
            pc, _ = self.levels[voxel]
            points, normals = np.asarray(pc.points), np.asarray(pc.normals)
        keep = np.flatnonzero((np.abs(points[:, :2] - xy) < CROP).all(axis=1))
        return points[keep], normals[keep]


def downsample_oriented(xyz: Array, normals: Array, voxel: float) -> tuple[Array, Array]:
    """One point per (voxel, normal direction): the mean of the points whose normal's dominant axis and
    sign agree, with their mean normal (unit): a wall thinner than the voxel keeps both faces apart.
    Points with a zero normal (a degenerate triangle's) are left out."""
    ok = np.abs(normals).max(axis=1) > 0
    xyz, normals = xyz[ok], normals[ok].astype(np.float64)
    axis = np.argmax(np.abs(normals), axis=1)
    direction = 2 * axis + (normals[np.arange(len(axis)), axis] < 0)
    cell = np.floor(xyz / voxel).astype(np.int64)
    groups = np.column_stack([cell, direction])
    _, inverse = np.unique(groups, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    count = np.bincount(inverse).astype(np.float64)
    pts = np.stack([np.bincount(inverse, xyz[:, a]) for a in range(3)], axis=1) / count[:, None]
    nrm = np.stack([np.bincount(inverse, normals[:, a]) for a in range(3)], axis=1)
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1), 1e-12)[:, None]
    return pts, nrm


def register(scan_xyz: Array, target: Target, start: Array, method: str) -> Array:
    """Coarse-to-fine registration of a scan (sensor frame) to a map cloud from ``start``."""
    if method in {"planar", "planar_oriented"}:
        return register_planar(scan_xyz, target, start, STAGES[method], oriented=method == "planar_oriented")
    reg = o3d.pipelines.registration
    raw = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(scan_xyz))
    pose = start
    for voxel, distance, iterations in STAGES[method]:
        scan = raw.voxel_down_sample(voxel)
        near = target.near(voxel, start[:2, 3])
        criteria = reg.ICPConvergenceCriteria(RELATIVE, RELATIVE, iterations)
        if method == "gicp":
            scan.estimate_covariances(o3d.geometry.KDTreeSearchParamKNN(20))
            scan.covariances = o3d.utility.Matrix3dVector(plane_covariances(np.asarray(scan.covariances)))
            # its residuals are Mahalanobis: along a normal, metres / sqrt(2 epsilon); the kernel likewise
            gicp_kernel = reg.TukeyLoss(k=distance * KERNEL / np.sqrt(2 * EPSILON))
            est = reg.TransformationEstimationForGeneralizedICP(EPSILON, gicp_kernel)
            result = reg.registration_generalized_icp(scan, near, distance, pose, est, criteria)
        else:
            est = reg.TransformationEstimationPointToPlane(reg.TukeyLoss(k=distance * KERNEL))
            result = reg.registration_icp(scan, near, distance, pose, est, criteria)
        pose = np.asarray(result.transformation)
    return pose


def _yaw_of(pose: Array) -> float:
    return float(np.arctan2(pose[1, 0], pose[0, 0]))


def register_planar(
    scan_xyz: Array,
    target: Target,
    start: Array,
    stages: list[tuple[float, float, int]],
    *,
    oriented: bool = False,
) -> Array:
    """Point-to-plane ICP in x, y and yaw only, a Tukey kernel per stage: a ground robot's localizer,
    whose lidar height above the floor is its mount and whose roll and pitch come from gravity (an
    IMU); these three stay as ``start`` has them. ``oriented``: a scan point (its normal turned to the
    sensor) pairs with the nearest of its 4 nearest map points whose outward normal faces the same way,
    not with the far side of a wall (a rejector of incompatible normals, as PCL's and libpointmatcher's)."""
    raw = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(scan_xyz))
    tilt = _rot_z(-_yaw_of(start)) @ start[:3, :3]  # roll and pitch: start = Rz(yaw) @ tilt
    x, y, z, yaw = float(start[0, 3]), float(start[1, 3]), float(start[2, 3]), _yaw_of(start)
    for voxel, distance, iterations in stages:
        down = raw.voxel_down_sample(voxel)
        pts = np.asarray(down.points) @ tilt.T
        if oriented:
            down.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=3 * voxel, max_nn=20))
            down.orient_normals_towards_camera_location(np.zeros(3))
            scan_n = np.asarray(down.normals) @ tilt.T
        tgt, nrm = target.near_arrays(voxel, start[:2, 3], outward=oriented)
        index = o3d.core.nns.NearestNeighborSearch(o3d.core.Tensor(tgt.astype(np.float32)))
        index.knn_index()
        k = distance * KERNEL
        for _ in range(iterations):
            rot = _rot_z(yaw)
            rp = pts @ rot.T
            moved = rp + np.array([x, y, z])
            found, d2 = index.knn_search(o3d.core.Tensor(moved.astype(np.float32)), 4 if oriented else 1)
            cand, dist2 = found.numpy().astype(np.intp), d2.numpy()
            pick = np.zeros(len(pts), dtype=np.intp)
            if oriented:
                facing = np.einsum("nkj,nj->nk", nrm[cand], scan_n @ rot.T) > 0.0
                pick = np.argmax(facing, axis=1)
                dist2 = np.where(facing, dist2, np.inf)
            rows = np.arange(len(pts))
            j = cand[rows, pick]
            keep = dist2[rows, pick] < distance * distance
            if keep.sum() < 10:
                break
            n, q, rp_k = nrm[j[keep]], tgt[j[keep]], rp[keep]
            r = np.einsum("ij,ij->i", n, moved[keep] - q)
            w = np.where(np.abs(r) < k, (1 - (r / k) ** 2) ** 2, 0.0)
            jac = np.stack([n[:, 0], n[:, 1], n[:, 1] * rp_k[:, 0] - n[:, 0] * rp_k[:, 1]], axis=1)
            h = jac.T @ (jac * w[:, None]) + 1e-9 * np.eye(3)
            step = np.linalg.solve(h, -jac.T @ (w * r))
            x, y, yaw = x + step[0], y + step[1], yaw + step[2]
            if np.abs(step[:2]).max() < 1e-4 and abs(step[2]) < 1e-5:
                break
    out = np.eye(4)
    out[:3, :3] = _rot_z(yaw) @ tilt
    out[:3, 3] = (x, y, z)
    return out


def _rot_x(a: float) -> Array:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_y(a: float) -> Array:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def perturbed(truth: Array, rng: np.random.Generator) -> Array:
    """The start: 0.3 m off in a random horizontal direction, 5 deg off in yaw (either sign), and roll
    and pitch off by an IMU's gravity estimate (normal, 0.1 deg); z (the lidar's mount) as true."""
    d = rng.uniform(0, 2 * np.pi)
    sign = float(rng.choice([-1.0, 1.0]))
    roll, pitch = np.deg2rad(rng.normal(0.0, IMU_DEG, 2))
    start = truth.copy()
    start[:3, :3] = _rot_z(_yaw_of(truth) + sign * np.deg2rad(OFFSET_DEG)) @ _rot_y(pitch) @ _rot_x(roll)
    start[:2, 3] += OFFSET_M * np.array([np.cos(d), np.sin(d)])
    return start


def pose_error(truth: Array, estimate: Array) -> tuple[float, float]:
    """Translation (m) and rotation (deg) between two poses."""
    delta = np.linalg.inv(truth) @ estimate
    angle = np.arccos(np.clip((np.trace(delta[:3, :3]) - 1) / 2, -1.0, 1.0))
    return float(np.linalg.norm(delta[:3, 3])), float(np.degrees(angle))


def weakest_constraint(points: Array, normals: Array) -> tuple[float, Array]:
    """How well a scan's structure fixes the robot's horizontal position: over one return per 0.1 m
    voxel, the smallest eigenvalue of the x, y block of ``sum n n^T`` (about how many voxels of surface
    face the weakest horizontal direction) and that direction."""
    if len(points) == 0:
        return 0.0, np.zeros(2)
    _, first = np.unique(np.floor(points / 0.1).astype(np.int64), axis=0, return_index=True)
    n = normals[first][:, :2]
    vals, vecs = np.linalg.eigh(n.T @ n)
    return float(vals[0]), vecs[:, 0]


@dataclass(slots=True)
class Candidates:
    """Where a robot can stand on one storey: cell centres of the navigation map with clearance."""

    xy: Array
    stats: dict[str, int] = field(default_factory=dict)


def candidates(scene: Scene, store: EmbeddedStore, storey: StoreyInfo) -> Candidates:
    nav = parse_skill("robot", NAVIGATION)
    on_storey = [iri for iri, st in scene.space_storey.items() if st == storey.iri]
    if not on_storey:  # no spaces to tell inside from outside: free space anywhere
        nav = parse_skill("robot", {k: v for k, v in NAVIGATION.items() if k != "unknown_outside"})
    grid = build_map(scene, plan_map(scene, nav, storey.key, _iris(store, NAVIGATION)))
    blocked = grid.data != 0
    clear = ~dilate_disk(blocked, CLEARANCE / grid.frame.resolution_m)
    rows, cols = np.nonzero(clear)
    xs, ys = grid.frame.cell_centres()
    xy = np.stack([xs[cols], ys[rows]], axis=1)
    return Candidates(xy, {"free_cells": int((~blocked).sum()), "clear_cells": len(xy)})


def _summary(records: list[dict[str, Any]], names: list[str]) -> dict[str, Any]:
    out: dict[str, Any] = {"poses": len(records)}
    for subset, rows in (
        ("all", records),
        ("observable", [r for r in records if not r["degenerate"]]),
        ("degenerate", [r for r in records if r["degenerate"]]),
    ):
        part: dict[str, Any] = {"poses": len(rows)}
        for name in names:
            errs = [r["error"][name] for r in rows]
            ok = sum(te < GOOD_M and re < GOOD_DEG for te, re in errs)
            part[name] = {
                "converged": ok,
                "percent": round(100 * ok / len(rows), 1) if rows else None,
                "median_cm": round(100 * float(np.median([e[0] for e in errs])), 2) if errs else None,
                "median_deg": round(float(np.median([e[1] for e in errs])), 3) if errs else None,
            }
        out[subset] = part
    return out


def run(
    store_dir: Path,
    poses: int,
    seed: int,
    *,
    methods: list[str],
    names: list[str],
    storeys: list[str] | None,
    degenerate: float,
    map_normals: str = "cloud",
) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    store = EmbeddedStore.open(store_dir, read_only=True)
    scene = load_scene(store)
    world = World.build(store, scene, rng)
    beams = _beams()
    skills = {name: parse_skill(name, CLOUDS[name]) for name in names}
    iris = {name: _iris(store, CLOUDS[name]) for name in names}
    voxels = {s[0] for m in methods for s in STAGES[m]}
    combos = [f"{name}@{m}" for m in methods for name in names]
    records: list[dict[str, Any]] = []
    storey_rows: list[dict[str, Any]] = []
    for storey in scene.storeys:
        if storeys and storey.key not in storeys:
            continue
        if plan_points(scene, skills[names[0]], storey.key, ()).band[1] < 2.0:
            log.info("%s: skipped (a band under 2 m high)", storey.key)
            continue
        cand = candidates(scene, store, storey)
        if not len(cand.xy):
            log.info("%s: skipped (no free space with %s m clearance)", storey.key, CLEARANCE)
            continue
        targets, sizes = {}, {}
        for name in names:
            cloud = build_points(scene, plan_points(scene, skills[name], storey.key, iris[name]))
            xyz = cloud.xyz.astype(np.float64)
            xyz[:, 2] += storey.elevation_m  # the cloud's z is above the storey's elevation
            oriented = "planar_oriented" in methods
            targets[name], sizes[name] = (
                Target.build(
                    xyz,
                    voxels,
                    covariances="gicp" in methods,
                    normals=cloud.normals.astype(np.float64) if oriented and map_normals == "cloud" else None,
                    world=world if oriented and map_normals == "mesh" else None,
                ),
                len(xyz),
            )
        found = tried = 0
        rejected = {"body": 0, "floor": 0, "outside": 0}
        z = storey.elevation_m + LIDAR_HEIGHT
        while found < poses and tried < 200 * poses:
            tried += 1
            x, y = cand.xy[rng.integers(len(cand.xy))] + rng.uniform(-0.05, 0.05, 2)
            body = np.array([[x, y, storey.elevation_m + h] for h in (0.6, 1.0, 1.4)])
            if (world.distance(body) < CLEARANCE).any():
                rejected["body"] += 1
                continue
            down, _, _ = world.cast(np.array([x, y, z]), np.array([[0.0, 0.0, -1.0]]))
            if not 0.8 <= down[0] <= 1.2:
                rejected["floor"] += 1
                continue
            if not world.enclosed(np.array([x, y, z])):
                rejected["outside"] += 1
                continue
            found += 1
            yaw = float(rng.uniform(-np.pi, np.pi))
            truth = _pose(x, y, z, yaw)
            t, prim, normals = world.cast(np.array([x, y, z]), beams @ truth[:3, :3].T)
            hit = t < RANGE
            r = t[hit] + rng.normal(0.0, 0.01, int(hit.sum()))
            scan = beams[hit] * r[:, None]
            on_furniture = world.furniture[prim[hit]]
            world_pts = scan @ truth[:3, :3].T + truth[:3, 3]
            weakest, direction = weakest_constraint(world_pts[~on_furniture], normals[hit][~on_furniture])
            start = perturbed(truth, rng)
            errors = {
                f"{name}@{m}": pose_error(truth, register(scan, targets[name], start, m))
                for m in methods
                for name in names
            }
            records.append(
                {
                    "storey": storey.key,
                    "x": round(float(x), 2),
                    "y": round(float(y), 2),
                    "yaw_deg": round(float(np.degrees(yaw)), 1),
                    "returns": round(float(hit.mean()), 3),
                    "furniture": round(float(on_furniture.mean()), 3) if hit.any() else 0.0,
                    "median_range": round(float(np.median(t[hit])), 2) if hit.any() else None,
                    "weakest": round(weakest, 1),
                    "weakest_dir": [round(float(v), 2) for v in direction],
                    "degenerate": weakest < degenerate,
                    "error": {k: (round(v[0], 4), round(v[1], 3)) for k, v in errors.items()},
                }
            )
            log.info(
                "%s (%.1f, %.1f) furn %.2f weakest %.0f: %s",
                storey.key,
                x,
                y,
                records[-1]["furniture"],
                weakest,
                " ".join(f"{k}={100 * e[0]:.1f}cm/{e[1]:.2f}deg" for k, e in errors.items()),
            )
        rows = [r for r in records if r["storey"] == storey.key]
        storey_rows.append(
            {"storey": storey.key, "points": sizes, "candidates": cand.stats, "rejected": rejected}
            | _summary(rows, combos)
        )
    store.close()
    return {
        "seed": seed,
        "map_normals": map_normals,
        "stages": {m: STAGES[m] for m in methods},
        "degenerate_below": degenerate,
        "storeys": storey_rows,
        "totals": _summary(records, combos),
        "poses": records,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--store", type=Path, required=True)
    ap.add_argument("--poses", type=int, default=20, help="poses per storey")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument(
        "--methods", default="planar_oriented,planar,p2l", help="comma-separated, of: " + ", ".join(STAGES)
    )
    ap.add_argument("--clouds", default=",".join(CLOUDS), help="comma-separated, of: " + ", ".join(CLOUDS))
    ap.add_argument("--storeys", default="", help="comma-separated storey keys (default: all)")
    ap.add_argument("--degenerate", type=float, default=50.0)
    ap.add_argument(
        "--map-normals",
        choices=("cloud", "mesh"),
        default="cloud",
        help="planar_oriented's map normals: the cloud's own (the PCD's) or the model's meshes'",
    )
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    names = [n for n in args.clouds.split(",") if n]
    unknown = [n for n in names if n not in CLOUDS] + [m for m in args.methods.split(",") if m not in STAGES]
    if unknown:
        ap.error(f"unknown clouds or methods {unknown}; known: {', '.join(CLOUDS)}; {', '.join(STAGES)}")
    t = time.perf_counter()
    result = run(
        args.store,
        args.poses,
        args.seed,
        methods=[m for m in args.methods.split(",") if m],
        names=names,
        storeys=[s for s in args.storeys.split(",") if s] or None,
        degenerate=args.degenerate,
        map_normals=args.map_normals,
    )
    result["seconds"] = round(time.perf_counter() - t, 1)
    print(json.dumps({k: v for k, v in result.items() if k != "poses"}, indent=1))
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
