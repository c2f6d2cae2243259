"""Does the points map localize? A simulated 3D lidar registered to the twin's cloud (issue 32).

For random poses on every storey of a model, a 16 x 1,800-ray lidar (vertical -15..+15 deg, 30 m range,
1 cm range noise) is ray cast against the building's meshes as a robot would see them: glass
transparent (left out), openings left out, and the furniture moved from where the model has it (each
piece shifted 0.2-0.5 m in a random direction), so the scans are not the map's own meshes. Each scan
(downsampled to 0.1 m) is registered with Open3D's point-to-plane ICP (plain: one stage with 1 m
correspondences; ``--robust``: 1 m, 0.5 m and 0.2 m stages with a Tukey kernel) from a start perturbed
by 0.3 m and 5 deg (yaw) to

- the twin's cloud: a ``points`` skill with the issue's default selection (no glass, no furniture, no
  openings), 0.1 m;
- the naive baseline: a cloud of every element's surfaces (glass and furniture where the model has
  them; openings left out, as they are no surfaces), 0.1 m;

and, to show what the selection does, to the twin's cloud with the 2D localization skill's selection
(proxies and flow terminals left out too); counted converged when within 5 cm and 1 deg of the true
pose. Poses: x, y uniform in the storey's
extent, the lidar 1.0 m above the floor, yaw uniform; kept when a floor is under it (within 1.5 m), no
surface is within 0.4 m around it and 70 % of the rays return (inside the building). Storeys whose band
is under 2 m high (ceiling voids modelled as storeys) are skipped: no robot drives there.

Needs ``open3d`` (PyPI; not a project dependency)::

    python benchmarks/localize.py --store STORE_DIR [--poses 10] [--seed 32] [--robust] [--json OUT.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
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
from twin.maps.scene import load_scene  # noqa: E402
from twin.selection.skill_selection import selection_query  # noqa: E402
from twin.selection.skills import parse_skill  # noqa: E402

TWIN = {
    "kind": "points",
    "exclude_types": ["IfcOpeningElement", "IfcFurnishingElement"],
    "exclude_materials": ["glass"],
}
TWIN_2D = {  # the 2D localization skill's selection: proxies and flow terminals out too
    "kind": "points",
    "exclude_types": [
        "IfcOpeningElement",
        "IfcFurnishingElement",
        "IfcBuildingElementProxy",
        "IfcFlowTerminal",
    ],
    "exclude_materials": ["glass"],
}
BASELINE = {"kind": "points", "exclude_types": ["IfcOpeningElement"]}
SEEN = {"kind": "points", "exclude_types": ["IfcOpeningElement"], "exclude_materials": ["glass"]}
FURNITURE = {"kind": "points", "include_types": ["IfcFurnishingElement"]}
Array = npt.NDArray[np.float64]


def _iris(store: EmbeddedStore, data: dict[str, Any]) -> list[str]:
    skill = parse_skill("q", data)
    return [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]


def _rays(origin: Array, yaw: float) -> tuple[Array, Array]:
    """16 x 1,800 lidar rays from ``origin``: (directions in the world, directions in the sensor)."""
    el = np.deg2rad(np.linspace(-15.0, 15.0, 16))
    az = np.linspace(0.0, 2 * np.pi, 1800, endpoint=False)
    e, a = np.meshgrid(el, az, indexing="ij")
    local = np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], axis=-1).reshape(-1, 3)
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return local @ rot.T, local


def _cast(scene: Any, origin: Array, dirs: Array) -> Array:
    rays = np.concatenate([np.broadcast_to(origin, dirs.shape), dirs], axis=1).astype(np.float32)
    hit = scene.cast_rays(o3d.core.Tensor(rays))
    return np.asarray(hit["t_hit"].numpy(), dtype=np.float64)


def _cloud(xyz: Array, *, normals: bool) -> Any:
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz))
    if normals:
        pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=0.3, max_nn=20))
    return pc


def _pose(x: float, y: float, z: float, yaw: float) -> Array:
    c, s = np.cos(yaw), np.sin(yaw)
    t = np.eye(4)
    t[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    t[:3, 3] = (x, y, z)
    return t


def _register(scan: Any, target: Any, start: Array, *, robust: bool) -> Array:
    """Point-to-plane ICP: plain (one stage, 1 m correspondences), or robust (1 m, 0.5 m, 0.2 m stages
    with a Tukey kernel of half the stage's distance: points with no counterpart, such as moved
    furniture, stop pulling)."""
    reg = o3d.pipelines.registration
    if not robust:
        stages = [(1.0, reg.TransformationEstimationPointToPlane(), 60)]
    else:
        stages = [
            (d, reg.TransformationEstimationPointToPlane(reg.TukeyLoss(k=d / 2)), 30) for d in (1.0, 0.5, 0.2)
        ]
    pose = start
    for distance, estimation, iterations in stages:
        result = reg.registration_icp(
            scan, target, distance, pose, estimation, reg.ICPConvergenceCriteria(max_iteration=iterations)
        )
        pose = np.asarray(result.transformation)
    return pose


def run(store_dir: Path, poses: int, seed: int, *, robust: bool = False) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    store = EmbeddedStore.open(store_dir, read_only=True)
    scene = load_scene(store)
    els = scene.elements
    seen_ids = els.indices_of(tuple(_iris(store, SEEN)))
    furniture = set(els.indices_of(tuple(_iris(store, FURNITURE))).tolist())
    # what the lidar sees: no glass, no openings; furniture moved
    tris = []
    for i in seen_ids.tolist():
        t = els.triangles[els.start[i] : els.start[i + 1]]
        if i in furniture:
            angle = rng.uniform(0, 2 * np.pi)
            t = t + np.array([np.cos(angle), np.sin(angle), 0.0]) * rng.uniform(0.2, 0.5)
        tris.append(t)
    world = np.concatenate(tris).reshape(-1, 3)
    faces = np.arange(len(world), dtype=np.int32).reshape(-1, 3)
    ray_scene = o3d.t.geometry.RaycastingScene()
    mesh = o3d.t.geometry.TriangleMesh()
    mesh.vertex.positions = o3d.core.Tensor(world.astype(np.float32))
    mesh.triangle.indices = o3d.core.Tensor(faces)
    ray_scene.add_triangles(mesh)
    twin_skill = parse_skill("lidar3d", TWIN)
    clouds = [
        ("twin", twin_skill, _iris(store, TWIN)),
        ("twin_2d_selection", parse_skill("lidar3d-2d", TWIN_2D), _iris(store, TWIN_2D)),
        ("baseline", parse_skill("everything", BASELINE), _iris(store, BASELINE)),
    ]
    out: dict[str, Any] = {
        "storeys": [],
        "triangles_cast": len(faces),
        "icp": "robust" if robust else "plain",
    }
    totals = {name: 0 for name, _, _ in clouds} | {"poses": 0}
    for storey in scene.storeys:
        if plan_points(scene, twin_skill, storey.key, ()).band[1] < 2.0:
            print(f"  {storey.key}: skipped (a band under 2 m high)", flush=True)
            continue
        maps = {}
        for name, skill, iris in clouds:
            cloud = build_points(scene, plan_points(scene, skill, storey.key, iris))
            xyz = cloud.xyz.copy()
            xyz[:, 2] += storey.elevation_m
            maps[name] = (_cloud(xyz, normals=True), len(cloud))
        xmin, ymin, xmax, ymax = storey.extent
        row: dict[str, Any] = {"storey": storey.key, "points": {k: v[1] for k, v in maps.items()}}
        ok = {name: 0 for name, _, _ in clouds}
        errors: dict[str, list[tuple[float, float]]] = {name: [] for name, _, _ in clouds}
        tried = found = 0
        while found < poses and tried < 400 * poses:
            tried += 1
            x, y = rng.uniform(xmin, xmax), rng.uniform(ymin, ymax)
            z = storey.elevation_m + 1.0
            origin = np.array([x, y, z])
            down = _cast(ray_scene, origin, np.array([[0.0, 0.0, -1.0]]))
            if not down[0] < 1.5:
                continue
            ring = np.stack(
                [
                    np.cos(np.linspace(0, 2 * np.pi, 16)),
                    np.sin(np.linspace(0, 2 * np.pi, 16)),
                    0 * np.ones(16),
                ],
                1,
            )
            if (_cast(ray_scene, origin, ring) < 0.4).any():
                continue
            yaw = rng.uniform(-np.pi, np.pi)
            dirs, local = _rays(origin, yaw)
            t = _cast(ray_scene, origin, dirs)
            hit = t < 30.0
            if hit.mean() < 0.7:
                continue
            found += 1
            r = t[hit] + rng.normal(0.0, 0.01, int(hit.sum()))
            scan = _cloud(local[hit] * r[:, None], normals=False).voxel_down_sample(0.1)
            truth = _pose(x, y, z, yaw)
            d = rng.uniform(0, 2 * np.pi)
            start = _pose(
                x + 0.3 * np.cos(d), y + 0.3 * np.sin(d), z, yaw + np.deg2rad(5.0) * rng.choice([-1, 1])
            )
            for name, (target, _) in maps.items():
                reg_t = _register(scan, target, start, robust=robust)
                delta = np.linalg.inv(truth) @ reg_t
                te = float(np.linalg.norm(delta[:3, 3]))
                re = float(np.degrees(np.arccos(np.clip((np.trace(delta[:3, :3]) - 1) / 2, -1.0, 1.0))))
                errors[name].append((te, re))
                ok[name] += te < 0.05 and re < 1.0
        row |= {
            "poses": found,
            "converged": ok,
            "median_error_cm": {
                k: 100 * float(np.median([e[0] for e in v])) if v else None for k, v in errors.items()
            },
        }
        out["storeys"].append(row)
        totals["poses"] += found
        for name, count in ok.items():
            totals[name] += count
        print(f"  {storey.key}: {found} poses, converged {ok}", flush=True)
    out["totals"] = totals
    store.close()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--store", type=Path, required=True)
    ap.add_argument("--poses", type=int, default=10)
    ap.add_argument("--seed", type=int, default=32)
    ap.add_argument("--robust", action="store_true", help="coarse-to-fine ICP with a Tukey kernel")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    t = time.perf_counter()
    result = run(args.store, args.poses, args.seed, robust=args.robust)
    result["seconds"] = time.perf_counter() - t
    print(json.dumps(result, indent=2))
    if args.json:
        args.json.write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
