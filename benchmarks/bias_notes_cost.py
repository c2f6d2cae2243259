"""What the bias notes cost the writer per confirming array, without a profiler's per-call overhead.

Runs ``confirm_cost.py``'s fleet (``--robots`` robots reporting the same 20 tables in turns, one batch per
array), records the last ``--calls`` arrays' bias notes (:func:`twin.fusion.bias.sightings_noted`'s
input), then times on the memory as the run left it, best of ``--repeat`` passes, us per array:
``sightings_noted`` (each element's new mean and each robot pair's last comparison),
``update_pairs`` (both means of each pair, in place) and ``applied_bias`` (the robot's bias, read once
an array). ``--baseline TREE`` times another code tree's functions on the same calls, alternated.

    python benchmarks/bias_notes_cost.py --robots 25 --baseline /tmp/base_b
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))


def tree_bias(tree: str) -> ModuleType:
    """``twin/fusion/bias.py`` of another code tree (its own module, on this tree's memory types)."""
    spec = importlib.util.spec_from_file_location("baseline_bias", Path(tree) / "twin/fusion/bias.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def best(calls: list[Any], f: Callable[[Any], object], repeat: int) -> float:
    """The best pass of ``f`` over ``calls``, us per call."""
    out = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        for call in calls:
            f(call)
        out = min(out, (time.perf_counter() - t) / len(calls) * 1e6)
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--robots", type=int, default=25)
    p.add_argument("--arrays", type=int, default=100, help="confirm_cost.py's arrays per robot")
    p.add_argument("--calls", type=int, default=2000, help="arrays timed (the run's last)")
    p.add_argument("--repeat", type=int, default=7)
    p.add_argument("--baseline", help="another code tree's bias.py, timed alternately")
    args = p.parse_args()

    import confirm_cost

    from twin.fusion import bias, confirm_array

    recorded: list[tuple[Any, list[tuple[str, float, float, int]]]] = []
    noted = bias.sightings_noted

    def recording(ctx: Any, seen: Any) -> Any:
        recorded.append((ctx, list(seen)))
        return noted(ctx, seen)

    confirm_array.sightings_noted = recording  # type: ignore[assignment]
    service = confirm_cost.setup(0, robots=args.robots)
    confirm_cost.run(service, args.arrays, robots=args.robots, moves=20, single=True)
    confirm_array.sightings_noted = noted
    calls = recorded[-args.calls :]
    trees = {"this tree": bias}
    if args.baseline:
        trees = {"baseline": tree_bias(args.baseline), **trees}
    print(f"{'tree':>10} {'sightings_noted':>16} {'update_pairs':>13} {'applied_bias':>13}   us per array")
    for _ in range(3):
        for name, b in trees.items():
            diffs = [(ctx, b.sightings_noted(ctx, seen)[1]) for ctx, seen in calls]
            noting = best(calls, lambda c, b=b: b.sightings_noted(*c), args.repeat)
            pairs = best(diffs, lambda c, b=b: b.update_pairs(c[0].memory, c[0].robot, c[1]), args.repeat)
            reading = best(calls, lambda c, b=b: b.applied_bias(c[0].memory, c[0].robot), args.repeat)
            print(f"{name:>10} {noting:16.1f} {pairs:13.1f} {reading:13.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
