"""What fusion costs the daemon: its CPU per acked observation, with ``[fusion]`` on and off.

Robot processes (``--robots``) each own a distinct table on the lab's ground floor and send acked
observations at ``--rate`` per second for ``--duration`` seconds: every other one moves the table
between two spots 0.5 m apart (a move), the others re-report it where it stands with a camera's noise
(2 cm; a re-confirmation). The daemon (``twin serve``, no recording) runs as a process; its user +
system CPU over the run (``/proc/<pid>/stat``) divided by the acked observations is the figure. The
same run is made with fusion on (the default) and off (``[fusion] enabled = false``).

    python benchmarks/fusion_cost.py --robots 10 --rate 20 --duration 20 [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
import live  # benchmarks/ is not a package

TWIN = live.TWIN


def robot(endpoint: str, prefix: str, index: int, rate: float, duration: float, start_at: float) -> int:  # noqa: PLR0917
    from adapters.zenoh.client import TwinClient

    rng = random.Random(index)
    name = f"robot{index}"
    x0, y = 11.2 + 0.95 * index, 6.9 if index % 2 else 5.6
    acked = moves = 0
    waits: list[float] = []  # ms from the request to its ack: committed
    held: list[float] = []  # unchanged (a move held until a second sighting agrees, a re-confirmation)
    with TwinClient.connect([endpoint], prefix=prefix, timeout_s=30.0) as twin:
        time.sleep(max(0.0, start_at - time.time()))
        i, spot = 0, 0
        while time.time() < start_at + duration:
            time.sleep(max(0.0, start_at + i / rate - time.time()))
            if i % 2 == 0:
                spot, moves = 1 - spot, moves + 1
                dx = dy = 0.0
            else:
                dx, dy = rng.gauss(0, 0.02), rng.gauss(0, 0.02)
            x = x0 + 0.5 * spot + dx
            payload = (
                f'<urn:cost:{name}:table> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}storey> "ground-floor" ; '
                f'<{TWIN}box> "{x:.4f} {y + dy:.4f} 0.375 0.8 0.6 0.75 0.0" .'
            )
            t = time.perf_counter()
            ack = twin.observe(name, payload)
            if ack.get("ok"):
                acked += 1
                (held if ack.get("unchanged") else waits).append(1e3 * (time.perf_counter() - t))
            i += 1
    print(json.dumps({"acked": acked, "moves": moves, "ack_ms": waits, "unchanged_ack_ms": held}), flush=True)
    return 0


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def python_thread_names(pid: int) -> dict[int, str]:
    """The Python threads' names by thread id (``py-spy dump``; empty without py-spy)."""
    return {
        int(m.group(1)): m.group(2)
        for m in re.finditer(r'^Thread (?:0x)?(\d+) \([^)]*\): "([^"]*)"', live.py_spy_dump(pid), re.M)
    }


def by_thread(
    pid: int, before: dict[int, tuple[str, float]], after: dict[int, tuple[str, float]]
) -> dict[str, float]:
    """CPU seconds per thread over the run, threads of one kind together: the Python threads by name
    (the main thread is the writer), the Zenoh runtime's by name without their number."""
    names = python_thread_names(pid)
    out: dict[str, float] = {}
    for tid, (comm, cpu) in after.items():
        name = names.get(tid) or re.sub(r"[-_]?\d+$", "", comm)
        name = "writer (MainThread)" if tid == pid else name
        out[name] = out.get(name, 0.0) + cpu - before.get(tid, (comm, 0.0))[1]
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))


def run(fusion: bool, args: argparse.Namespace) -> dict[str, Any]:
    work = Path(tempfile.mkdtemp(prefix="fusion-cost-"))
    store = live.prepare_store("lab", work)
    config = work / "cost.toml"
    text = f"[fusion]\nenabled = {'true' if fusion else 'false'}\n"
    if args.batch_wait_ms is not None:  # (a tree before [serve] batch_wait_ms does not know the key)
        text += f"[serve]\nbatch_wait_ms = {args.batch_wait_ms}\n"
    config.write_text(text)
    endpoint = f"tcp/127.0.0.1:{live._free_port()}"
    daemon, line = live.serve(
        "--config", str(config), "--store", str(store), "--listen", endpoint, "--no-record"
    )
    prefix = "twin/" + line.split("site '", 1)[1].split("'", 1)[0]
    try:
        start_at = time.time() + 3.0
        children = [
            subprocess.Popen(
                [
                    sys.executable,
                    __file__,
                    "--child",
                    endpoint,
                    prefix,
                    str(i),
                    str(args.rate),
                    str(args.duration),
                    str(start_at),
                ],
                stdout=subprocess.PIPE,
                text=True,
                cwd=live.ROOT,
            )
            for i in range(args.robots)
        ]
        time.sleep(max(0.0, start_at - time.time()))
        cpu0 = cpu_seconds(daemon.pid)
        threads0 = live.thread_cpu(daemon.pid)
        spy = live.py_spy_record(daemon.pid, args.profile, args.duration) if args.profile else None
        results = [
            json.loads((c.communicate(timeout=args.duration + 120)[0] or "{}").splitlines()[-1])
            for c in children
        ]
        cpu = cpu_seconds(daemon.pid) - cpu0
        threads = by_thread(daemon.pid, threads0, live.thread_cpu(daemon.pid)) if args.threads else {}
        if spy is not None:
            spy.wait(timeout=60)
    finally:
        daemon.terminate()
        daemon.wait(timeout=30)
    acked = sum(r.get("acked", 0) for r in results)
    waits = sorted(w for r in results for w in r.get("ack_ms", []))
    held = sorted(w for r in results for w in r.get("unchanged_ack_ms", []))
    return {
        "ack_ms_p50": waits[len(waits) // 2] if waits else float("nan"),
        "ack_ms_p90": waits[int(len(waits) * 0.9)] if waits else float("nan"),
        "unchanged_ack_ms_p50": held[len(held) // 2] if held else float("nan"),
        "unchanged_ack_ms_p90": held[int(len(held) * 0.9)] if held else float("nan"),
        "fusion": fusion,
        "acked": acked,
        "acked_per_s": acked / args.duration,
        "daemon_cpu_s": cpu,
        "cpu_ms_per_acked": 1e3 * cpu / max(1, acked),
        "threads_ms_per_acked": {k: 1e3 * v / max(1, acked) for k, v in threads.items()},
        "load": os.getloadavg()[0],
    }


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        endpoint, prefix, index, rate, duration, start_at = sys.argv[2:8]
        return robot(endpoint, prefix, int(index), float(rate), float(duration), float(start_at))
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--robots", type=int, default=10)
    p.add_argument("--rate", type=float, default=20.0)
    p.add_argument("--duration", type=float, default=20.0)
    p.add_argument("--modes", default="on,off,on", help="the runs, fusion on or off, in order")
    p.add_argument(
        "--threads", action="store_true", help="split the daemon's CPU by thread (py-spy names them)"
    )
    p.add_argument("--batch-wait-ms", type=float, help="[serve] batch_wait_ms (default: the tree's)")
    p.add_argument(
        "--profile",
        type=Path,
        help="py-spy record the daemon over the run into this file (collapsed stacks; it costs CPU: "
        "not for the figures)",
    )
    p.add_argument("--json", type=Path)
    args = p.parse_args()
    rows = [run(mode == "on", args) for mode in args.modes.split(",")]
    print(f"{'fusion':8} {'acked':>7} {'acked/s':>8} {'daemon CPU s':>13} {'CPU ms/acked':>13}")
    for r in rows:
        print(
            f"{'on' if r['fusion'] else 'off':8} {r['acked']:7d} {r['acked_per_s']:8.1f} "
            f"{r['daemon_cpu_s']:13.2f} {r['cpu_ms_per_acked']:13.3f}   load {r['load']:.1f}   "
            f"ack p50 {r['ack_ms_p50']:.1f} ms, p90 {r['ack_ms_p90']:.1f} ms; unchanged "
            f"p50 {r['unchanged_ack_ms_p50']:.1f} ms, p90 {r['unchanged_ack_ms_p90']:.1f} ms"
        )
        for name, ms in r["threads_ms_per_acked"].items():
            if ms >= 0.001:
                print(f"    {name:32} {ms:7.3f}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
