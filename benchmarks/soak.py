"""Soak test of the live twin: a fleet for a long time, memory and the store sampled as it goes.

The daemon (``twin serve`` on an on-disk store of the generated lab; recording only with
``--record``), every robot and every subscriber run as separate processes on loopback. Each robot
owns one table in the ground floor's corridor and sends acked observations at ``--rate / --robots``
per second: a share ``--reconfirm`` of them re-reports the table where it stands (a re-confirmation:
nothing changes), the rest move it; every 100th removes it and the next adds it again under the same
IRI. Each subscriber keeps a copy of every ground-floor map (the latched map, then the updates).

Every ``--sample`` seconds it prints a row: daemon RSS, store size on disk, acked observations per
second, ack p50/p99 over the interval. At the end:

- no acknowledged change lost: each robot's last acked change of its table is the one in the graph;
- no subscriber behind: every subscriber's final copy of every map equals the daemon's;
- growth: RSS and store size from the end of warm-up (the first ``--warmup`` seconds) to the end,
  within ``--max-rss-growth`` and ``--max-store-growth`` MB. Both are saw-teeth with the daemon's
  store flush (a flush period of write buffers and write-ahead log), so growth compares the median of
  the first flush period after warm-up with the median of the last one (at most a quarter of the
  run): a trend, not the phase of the saw-tooth at two instants. End-minus-start is printed too.

Exit code 1 if any of those fails. The one-hour run (the benchmark)::

    python benchmarks/soak.py --duration 3600 --json soak.json --plot soak.png

The suite runs a short one (``tests/integration/test_soak.py``) and checks growth per observation.
"""

from __future__ import annotations

import argparse
import json
import random
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
import live  # benchmarks/ is not a package
import load

TWIN = live.TWIN
STOREY = load.STOREY


def robot(
    endpoint: str,
    index: int,
    rate: float,
    duration: float,
    start_at: float,
    *,
    reconfirm: float,
    storey: str = STOREY,
    area: tuple[float, float, float, float] = load.CORRIDOR,
) -> int:
    """One JSON line per observation: sent, acked, ok, revision, whether it changed anything."""
    from adapters.zenoh.client import TwinClient
    from twin.errors import TwinError

    rng = random.Random(index)
    last = (-1e9, -1e9)  # where its table was last sent
    name = f"robot{index}"
    x0, x1, y0, y1 = area
    table = f"urn:soak:{name}:table"
    present, payload = False, ""
    with TwinClient.connect([endpoint], timeout_s=10.0) as twin:
        time.sleep(max(0.0, start_at - time.time()))
        i, t_end = 0, start_at + duration
        while time.time() < t_end:
            time.sleep(max(0.0, start_at + i / rate - time.time()))
            if present and i % 100 == 99:
                op, doc = "remove", f"<{table}> <{TWIN}removed> true ."
            elif present and rng.random() < reconfirm:
                op, doc = "same", payload
            else:
                op = "move" if present else "add"
                x, y, yaw = rng.uniform(x0, x1), rng.uniform(y0, y1), rng.uniform(0, 3)
                while abs(x - last[0]) + abs(y - last[1]) < 0.8:  # a move fusion applies at once
                    x, y = rng.uniform(x0, x1), rng.uniform(y0, y1)
                last = (x, y)
                doc = payload = (
                    f'<{table}> <{TWIN}ifcClass> "IfcFurniture" ; <{TWIN}distinct> true ; '
                    f'<{TWIN}storey> "{storey}" ; '
                    f'<{TWIN}box> "{x:.3f} {y:.3f} 0.375 0.8 0.6 0.75 {yaw:.3f}" .'
                )
            sent = time.time()
            try:
                ack = twin.observe(name, doc)
                ok, revision = bool(ack.get("ok")), int(ack.get("revision", -1))
                unchanged = bool(ack.get("unchanged"))
            except TwinError as err:
                ok, revision, unchanged = False, -1, False
                print(json.dumps({"error": str(err)}), file=sys.stderr, flush=True)
            print(json.dumps([table, op, sent, time.time(), ok, revision, unchanged]), flush=True)
            if ok and op == "remove":
                present = False
            elif ok and op in ("add", "move"):
                present = True
            i += 1
    return 0


CENSUS_QUERIES = {
    "predicates": "SELECT ?p (COUNT(*) AS ?n) WHERE { ?s ?p ?o } GROUP BY ?p",
    "subjects": "SELECT (COUNT(DISTINCT ?s) AS ?n) WHERE { ?s ?p ?o }",
    "aliases": "SELECT (COUNT(*) AS ?n) WHERE { ?a twin:aliasOf ?t }",
    "tombstones": "SELECT (COUNT(*) AS ?n) WHERE { ?e twin:removed true }",
}


def census(endpoint: str) -> dict[str, Any]:
    """What the daemon holds now: the store's triples by predicate, distinct subjects, aliases and
    tombstones (SPARQL), and the lengths of the writer's containers (``status``'s ``sizes``)."""
    from adapters.zenoh.client import TwinClient

    def rows(query: str) -> list[dict[str, Any]]:
        result = twin.sparql(query)
        assert isinstance(result, dict)
        return list(result["results"]["bindings"])

    with TwinClient.connect([endpoint], timeout_s=30.0) as twin:
        status = twin.status()
        out: dict[str, Any] = {"triples": status.get("triples"), "sizes": status.get("sizes", {})}
        out["predicates"] = {
            r["p"]["value"].rsplit("#", 1)[-1].rsplit("/", 1)[-1]: int(r["n"]["value"])
            for r in rows(CENSUS_QUERIES["predicates"])
        }
        for key in ("subjects", "aliases", "tombstones"):
            out[key] = int(rows(CENSUS_QUERIES[key])[0]["n"]["value"])
    return out


def census_changes(first: dict[str, Any], last: dict[str, Any]) -> dict[str, Any]:
    """What differs between two censuses: ``name: [before, after]`` for every count that changed."""
    out: dict[str, Any] = {}
    for key in ("triples", "subjects", "aliases", "tombstones"):
        if first.get(key) != last.get(key):
            out[key] = [first.get(key), last.get(key)]
    for group in ("predicates", "sizes"):
        a, b = first.get(group, {}), last.get(group, {})
        for name in sorted(set(a) | set(b)):
            if a.get(name) != b.get(name):
                out[f"{group}.{name}"] = [a.get(name), b.get(name)]
    return out


def _dir_mb(path: Path) -> float:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file()) / 1e6


def _pct(values: list[float], q: float) -> float:
    return live._pct(values, q) if values else 0.0


def run(
    *,
    robots: int,
    rate: float,
    duration: float,
    subscribers: int,
    reconfirm: float,
    sample_s: float,
    warmup_s: float,
    quiet: bool = False,
    flush_every_s: float | None = None,
    model: str = "lab",
    record: bool = False,
    census_at: bool = False,
) -> dict[str, Any]:
    """One soak on ``model`` (the lab's corridor, or the busiest storey's extent of another model)."""
    work = Path(tempfile.mkdtemp(prefix="soak-"))
    store = live.prepare_store(model, work)
    if model == "lab":
        storey, area = STOREY, load.CORRIDOR
    else:
        storey, (ex0, ey0, ex1, ey1), _ = live.busiest(store)
        area = (ex0 + 1.0, ex1 - 1.0, ey0 + 1.0, ey1 - 1.0)
    endpoint = f"tcp/127.0.0.1:{live._free_port()}"
    config = work / "soak.toml"
    config.write_text(f"[store]\nflush_every_s = {flush_every_s}\n" if flush_every_s else "")
    rrd = work / "soak.rrd" if record else None
    daemon, _ = live.serve(
        "--store", str(store), "--listen", endpoint, "--config", str(config),
        *(["--record", str(rrd)] if rrd is not None else ["--no-record"]),
    )  # fmt: skip
    children: list[subprocess.Popen[str]] = [daemon]
    try:
        return _run(daemon, children, store, endpoint, robots=robots, rate=rate, duration=duration,
                    subscribers=subscribers, reconfirm=reconfirm, sample_s=sample_s, warmup_s=warmup_s,
                    quiet=quiet, rrd=rrd, flush_every_s=flush_every_s, model=model, storey=storey,
                    area=area, census_at=census_at)  # fmt: skip
    finally:  # an interrupted soak (SIGINT, SIGTERM) leaves no process behind
        for c in children:
            if c.poll() is None:
                c.kill()
                c.wait(timeout=30)


def _run(
    daemon: subprocess.Popen[str],
    children: list[subprocess.Popen[str]],
    store: Path,
    endpoint: str,
    *,
    robots: int,
    rate: float,
    duration: float,
    subscribers: int,
    reconfirm: float,
    sample_s: float,
    warmup_s: float,
    quiet: bool,
    flush_every_s: float | None,
    model: str,
    storey: str,
    area: tuple[float, float, float, float],
    rrd: Path | None = None,
    census_at: bool = False,
) -> dict[str, Any]:
    from adapters.zenoh.client import TwinClient

    assert daemon.stdout is not None
    threading.Thread(target=daemon.stdout.read, daemon=True).start()  # drain its log
    subs = [load._child("subscriber", endpoint, storey, stdin=True) for _ in range(subscribers)]
    children += subs
    for s in subs:
        assert s.stdout is not None and json.loads(s.stdout.readline())["ready"]
    start_at = time.time() + 1.0 + 0.1 * robots
    per_robot = rate / robots
    bots = [
        subprocess.Popen(
            [
                sys.executable,
                __file__,
                "--child",
                endpoint,
                str(i),
                str(per_robot),
                str(duration),
                str(start_at),
                str(reconfirm),
                storey,
                *map(str, area),
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=live.ROOT,
        )
        for i in range(robots)
    ]
    children += bots
    lock = threading.Lock()
    lines: list[list[Any]] = []
    errors: list[str] = []

    def drain(b: subprocess.Popen[str]) -> None:
        assert b.stdout is not None
        for ln in b.stdout:
            if ln.startswith("["):
                with lock:
                    lines.append(json.loads(ln))

    def drain_err(b: subprocess.Popen[str]) -> None:
        assert b.stderr is not None
        for ln in b.stderr:
            if ln.strip() and len(errors) < 20:
                errors.append(ln.strip())

    readers = [threading.Thread(target=f, args=(b,), daemon=True) for b in bots for f in (drain, drain_err)]
    for r in readers:
        r.start()
    samples: list[dict[str, float]] = []
    header = (
        f"{'t s':>7} {'rss MB':>8} {'store MB':>9} {'acked/s':>8} {'changed/s':>9} "
        f"{'ack p50 ms':>10} {'ack p99 ms':>10}"
    )
    if not quiet:
        print(header, flush=True)
    seen = 0
    next_at = start_at + sample_s
    censuses: list[dict[str, Any]] = []
    while any(b.poll() is None for b in bots):
        time.sleep(max(0.0, min(0.5, next_at - time.time())))
        if time.time() < next_at and any(b.poll() is None for b in bots):
            continue
        with lock:
            window, seen = lines[seen:], len(lines)
        acked = [ln for ln in window if ln[4]]
        acks = [(ln[3] - ln[2]) * 1e3 for ln in acked]
        row = {
            "t_s": round(time.time() - start_at, 1),
            "rss_mb": round(live._proc_mb(daemon.pid, "VmRSS"), 1),
            "store_mb": round(_dir_mb(store), 2),
            "acked_per_s": round(len(acked) / sample_s, 1),
            "changed_per_s": round(sum(1 for ln in acked if not ln[6]) / sample_s, 1),
            "ack_p50_ms": round(_pct(acks, 50), 2),
            "ack_p99_ms": round(_pct(acks, 99), 2),
            "observations": len(lines),
        }
        if rrd is not None:  # the recording (rotated files too) and the recorder process
            row["rrd_mb"] = round(sum(f.stat().st_size for f in rrd.parent.glob("soak*.rrd")) / 1e6, 2)
            row["recorder_rss_mb"] = round(
                sum(live._proc_mb(pid, "VmRSS") for pid in _children(daemon.pid)), 1
            )
        due = (not censuses and row["t_s"] >= warmup_s) or time.time() >= start_at + duration - sample_s
        if census_at and due:
            counted = census(endpoint)
            counted["t_s"], counted["observations"] = row["t_s"], row["observations"]
            censuses[1:] = [counted]  # the first after warm-up, and the latest
            if not quiet:
                print(f"census at {row['t_s']} s: {counted['triples']} triples", flush=True)
        samples.append(row)
        if not quiet:
            print(
                f"{row['t_s']:>7} {row['rss_mb']:>8} {row['store_mb']:>9} {row['acked_per_s']:>8} "
                f"{row['changed_per_s']:>9} {row['ack_p50_ms']:>10} {row['ack_p99_ms']:>10}",
                flush=True,
            )
        next_at += sample_s
    for r in readers:
        r.join(timeout=60)
    time.sleep(1.0)  # the last updates reach every subscriber
    with TwinClient.connect([endpoint], timeout_s=30.0) as twin:
        daemon_final = {}
        for skill in load.SKILLS:
            grid, _, version = twin.get_map(storey, skill)
            daemon_final[skill] = [version, load._digest(grid.data)]
    attempts = [
        {"iri": ln[0], "op": ln[1], "ok": ln[4], "revision": ln[5]} for ln in lines if ln[4] and not ln[6]
    ]
    checked, problems = load._check_graph(endpoint, attempts, prefix="urn:soak:")
    behind = 0
    for s in subs:
        out, _ = s.communicate(input="", timeout=120)
        behind += int(json.loads(out.strip().splitlines()[-1])["final"] != daemon_final)
    daemon.terminate()
    daemon.wait(timeout=60)
    acked_all = [ln for ln in lines if ln[4]]
    acks_all = [(ln[3] - ln[2]) * 1e3 for ln in acked_all]
    warm = [s for s in samples if s["t_s"] >= warmup_s] or samples[-1:]
    after = [s for s in samples if s["t_s"] >= warmup_s]
    span = (warm[-1]["t_s"] - warm[0]["t_s"]) if warm else 0.0
    window = min(max(flush_every_s or 60.0, 2 * sample_s), span / 4)  # one flush period
    obs_after = (after[-1]["observations"] - after[0]["observations"]) if len(after) > 1 else 0
    return {
        "model": model,
        "storey": storey,
        "robots": robots,
        "offered_per_s": rate,
        "reconfirm_share": reconfirm,
        "duration_s": duration,
        "subscribers": subscribers,
        "observations_sent": len(lines),
        "observations_acked": len(acked_all),
        "unchanged": sum(1 for ln in acked_all if ln[6]),
        "acked_per_s": round(len(acked_all) / duration, 1),
        "ack_p50_ms": round(_pct(acks_all, 50), 2),
        "ack_p99_ms": round(_pct(acks_all, 99), 2),
        "acked_changes_checked": checked,
        "lost_acks": len(problems),
        "subscribers_behind": behind,
        "rss_after_warmup_mb": warm[0]["rss_mb"] if warm else None,
        "rss_end_mb": samples[-1]["rss_mb"] if samples else None,
        "rss_growth_mb": _trend(warm, "rss_mb", window),
        "rss_end_minus_start_mb": round(warm[-1]["rss_mb"] - warm[0]["rss_mb"], 1) if warm else None,
        "rss_trough_growth_mb": _trough_growth(warm, "rss_mb", window),
        "store_after_warmup_mb": warm[0]["store_mb"] if warm else None,
        "store_end_mb": samples[-1]["store_mb"] if samples else None,
        "store_growth_mb": _trend(warm, "store_mb", window),
        "store_end_minus_start_mb": round(warm[-1]["store_mb"] - warm[0]["store_mb"], 2) if warm else None,
        "growth_window_s": window,
        "observations_after_warmup": obs_after,
        **(_recording(warm, samples, rrd) if rrd is not None else {}),
        **(_censuses(censuses) if census_at else {}),
        "problems": problems[:10],
        "robot_errors": errors[:10],
        "samples": samples,
    }


def _censuses(censuses: list[dict[str, Any]]) -> dict[str, Any]:
    """The census after warm-up and at the end, and what changed between them."""
    if len(censuses) < 2:
        return {"census": censuses}
    first, last = censuses[0], censuses[-1]
    return {
        "census_between": [[first["t_s"], first["observations"]], [last["t_s"], last["observations"]]],
        "census_changes": census_changes(first, last),
        "census": censuses,
    }


def _children(pid: int) -> list[int]:
    """The child processes of ``pid`` (the daemon's recorder process)."""
    try:
        return [
            int(c) for t in Path(f"/proc/{pid}/task").iterdir() for c in (t / "children").read_text().split()
        ]
    except OSError:
        return []


def _recording(warm: list[dict[str, Any]], samples: list[dict[str, Any]], rrd: Path) -> dict[str, Any]:
    """The recording's growth after warm-up, per changed observation and extrapolated to an hour."""
    size_mb = sum(f.stat().st_size for f in rrd.parent.glob("soak*.rrd")) / 1e6  # closed: all written
    span = warm[-1]["t_s"] - warm[0]["t_s"] if len(warm) > 1 else 0.0
    changed = sum(s["changed_per_s"] for s in warm[1:]) * (span / max(len(warm) - 1, 1))
    grown = warm[-1]["rrd_mb"] - warm[0]["rrd_mb"] if warm else 0.0
    return {
        "rrd_end_mb": round(size_mb, 2),
        "rrd_growth_after_warmup_mb": round(grown, 2),
        "rrd_bytes_per_change": round(grown * 1e6 / changed) if changed else None,
        "rrd_gb_per_hour": round(grown / span * 3600 / 1e3, 2) if span else None,
        "recorder_rss_end_mb": samples[-1].get("recorder_rss_mb") if samples else None,
    }


def _windows(samples: list[dict[str, Any]], key: str, window_s: float) -> tuple[list[float], list[float]]:
    """The values of ``key`` in the first and the last ``window_s`` of ``samples``."""
    t0, t1 = samples[0]["t_s"], samples[-1]["t_s"]
    first = [s[key] for s in samples if s["t_s"] <= t0 + window_s]
    last = [s[key] for s in samples if s["t_s"] >= t1 - window_s]
    return first, last


def _trend(samples: list[dict[str, Any]], key: str, window_s: float) -> float | None:
    """Growth of ``key`` from the first to the last window (medians): phase-free on a saw-tooth."""
    if len(samples) < 2:
        return None
    first, last = _windows(samples, key, window_s)
    return round(_pct(last, 50) - _pct(first, 50), 2)


def _trough_growth(samples: list[dict[str, Any]], key: str, window_s: float) -> float | None:
    """Growth of the minimum of ``key`` from the first to the last window (the saw-tooth's troughs)."""
    if len(samples) < 2:
        return None
    first, last = _windows(samples, key, window_s)
    return round(min(last) - min(first), 2)


def plot(result: dict[str, Any], out: Path) -> None:
    """RSS and store size over time (and acked/s) as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = result["samples"]
    t = [r["t_s"] / 60 for r in s]
    fig, (a, b) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    a.plot(t, [r["rss_mb"] for r in s], label="daemon RSS (MB)")
    a.plot(t, [r["store_mb"] for r in s], label="store on disk (MB)")
    a.set_ylabel("MB")
    a.set_ylim(bottom=0)
    a.legend()
    a.set_title(
        f"soak: {result['robots']} robots, {result['offered_per_s']:g} obs/s offered, "
        f"{result['reconfirm_share']:.0%} re-confirmations"
    )
    b.plot(t, [r["acked_per_s"] for r in s], label="acked/s")
    b.plot(t, [r["ack_p99_ms"] for r in s], label="ack p99 (ms)")
    b.set_xlabel("minutes")
    b.set_ylim(bottom=0)
    b.legend()
    fig.tight_layout()
    fig.savefig(out, dpi=100)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--model", default="lab", help="lab, janesville, ... or an IFC path (see live.py)")
    p.add_argument("--robots", type=int, default=4)
    p.add_argument("--rate", type=float, default=100.0, help="offered observations per second, all robots")
    p.add_argument("--reconfirm", type=float, default=0.5, help="share of re-confirmations (0..1)")
    p.add_argument("--duration", type=float, default=3600.0, help="seconds")
    p.add_argument("--subscribers", type=int, default=2)
    p.add_argument("--sample", type=float, default=10.0, help="seconds between samples")
    p.add_argument("--warmup", type=float, default=60.0, help="seconds before growth is measured")
    p.add_argument(
        "--flush-every", type=float, help="the daemon's [store] flush_every_s (default: the configuration's)"
    )
    p.add_argument("--max-rss-growth", type=float, default=20.0, help="MB after warm-up (trend)")
    p.add_argument("--max-store-growth", type=float, default=50.0, help="MB after warm-up")
    p.add_argument("--json", metavar="OUT.json", help="also write the result here")
    p.add_argument("--plot", metavar="OUT.png", help="plot RSS and store size over time")
    p.add_argument("--record", action="store_true", help="the daemon records (Rerun): the file's growth")
    p.add_argument(
        "--census",
        action="store_true",
        help="count the store's triples by predicate and the writer's containers after warm-up and at the "
        "end (census_changes: what grew)",
    )
    p.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = p.parse_args()
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # run the cleanup in run()'s finally
    if args.child:
        c = args.child
        area = (float(c[7]), float(c[8]), float(c[9]), float(c[10]))
        rate, duration, start_at = float(c[2]), float(c[3]), float(c[4])
        return robot(c[0], int(c[1]), rate, duration, start_at, reconfirm=float(c[5]), storey=c[6], area=area)
    print(
        f"soak ({args.model}): {args.robots} robots, {args.rate:g} obs/s offered "
        f"({args.reconfirm:.0%} re-confirmations) "
        f"for {args.duration:g} s, {args.subscribers} subscribers",
        file=sys.stderr,
    )
    result = run(
        robots=args.robots,
        rate=args.rate,
        duration=args.duration,
        subscribers=args.subscribers,
        reconfirm=args.reconfirm,
        sample_s=args.sample,
        warmup_s=min(args.warmup, args.duration / 2),
        flush_every_s=args.flush_every,
        model=args.model,
        record=args.record,
        census_at=args.census,
    )
    for key, value in result.items():
        if key not in ("samples", "census"):
            print(f"{key:<26}  {value}")
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2))
    if args.plot:
        plot(result, Path(args.plot))
    failed = (
        result["lost_acks"]
        or result["subscribers_behind"]
        or (result["rss_growth_mb"] or 0) > args.max_rss_growth
        or (result["store_growth_mb"] or 0) > args.max_store_growth
    )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
