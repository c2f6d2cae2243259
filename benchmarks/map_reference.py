"""Check every storey's default skill maps against an OpenCASCADE reference on the shared models.

The reference meshes the selected elements straight from the IFC file with OpenCASCADE in world
coordinates, slices them to each map's band and rasterises them cell by cell with shapely
(references/opencascade_maps.py, which the suite uses too: tests/adapters/ifc/test_maps_ifc.py checks
the four small models; Janesville is checked here because it is too slow for the suite). A cell is
missed when the reference surely occupies it (its square shrunk by 1 cm meets the geometry) and our
map does not, extra when our map occupies it and the reference cannot (its square grown by 1 cm does
not meet the geometry). Prints a table per model; exits 1 on any missed or extra cell, or a selected
element that only one side meshes.

    .venv/bin/python benchmarks/map_reference.py                 # every shared model
    .venv/bin/python benchmarks/map_reference.py janesville      # models by part of their file name
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from run import SHARED_IFC, find_models  # noqa: E402  (benchmarks/ is not a package)

WIDTHS = (9, 8, 8, 6, 6, 6)


def main() -> int:
    sys.path.insert(0, str(ROOT))
    from adapters.ifc import read_model
    from references.opencascade_maps import PINNED, TOLERANCE_M, compare_model, pinned
    from twin.config import load_config
    from twin.graph.import_model import import_model
    from twin.graph.store import EmbeddedStore
    from twin.maps.scene import load_scene

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*", help="parts of model file names (default: all)")
    args = parser.parse_args()
    if not SHARED_IFC.is_dir():
        print(f"shared models not found at {SHARED_IFC}; nothing to check")
        return 0
    paths = find_models(args.models, quick=False)
    config = load_config()
    skills = [config.skill("localization"), config.skill("navigation")]
    print(f"tolerance {TOLERANCE_M * 100:g} cm; skills {', '.join(s.name for s in skills)}")
    bad = 0
    for path in paths:
        t0 = time.perf_counter()
        model = read_model(path, static_types=config.import_.static_types)
        store = EmbeddedStore.open(None)
        import_model(store, model, base_iri="https://example.org/map-reference#", site="bench")
        scene = load_scene(store)
        t1 = time.perf_counter()
        result = compare_model(path, store, scene, skills, skip=pinned(path.name))
        t2 = time.perf_counter()
        print(
            f"\n{path.name}: {result.elements} selected elements meshed by OpenCASCADE in "
            f"{result.mesh_seconds:.1f} s (import {t1 - t0:.1f} s, whole check {t2 - t1:.1f} s)"
        )
        for (name, guid), reason in PINNED.items():
            if name == path.name:
                print(f"  pinned, left out: {guid}: {reason}")
        for side, elements in (("lost (no mesh of ours)", result.lost), ("invented", result.invented)):
            for guid, ifc_class in elements:
                print(f"  {side}: {guid} {ifc_class}")
            bad += len(elements)
        head = ("cells", "ours", "certain", "missed", "extra", "s")
        print(
            f"  {'storey':<24} {'skill':<13} "
            + " ".join(f"{h:>{w}}" for h, w in zip(head, WIDTHS, strict=True))
        )
        for m in result.maps:
            c = m.check
            print(
                f"  {m.storey:<24} {m.skill:<13} {c.cells:>9} {c.occupied:>8} {c.certain:>8} "
                f"{int(c.missed.sum()):>6} {int(c.extra.sum()):>6} {m.seconds:>6.1f}"
            )
            for x in m.culprits:
                print(f"    {x.side} {x.cells} cells: {x.guid} {x.ifc_class}")
            bad += not m.agrees
        total = sum(m.check.cells for m in result.maps)
        print(
            f"  {len(result.maps)} maps, {total:,} cells, {sum(not m.agrees for m in result.maps)} disagree"
        )
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
