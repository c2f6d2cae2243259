"""``twin map``: write skill maps of a store as nav2 map_server files, PNG previews and CDR messages,
``points`` skills' clouds as PCD files and CDR ``sensor_msgs/PointCloud2`` messages, and ``routes``
skills' route graphs as an Open-RMF nav graph and nav2 GeoJSON (:mod:`adapters.cli.map_routes`)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from adapters.cli.common import add_store_args, open_store
from adapters.cli.map_routes import write_routes
from adapters.ros import write_map_files
from adapters.ros.pcd import points_offset, write_points_files
from twin.config import Config
from twin.errors import MapError, SkillError
from twin.graph.rdf import literal_value
from twin.maps.points import PointsPlan, build_points, estimate_points, plan_points
from twin.maps.render import build_map, plan_map
from twin.maps.scene import load_scene
from twin.selection.skill_selection import selection_query


def check_points_size(plan: PointsPlan, estimate: int, cfg: Config, *, force: bool) -> None:
    """MapError (one line: the skill, the estimate, the limit) when a cloud is estimated over
    ``[maps] max_points_per_storey``, unless ``force``."""
    limit = cfg.max_points_per_storey
    if estimate > limit and not force:
        msg = (
            f"Skill {plan.skill.name!r} on storey {plan.storey.key!r}: about {estimate:,} points at "
            f"resolution_m={plan.resolution_m}, over the limit of {limit:,} ([maps] max_points_per_storey); "
            "use a coarser resolution_m, raise the limit, or give --force."
        )
        raise MapError(msg)


def cmd_map(args: argparse.Namespace, cfg: Config) -> int:
    if args.all_skills == bool(args.skill):
        msg = "Give either --skill NAME (repeatable) or --all-skills."
        raise SkillError(msg)
    names = args.skill or sorted([*cfg.skills, *cfg.routes])
    routes = [name for name in names if name in cfg.routes]  # kind = "routes": route graphs
    skills = [cfg.skill(name) for name in names if name not in cfg.routes]
    out = Path(args.out) if args.out else cfg.maps_out
    stamp_ns = time.time_ns()
    with open_store(args, cfg, read_only=True) as store:
        t0 = time.perf_counter()
        scene = load_scene(store)
        print(
            f"loaded {len(scene.elements)} elements ({len(scene.elements.triangles):,} triangles) "
            f"in {time.perf_counter() - t0:.2f} s"
        )
        for name in routes:
            write_routes(cfg, store, scene, name, out)
        storeys = [scene.storey(args.storey)] if args.storey else list(scene.storeys)
        if not storeys:
            msg = "The model has no storey (IfcBuildingStorey): maps are made per storey."
            raise MapError(msg)
        for skill in skills:
            iris = [literal_value(r["element"]) or "" for r in store.select(selection_query(skill))]
            for storey in storeys:
                t1 = time.perf_counter()
                if skill.kind == "points":
                    plan = plan_points(scene, skill, storey.key, iris, margin_m=cfg.margin_m)
                    check_points_size(plan, estimate_points(scene, plan), cfg, force=args.force)
                    cloud = build_points(scene, plan)
                    pfiles = write_points_files(cloud, out, stamp_ns=stamp_ns)
                    ox, oy = points_offset(cloud)
                    shift = f" (offset {ox}, {oy} m)" if (ox, oy) != (0.0, 0.0) else ""
                    print(
                        f"{storey.key}/{skill.name}: {len(cloud):,} points at {skill.resolution_m} m, "
                        f"{time.perf_counter() - t1:.2f} s -> {pfiles.pcd}{shift}"
                    )
                    continue
                grid = build_map(scene, plan_map(scene, skill, storey.key, iris, margin_m=cfg.margin_m))
                files = write_map_files(grid, out, stamp_ns=stamp_ns)
                occupied = int(grid.occupied().sum())
                print(
                    f"{storey.key}/{skill.name}: {grid.frame.width}x{grid.frame.height} cells, "
                    f"{occupied:,} occupied, {time.perf_counter() - t1:.2f} s -> {files.yaml}"
                )
    return 0


def add_map_parser(sub: Any) -> None:
    sp = sub.add_parser(
        "map", help="write skill maps (map_server YAML+PGM, PNG, CDR; points skills: PCD) per storey"
    )
    add_store_args(sp)
    sp.add_argument("--skill", action="append", help="a configured skill (repeatable)")
    sp.add_argument("--all-skills", action="store_true", help="every configured skill")
    sp.add_argument("--storey", help="one storey key (see 'twin stats'); default: every storey")
    sp.add_argument("--out", help="output directory (default: maps.out of the configuration)")
    sp.add_argument(
        "--force", action="store_true", help="build points clouds estimated over [maps] max_points_per_storey"
    )
    sp.set_defaults(func=cmd_map)
