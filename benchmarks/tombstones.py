"""Tombstones over minutes: does the writer stay flat while robots mint new IRIs and remove them all day?

Open-RMF obstacles (one IRI per obstacle id, removed when their lifetime lapses) and removals by absence
leave a tombstone per IRI. In process, no Zenoh: a :class:`~twin.live.TwinService` on the sample lab
(imported to an on-disk store as ``twin serve`` has it) serving on its own thread (``serve_forever``:
its housekeeping forgets tombstones older than ``[fusion] tombstone_ttl_s``), and a robot that adds
``--rate`` new 0.3 m obstacles a second, each removed ``--alive`` obstacles later. Every ``--sample-s``
a row: the elements the writer holds (states, tombstones among them), the store's triples, the
Python heap (``tracemalloc``, started before the service: the writer's own memory, without the store's
RocksDB buffers), the process's RSS, the store directory's size, the forgotten count and the longest
forgetting pass.

``--compare`` runs two such processes side by side under the same load (the same machine, the same
minutes): one with ``--ttl`` (e.g. 30 s), one with ``tombstone_ttl_s = 0`` (never forget, as before).

    nice -n 10 python benchmarks/tombstones.py --compare --minutes 4 --rate 10 --ttl 30 [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import tracemalloc
from dataclasses import replace
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
TWIN = "https://w3id.org/building-twin#"


def _obstacle(k: int) -> bytes:
    """Obstacle ``k``: a 0.3 m box on one of 32 spots 0.5 m apart (never near another held one)."""
    x, y = 11.2 + 0.5 * (k % 8), 5.6 + 0.5 * ((k // 8) % 4)
    return (
        f'<urn:bench:obstacle:{k}> <{TWIN}ifcClass> "IfcBuildingElementProxy" ; '
        f'<{TWIN}storey> "ground-floor" ; '
        f'<{TWIN}box> "{x:.3f} {y:.3f} 0.15 0.3 0.3 0.3 0.0" .'
    ).encode()


def _removal(k: int) -> bytes:
    return f"<urn:bench:obstacle:{k}> <{TWIN}removed> true .".encode()


def _dir_mb(path: Path) -> float:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file()) / 2**20


def run(args: argparse.Namespace) -> list[dict[str, Any]]:
    """One run in this process: the rows, one every ``sample_s``."""
    sys.path.insert(0, str(HERE))
    import live  # benchmarks/ is not a package

    from twin.config import load_config
    from twin.graph.store import EmbeddedStore
    from twin.live import TwinService

    tracemalloc.start()
    work = Path(tempfile.mkdtemp(prefix="tombstones-"))
    rows: list[dict[str, Any]] = []
    try:
        store_path = live.prepare_store("lab", work)
        config = load_config()
        config = replace(config, fusion=replace(config.fusion, tombstone_ttl_ns=int(args.ttl * 1e9)))
        with EmbeddedStore.open(store_path) as store:
            service = TwinService(store, config)
            service.start()
            observer = service.observer
            passes: list[float] = []
            forget = observer.forget_tombstones

            def timed_forget(**kw: Any) -> int:
                t = time.perf_counter()
                try:
                    return forget(**kw)
                finally:
                    passes.append((time.perf_counter() - t) * 1e3)

            observer.forget_tombstones = timed_forget  # type: ignore[method-assign]
            stop = threading.Event()
            writer = threading.Thread(target=service.serve_forever, args=(stop,), name="writer")
            writer.start()
            acks = {"ok": 0, "error": 0}

            def on_reply(r: Any) -> None:
                acks["ok" if r.ok else "error"] += 1

            t0 = time.monotonic()
            next_sample, k = 0.0, 0
            try:
                while (elapsed := time.monotonic() - t0) < args.minutes * 60:
                    if elapsed >= next_sample:
                        states = list(service.live.states.values())
                        rows.append(
                            {
                                "t_s": round(elapsed),
                                "created": k,
                                "states": len(states),
                                "tombstones": sum(s.removed for s in states),
                                "triples": len(store),
                                "heap_mb": round(tracemalloc.get_traced_memory()[0] / 2**20, 1),
                                "rss_mb": round(live._proc_mb(os.getpid(), "VmRSS"), 1),
                                "store_mb": round(_dir_mb(store_path), 1),
                                "forgotten": observer.fusion_counts["forgotten"],
                                "longest_pass_ms": round(max(passes, default=0.0), 1),
                                "acks": dict(acks),
                            }
                        )
                        print(json.dumps(rows[-1]), flush=True)
                        passes.clear()
                        next_sample += args.sample_s
                    service.submit_observation("robot1", _obstacle(k), on_reply)
                    if k >= args.alive:
                        service.submit_observation("robot1", _removal(k - args.alive), on_reply)
                    k += 1
                    time.sleep(max(0.0, t0 + k / args.rate - time.monotonic()))
            finally:
                stop.set()
                writer.join()
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return rows


def _table(runs: dict[str, list[dict[str, Any]]]) -> str:
    names = list(runs)
    head = "| t (s) | " + " | ".join(f"{n}: states / triples / heap MB / RSS MB" for n in names) + " |"
    lines = [head, "|---|" + "---|" * len(names)]
    for i in range(min(len(r) for r in runs.values())):
        cells = [
            f"{r[i]['states']} / {r[i]['triples']:,} / {r[i]['heap_mb']} / {r[i]['rss_mb']}"
            for r in (runs[n] for n in names)
        ]
        lines.append(f"| {runs[names[0]][i]['t_s']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    raw = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=raw)
    parser.add_argument("--minutes", type=float, default=4.0)
    parser.add_argument("--rate", type=float, default=10.0, help="new obstacles a second")
    parser.add_argument("--alive", type=int, default=10, help="each obstacle is removed this many later")
    parser.add_argument("--ttl", type=float, default=30.0, help="[fusion] tombstone_ttl_s (0: never forget)")
    parser.add_argument("--sample-s", type=float, default=15.0)
    parser.add_argument("--compare", action="store_true", help="run --ttl and 0 side by side")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    if not args.compare:
        rows = run(args)
        if args.json:
            args.json.write_text(json.dumps(rows, indent=1))
        return
    base = [sys.executable, __file__, "--minutes", str(args.minutes), "--rate", str(args.rate)]
    base += ["--alive", str(args.alive), "--sample-s", str(args.sample_s)]
    out = Path(tempfile.mkdtemp(prefix="tombstones-compare-"))
    names = {f"ttl {args.ttl:g} s": args.ttl, "never forget": 0.0}
    children = {
        name: subprocess.Popen([*base, "--ttl", str(ttl), "--json", str(out / f"{i}.json")], cwd=ROOT)
        for i, (name, ttl) in enumerate(names.items())
    }
    for child in children.values():
        child.wait()
    runs = {name: json.loads((out / f"{i}.json").read_text()) for i, name in enumerate(names)}
    shutil.rmtree(out, ignore_errors=True)
    print(_table(runs))
    if args.json:
        args.json.write_text(json.dumps(runs, indent=1))


if __name__ == "__main__":
    main()
