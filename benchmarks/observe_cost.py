"""Where the writer's time goes on ``fusion_cost.py``'s workload: its CPU per observation, stage by stage.

In process, no Zenoh: a :class:`~twin.live.TwinService` on the sample lab (imported to an on-disk store as
``twin serve`` would have it) and the workload of ``fusion_cost.py``: ``--robots`` robots, each with its
own table on the ground floor, every other observation moving it 0.5 m, the others re-reporting it
with 2 cm of noise (fusion holds the first sighting at the new spot, acked unchanged and pending; the
re-report there moves the table: a commit). ``--batch`` observations are queued before the writer
takes them (1: one at a time; the robots' number: all at once, as when every robot sends at the same
instant). The figures are the writer's thread CPU (``time.thread_time``) per observation over the
run and in the best of ``--blocks`` blocks (on a shared machine the best block shows the code), and
the CPU of each stage of the writer summed over the run: parse (Turtle, validation), fuse, plan,
commit (the store transaction), redraw (the maps' cells), index (fusion's poses), membership, and the
rest (batch bookkeeping, events, acks). The daemon's other threads (the Zenoh sends of updates and
acks) are not here: ``fusion_cost.py`` measures the daemon whole.

``--baseline TREE`` runs the same, alternately, with another code tree (e.g. an earlier commit's
``git archive``) on ``PYTHONPATH``; ``--repeat`` runs each that many times.

    PYTHONPATH=$PWD python benchmarks/observe_cost.py --rounds 200 [--batch 10] [--baseline /tmp/base]
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
TWIN = "https://w3id.org/building-twin#"
STAGES = ("parse", "fuse", "plan", "commit", "redraw", "index", "membership")


def _timed(owner: Any, name: str, stage: str, cpu: Counter[str]) -> None:
    """Wrap ``owner.name`` so that its thread CPU adds to ``cpu[stage]`` (nothing if it has none)."""
    f = getattr(owner, name, None)
    if f is None:
        return

    def timed(*args: Any, **kwargs: Any) -> Any:
        t = time.thread_time_ns()
        try:
            return f(*args, **kwargs)
        finally:
            cpu[stage] += time.thread_time_ns() - t

    setattr(owner, name, timed)


def _payload(robot: int, k: int, spots: list[int], rng: random.Random) -> bytes:
    x0, y = 11.2 + 0.95 * robot, 6.9 if robot % 2 else 5.6
    if k % 2 == 0:
        spots[robot] = 1 - spots[robot]
        dx = dy = 0.0
    else:
        dx, dy = rng.gauss(0, 0.02), rng.gauss(0, 0.02)
    x = x0 + 0.5 * spots[robot] + dx
    return (
        f'<urn:cost:robot{robot}:table> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "ground-floor" ; '
        f'<{TWIN}box> "{x:.4f} {y + dy:.4f} 0.375 0.8 0.6 0.75 0.0" .'
    ).encode()


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """One run in this process, with the ``twin`` on ``sys.path``."""
    sys.path.insert(0, str(HERE))
    import live  # benchmarks/ is not a package

    from twin.config import load_config
    from twin.graph.store import EmbeddedStore
    from twin.live import TwinService, observe

    cpu: Counter[str] = Counter()
    for name, stage in (
        ("parse_observation_document", "parse"),
        ("fuse", "fuse"),
        ("plan_observation", "plan"),
        ("membership", "membership"),
        ("index_element", "index"),
    ):
        _timed(observe, name, stage, cpu)
    work = Path(tempfile.mkdtemp(prefix="observe-cost-"))
    try:
        store_path = live.prepare_store("lab", work)
        with EmbeddedStore.open(store_path) as store:
            service = TwinService(store, load_config())
            service.start()
            _timed(service.store, "apply", "commit", cpu)
            _timed(service.live.maps, "redraw", "redraw", cpu)
            rngs = [random.Random(i) for i in range(args.robots)]
            spots = [0] * args.robots
            replies: list[bytes] = []
            queued = 0

            def send(robot: int, k: int) -> None:
                nonlocal queued
                service.submit_observation(
                    f"robot{robot}",
                    _payload(robot, k, spots, rngs[robot]),
                    lambda r: replies.append(r.to_json()),
                )
                queued += 1
                if queued >= args.batch:
                    service.process()
                    queued = 0

            def rounds(first: int, n: int) -> None:
                for k in range(first, first + n):
                    for robot in range(args.robots):
                        send(robot, k)
                service.process()

            rounds(0, 6)  # the tables created, each moved once
            gc.collect()
            gc.freeze()  # as `twin serve` after start-up
            cpu.clear()
            replies.clear()
            blocks = []
            per_block = max(1, args.rounds // args.blocks)
            t0 = time.thread_time_ns()
            for b in range(args.blocks):
                t, n = time.thread_time_ns(), len(replies)
                rounds(6 + b * per_block, per_block)
                blocks.append((time.thread_time_ns() - t) / 1e6 / max(1, len(replies) - n))
            total = time.thread_time_ns() - t0
    finally:
        shutil.rmtree(work, ignore_errors=True)
    n = len(replies)
    stages = {s: cpu[s] / 1e6 / n for s in STAGES}
    stages["rest"] = total / 1e6 / n - sum(stages.values())
    return {
        "observations": n,
        "unchanged": sum(b'"unchanged": true' in r for r in replies),
        "batch": args.batch,
        "best_block_ms": min(blocks),
        "ms_per_observation": total / 1e6 / n,
        "stages_ms": stages,
    }


def _child(tree: Path, argv: list[str]) -> dict[str, Any]:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    out = subprocess.run(
        [sys.executable, __file__, "--child", str(tree), *argv],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    result: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    return result


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--robots", type=int, default=10)
    p.add_argument("--rounds", type=int, default=200, help="observations per robot")
    p.add_argument("--batch", type=int, default=1, help="observations queued before the writer takes them")
    p.add_argument("--blocks", type=int, default=5)
    p.add_argument("--baseline", type=Path, help="another code tree, run alternately with this one")
    p.add_argument("--repeat", type=int, default=1)
    p.add_argument("--json", type=Path)
    p.add_argument("--child", type=Path, help=argparse.SUPPRESS)
    args, _ = p.parse_known_args()
    if args.child is not None:
        print(json.dumps(measure(args)))
        return 0
    argv = [
        f"--robots={args.robots}",
        f"--rounds={args.rounds}",
        f"--batch={args.batch}",
        f"--blocks={args.blocks}",
    ]
    trees = ([("baseline", args.baseline.resolve())] if args.baseline else []) + [("this tree", ROOT)]
    rows: list[tuple[str, dict[str, Any]]] = []
    for _ in range(args.repeat):
        rows += [(label, _child(tree, argv)) for label, tree in trees]
    stage_head = " ".join(f"{s:>10}" for s in (*STAGES, "rest"))
    print(f"{'code':10} {'batch':>5} {'obs':>6} {'ms/obs':>7} {'best':>6} {stage_head}")
    for label, r in rows:
        stages = " ".join(f"{r['stages_ms'][s]:10.3f}" for s in (*STAGES, "rest"))
        print(
            f"{label:10} {r['batch']:5d} {r['observations']:6d} {r['ms_per_observation']:7.3f} "
            f"{r['best_block_ms']:6.3f} {stages}"
        )
    if args.json:
        args.json.write_text(json.dumps([{"code": label, **r} for label, r in rows], indent=1))
    return 0


if __name__ == "__main__":
    if "--child" in sys.argv:
        sys.path.insert(0, sys.argv[sys.argv.index("--child") + 1])
    sys.exit(main())
