"""Check every stored element mesh against the reference kernel (OpenCASCADE) on the shared models.

The suite checks the four small models (tests/adapters/ifc/test_kernels.py); Janesville is checked here
because OpenCASCADE alone takes 16-30 s on it. Prints, per model, how many elements each kernel meshed
and how many disagree with the reference (volume within 1 %, world bounding box within 1 cm).

    .venv/bin/python benchmarks/kernels.py                 # every shared model
    .venv/bin/python benchmarks/kernels.py janesville      # models by part of their file name
    .venv/bin/python benchmarks/kernels.py --no-routing    # what they would be without kernel routing
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

SHOWN = 20
sys.path.insert(0, str(Path(__file__).resolve().parent))
from run import SHARED_IFC, find_models  # noqa: E402  (benchmarks/ is not a package)


def main() -> int:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from adapters.ifc import read_model
    from adapters.ifc.kernel_check import disagreements

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*", help="parts of model file names (default: all)")
    parser.add_argument(
        "--no-routing", action="store_true", help="mesh every body with manifold first (what routing fixes)"
    )
    args = parser.parse_args()
    if not SHARED_IFC.is_dir():
        print(f"shared models not found at {SHARED_IFC}; nothing to check")
        return 0
    paths = find_models(args.models, quick=False)
    bad = 0
    for path in paths:
        t0 = time.perf_counter()
        model = read_model(path, routing=not args.no_routing)
        t1 = time.perf_counter()
        found = disagreements(path, model)
        t2 = time.perf_counter()
        kernels = Counter(e.mesh_kernel for e in model.elements if e.geometry is not None)
        print(
            f"{path.name}: {len(model.elements)} elements; meshed by "
            + ", ".join(f"{k} {n}" for k, n in sorted(kernels.items()))
            + f"; no mesh {len(model.mesh_failures)}; disagree with OpenCASCADE {len(found)}"
            + f" (read {t1 - t0:.1f} s, reference {t2 - t1:.1f} s)"
        )
        for d in found[:SHOWN]:
            print(f"  {d.guid} {d.ifc_class} ({d.kernel}): {d.reason}")
        if len(found) > SHOWN:
            by_class = Counter(f"{d.ifc_class} ({d.kernel})" for d in found)
            print(
                f"  ... and {len(found) - SHOWN} more; by class: "
                + ", ".join(f"{c} {n}" for c, n in by_class.most_common())
            )
        bad += len(found)
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
