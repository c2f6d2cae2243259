"""First-ack benchmark: is the daemon ready when it says ``serving``?

For each model the store is imported once; then ``twin serve`` is started on it ``--repeat`` times
built from the store (``--no-snapshot``) and ``--repeat`` times from its snapshot (a first, unmeasured
start writes it). Once the daemon prints its ``serving`` line, a robot in this process connects and
sends two observations of new objects (``twin:distinct true``: fusion's association is not asked;
with ``--associated`` without it, so that fusion matches them against the dynamic elements it holds,
as a robot's ordinary report is), on the busiest storey. It reports the time from ``serving`` to the
first ack, and the second ack's round trip (what an ack costs once everything is built).

Usage::

    nice -n 10 python benchmarks/first_ack.py [--models lab janesville PATH.ifc ...] [--repeat 2] \
        [--associated] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
import live  # the live benchmark's machinery: models, store preparation, the twin command, ports

TWIN = "https://w3id.org/building-twin#"


def _observation(iri: str, storey: str, x: float, y: float, *, distinct: bool = True) -> str:
    mark = f"<{TWIN}distinct> true ; " if distinct else ""
    return (f'<{iri}> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "{storey}" ; {mark}'
            f'<{TWIN}box> "{x:.3f} {y:.3f} 0.4 0.6 0.6 0.8 0" .')  # fmt: skip


def one_start(
    store: Path, storey: str, spot: tuple[float, float], *, snapshot: bool, n: int, distinct: bool = True
) -> dict[str, Any]:
    from adapters.zenoh.client import TwinClient

    endpoint = f"tcp/127.0.0.1:{live._free_port()}"
    args = ["serve", "--store", str(store), "--listen", endpoint, "--no-record"]
    process = subprocess.Popen(
        live._twin(*args, *([] if snapshot else ["--no-snapshot"])),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    try:
        assert process.stdout is not None
        t0 = time.monotonic()
        while (line := process.stdout.readline()) and "serving site" not in line:
            pass
        assert line, "the daemon did not start"
        serving = time.monotonic()
        prefix = line.split(" under ")[1].split(" ")[0].rstrip(",:").removesuffix("/")  # "twin/lab/,"
        with TwinClient.connect([endpoint], prefix=prefix, timeout_s=120) as robot:
            x, y = spot
            first = robot.observe(
                "bench", _observation(f"urn:bench:first-ack:{n}a", storey, x, y, distinct=distinct)
            )
            acked = time.monotonic()
            robot.observe(
                "bench", _observation(f"urn:bench:first-ack:{n}b", storey, x + 1.0, y, distinct=distinct)
            )
            second = time.monotonic() - acked
        assert first["ok"], first
        return {
            "from": "snapshot" if "from the snapshot" in line else "store",
            "to_serving_s": round(serving - t0, 2),
            "first_ack_after_serving_s": round(acked - serving, 3),
            "second_ack_s": round(second, 3),
        }
    finally:
        process.send_signal(2)
        process.communicate(timeout=120)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--models", nargs="+", default=["lab", "janesville"])
    p.add_argument("--repeat", type=int, default=2)
    p.add_argument("--associated", action="store_true", help="observations without twin:distinct")
    p.add_argument("--json", type=Path)
    args = p.parse_args()
    distinct = not args.associated
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="first-ack-") as tmp:
        for name in args.models:
            path = live.model_path(name)
            if path is not None and not path.exists():
                print(f"skipping {name}: {path} is not here", file=sys.stderr)
                continue
            store = live.prepare_store(name, Path(tmp) / live.model_label(name))
            storey, (x0, y0, x1, y1), _ = live.busiest(store)
            spot = ((x0 + x1) / 2, (y0 + y1) / 2)
            one_start(store, storey, spot, snapshot=True, n=0, distinct=distinct)  # writes the snapshot
            for snapshot in (False, True):
                runs = [
                    one_start(store, storey, spot, snapshot=snapshot, n=i + 1, distinct=distinct)
                    for i in range(args.repeat)
                ]
                first = [r["first_ack_after_serving_s"] for r in runs]
                rows.append({
                    "model": live.model_label(name), "from": runs[-1]["from"],
                    "to_serving_s": statistics.median(r["to_serving_s"] for r in runs),
                    "first_ack_after_serving_s": statistics.median(first), "max_s": max(first),
                    "second_ack_s": statistics.median(r["second_ack_s"] for r in runs),
                })  # fmt: skip
    print("| model | from | to_serving_s | first ack after serving, s (max) | second ack, s |")
    print("|---|---|---:|---|---:|")
    for r in rows:
        first = f"{r['first_ack_after_serving_s']:.3f} ({r['max_s']:.3f})"
        print(f"| {r['model']} | {r['from']} | {r['to_serving_s']:.2f} | {first} | {r['second_ack_s']:.3f} |")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
