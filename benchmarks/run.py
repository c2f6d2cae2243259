"""Benchmark harness: IFC import and skill-map speed of building-twin against the bare iterator and peers.

Usage::

    python benchmarks/run.py [--models NAME ...] [--json OUT.json] [--repeat N] [--quick]

Every measurement runs in a fresh child process (``run.py --child ...``, one JSON line back), so each
has its own peak memory (``ru_maxrss`` from ``os.wait4`` on the child, which includes the children it
waited for, such as the import's meshing process) and no cache carries over. See README.md.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import importlib.metadata
import json
import os
import platform
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
SHARED_IFC = Path(__file__).resolve().parents[2] / "shared" / "data" / "ifc"
SKILLS = ("localization", "navigation")
MAP_METHODS = ("twin-full", "twin-region", "twin-region-prepared", "trimesh", "manifold3d")
PACKAGES = ("numpy", "ifcopenshell", "pyoxigraph", "trimesh", "manifold3d", "Pillow")
SMALL_BYTES = 10_000_000
RESULT_TAG = "BENCH-RESULT "
CHILD_TIMEOUT_S = 600.0


# --- the child side --------------------------------------------------------------------------------


def child_main(args: argparse.Namespace) -> int:
    """Run one task and print its result as one tagged JSON line."""
    import tasks

    path = Path(args.model)
    if args.child == "bare":
        result = tasks.bare_iterator(path)
    elif args.child == "bare-routed":
        result = tasks.bare_routed_iterator(path)
    elif args.child == "import":
        result = tasks.twin_import(path, Path(args.store_dir))
    elif args.child == "stats":
        result = tasks.table1(Path(args.store_dir))
    elif args.child == "map":
        result = tasks.run_map(path, args.skill, args.method, args.repeat)
    elif args.child == "storey-maps":
        result = tasks.storey_maps(Path(args.store_dir), args.repeat)
    else:
        print(f"unknown child task {args.child!r}", file=sys.stderr)
        return 2
    sys.stdout.write(RESULT_TAG + json.dumps(result) + "\n")
    sys.stdout.flush()
    return 0


# --- the parent side -------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Outcome:
    """A finished child: its result (or error), wall time, peak RSS and CPU time (with its children)."""

    ok: bool
    result: dict[str, Any]
    error: str
    wall_s: float
    peak_mb: float
    cpu_s: float
    foreign_cpu: float  # share of the machine's CPU used by *other* processes meanwhile (0..1)

    def row(self, **labels: Any) -> dict[str, Any]:
        return {
            **labels,
            "ok": self.ok,
            "error": self.error,
            "wall_s": self.wall_s,
            "peak_mb": self.peak_mb,
            "cpu_s": self.cpu_s,
            "foreign_cpu": self.foreign_cpu,
            **self.result,
        }


def busy_cpu_seconds() -> float:
    """CPU seconds all processes of the machine have used so far (``/proc/stat``); 0.0 if unreadable."""
    try:
        with open("/proc/stat", encoding="ascii") as fh:
            fields = [int(v) for v in fh.readline().split()[1:9]]
    except (OSError, ValueError):
        return 0.0
    user, nice, system, _idle, _iowait, irq, softirq, steal = fields
    return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")


def _error_of(code: int, stderr: str) -> str:
    if code < 0:
        try:
            return f"crashed ({signal.Signals(-code).name})"
        except ValueError:
            return f"crashed (signal {-code})"
    lines = [ln for ln in stderr.strip().splitlines() if ln.strip()]
    return lines[-1].strip() if lines else f"exit code {code}"


def run_child(argv: Sequence[str], timeout_s: float = CHILD_TIMEOUT_S) -> Outcome:
    """Run ``run.py --child argv`` in a new session; kill its process group after ``timeout_s``."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", *argv]
    with tempfile.TemporaryFile() as err:
        busy0 = busy_cpu_seconds()
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=err, start_new_session=True)
        timer = threading.Timer(timeout_s, _kill_group, args=(proc.pid,))
        timer.start()
        try:
            assert proc.stdout is not None
            out = proc.stdout.read().decode("utf-8", "replace")
            proc.stdout.close()
            _, status, usage = os.wait4(proc.pid, 0)
        finally:
            timer.cancel()
        wall = time.perf_counter() - t0
        busy = busy_cpu_seconds() - busy0
        proc.returncode = code = os.waitstatus_to_exitcode(status)
        err.seek(0)
        stderr = err.read().decode("utf-8", "replace")
    peak_mb = usage.ru_maxrss / 1024  # KiB on Linux
    cpu = usage.ru_utime + usage.ru_stime
    foreign = max(busy - cpu, 0.0) / (wall * (os.cpu_count() or 1)) if wall > 0 else 0.0
    tagged = [ln for ln in out.splitlines() if ln.startswith(RESULT_TAG)]
    if code == 0 and tagged:
        return Outcome(True, json.loads(tagged[-1][len(RESULT_TAG) :]), "", wall, peak_mb, cpu, foreign)
    return Outcome(False, {}, _error_of(code, stderr), wall, peak_mb, cpu, foreign)


def _kill_group(pid: int) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.killpg(pid, signal.SIGKILL)


def _progress(done: int, total: int, label: str, outcome: Outcome) -> None:
    state = "ok" if outcome.ok else f"FAILED: {outcome.error}"
    busy = f", machine {outcome.foreign_cpu:.0%} busy with other work" if outcome.foreign_cpu > 0.1 else ""
    print(f"[{done}/{total}] {label}: {outcome.wall_s:.1f} s, {state}{busy}", file=sys.stderr, flush=True)


# --- what to run -----------------------------------------------------------------------------------


def find_models(names: Sequence[str] | None, quick: bool) -> list[Path]:
    """The shared models (smallest first), filtered by ``names`` (substring of the file name, or paths)."""
    available = sorted(SHARED_IFC.glob("*.ifc"), key=lambda p: p.stat().st_size)
    if quick:
        available = [p for p in available if p.stat().st_size < SMALL_BYTES]
    if not names:
        return available
    chosen: list[Path] = []
    for name in names:
        if Path(name).is_file():
            chosen.append(Path(name).resolve())
            continue
        hits = [p for p in available if name.lower() in p.name.lower()]
        if not hits:
            known = ", ".join(p.stem for p in available)
            msg = f"No model matches {name!r}; available: {known}"
            raise SystemExit(msg)
        chosen.extend(h for h in hits if h not in chosen)
    return chosen


def machine_info() -> dict[str, Any]:
    cpu = "unknown"
    with contextlib.suppress(OSError), open("/proc/cpuinfo", encoding="utf-8") as fh:
        for line in fh:
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    mem_gb = None
    with contextlib.suppress(OSError, ValueError), open("/proc/meminfo", encoding="ascii") as fh:
        mem_gb = round(int(fh.readline().split()[1]) / 1024**2, 1)
    versions = {}
    for pkg in PACKAGES:
        try:
            versions[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            versions[pkg] = None
    return {
        "cpu_model": cpu,
        "cores": os.cpu_count(),
        "usable_cores": len(os.sched_getaffinity(0)),
        "memory_gb": mem_gb,
        "python": platform.python_version(),
        "platform": platform.platform(),
        "packages": versions,
        "loadavg_start": list(os.getloadavg()),
    }


# --- the run ---------------------------------------------------------------------------------------


@dataclass(slots=True)
class Runner:
    total: int
    done: int = 0

    def __call__(self, label: str, argv: Sequence[str]) -> Outcome:
        outcome = run_child(argv)
        self.done += 1
        _progress(self.done, self.total, label, outcome)
        return outcome


def run_imports(
    models: list[Path], repeat: int, run: Runner, workdir: Path
) -> tuple[list[dict[str, Any]], list[dict[str, Any]], list[dict[str, Any]]]:
    """Bare and twin imports (alternating, ``repeat`` fresh processes each) and Table 1 per model."""
    import report

    raw: list[dict[str, Any]] = []
    summaries: list[dict[str, Any]] = []
    stats: list[dict[str, Any]] = []
    for model in models:
        bare, routed, twin = [], [], []
        kept: Path | None = None
        for i in range(repeat):
            o = run(f"{model.stem} bare iterator #{i + 1}", ["bare", "--model", str(model)])
            bare.append(o.row(section="import", model=model.stem, row="bare iterator", repeat=i))
            o = run(f"{model.stem} bare routed iterators #{i + 1}", ["bare-routed", "--model", str(model)])
            routed.append(o.row(section="import", model=model.stem, row="bare routed iterators", repeat=i))
            store_dir = workdir / f"{model.stem}-{i}.store"
            o = run(
                f"{model.stem} twin import #{i + 1}",
                ["import", "--model", str(model), "--store-dir", str(store_dir)],
            )
            twin.append(o.row(section="import", model=model.stem, row="twin import", repeat=i))
            if o.ok and kept is None:
                kept = store_dir
        raw += bare + routed + twin
        summaries.append(report.import_summary(model.stem, bare, twin, routed))
        if kept is not None:
            o = run(f"{model.stem} table 1", ["stats", "--model", str(model), "--store-dir", str(kept)])
            stats.append(o.row(section="table1", model=model.stem, row="model_stats"))
    return raw, summaries, stats


def run_maps(models: list[Path], repeat: int, run: Runner) -> list[dict[str, Any]]:
    rows = []
    for model in models:
        for skill in SKILLS:
            for method in MAP_METHODS:
                argv = [
                    "map",
                    "--model",
                    str(model),
                    "--skill",
                    skill,
                    "--method",
                    method,
                    "--repeat",
                    str(repeat),
                ]
                o = run(f"{model.stem} {skill} {method}", argv)
                rows.append(o.row(section="maps", model=model.stem, skill=skill, method=method))
    return rows


def targets_block(summaries: list[dict[str, Any]], maps: list[dict[str, Any]]) -> str:
    import report

    lines = []
    for s in summaries:
        t = report.import_targets(s)
        if t:
            lines.append(f"  import  {report.short(s['model'])}: {t}")
    for r in maps:
        peers = [p for p in maps if p["model"] == r["model"] and p["skill"] == r["skill"]]
        t = (
            report.map_targets(r, [p for p in peers if p["method"] in ("trimesh", "manifold3d")])
            if r["ok"]
            else ""
        )
        if t:
            lines.append(f"  {r['method']:<11} {report.short(r['model'])} {r['skill']}: {t}")
    return "\n".join(lines)


def print_report(
    info: dict[str, Any],
    raw: list[dict[str, Any]],
    summaries: list[dict[str, Any]],
    stats: list[dict[str, Any]],
    maps: list[dict[str, Any]],
) -> None:
    import report

    pk = ", ".join(f"{k} {v}" for k, v in info["packages"].items())
    cpu = f"{info['cpu_model']}, {info['cores']} cores, {info['memory_gb']} GB"
    print(f"\nmachine: {cpu}; Python {info['python']}")
    print(f"packages: {pk}")
    print(f"date: {info['date']}; load average at start {info['loadavg_start'][0]:.2f}\n")
    if summaries:
        print("A) IMPORT (median of fresh processes; peak = max RSS of the process and its meshing child)")
        print(report.import_table(summaries))
        print("\nTable 1 (paper): twin.graph.stats.model_stats of the imported store")
        print(report.table1_table(stats))
    if maps:
        print("\nB) MAPS (time = median of runs; peak MB = method's own peak RSS, +MB above the setup)")
        print(f"storey per model (most elements): {report.storeys_line(maps)}")
        print(report.map_table(maps))
    foreign = [r["foreign_cpu"] for r in [*raw, *maps] if r.get("ok")]
    if foreign:
        share = sum(foreign) / len(foreign)
        warn = "  (numbers are contended: rerun on an idle machine)" if share > 0.1 else ""
        print(f"\nother processes used {share:.0%} of the machine's CPU during measurements on average{warn}")
    block = targets_block(summaries, maps)
    if block:
        print("\nTargets:\n" + block)


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--models", nargs="+", metavar="NAME", help="models by (part of) file name, or IFC paths")
    p.add_argument("--json", type=Path, metavar="OUT.json", help="also write machine info and rows as JSON")
    p.add_argument("--repeat", type=int, default=None, help="map timing repeats (median); default 5")
    p.add_argument(
        "--import-repeat", type=int, default=None, help="fresh import processes per model; default 5"
    )
    p.add_argument("--quick", action="store_true", help="small models only, one repeat")
    p.add_argument("--skip-import", action="store_true", help="maps only")
    p.add_argument("--skip-maps", action="store_true", help="imports only")
    p.add_argument(
        "--report", type=Path, metavar="IN.json", help="only print the tables of an earlier --json"
    )
    # internal: one measurement in this process
    p.add_argument("--child", help=argparse.SUPPRESS)
    p.add_argument("--model", help=argparse.SUPPRESS)
    p.add_argument("--skill", help=argparse.SUPPRESS)
    p.add_argument("--method", help=argparse.SUPPRESS)
    p.add_argument("--store-dir", help=argparse.SUPPRESS)
    return p.parse_args(argv)


def reprint(path: Path) -> int:
    """Print the tables of a JSON file an earlier run wrote (``--json``), without measuring."""
    doc = json.loads(path.read_text(encoding="utf-8"))
    rows = doc["rows"]

    def section(name: str) -> list[dict[str, Any]]:
        return [r for r in rows if r.get("section") == name]

    print_report(doc["machine"], section("import"), doc["import_summary"], section("table1"), section("maps"))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    if args.child:
        args.repeat = args.repeat or 1
        return child_main(args)
    if args.report:
        return reprint(args.report)
    if not SHARED_IFC.is_dir():
        print(f"Skipping benchmarks: no shared IFC models at {SHARED_IFC}.")
        return 0
    models = find_models(args.models, args.quick)
    if not models:
        print(f"Skipping benchmarks: no IFC models in {SHARED_IFC}.")
        return 0
    repeat = args.repeat or (1 if args.quick else 5)
    import_repeat = args.import_repeat or (1 if args.quick else 5)
    info = machine_info() | {
        "date": dt.date.today().isoformat(),
        "repeat": repeat,
        "import_repeat": import_repeat,
    }
    n_import = 0 if args.skip_import else len(models) * (2 * import_repeat + 1)
    n_maps = 0 if args.skip_maps else len(models) * len(SKILLS) * len(MAP_METHODS)
    run = Runner(total=n_import + n_maps)
    t0 = time.perf_counter()
    raw: list[dict[str, Any]] = []
    summaries: list[dict[str, Any]] = []
    stats: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="twin-bench-") as tmp:
        if not args.skip_import:
            raw, summaries, stats = run_imports(models, import_repeat, run, Path(tmp))
    maps = [] if args.skip_maps else run_maps(models, repeat, run)
    info["loadavg_end"] = list(os.getloadavg())
    info["elapsed_s"] = time.perf_counter() - t0
    print_report(info, raw, summaries, stats, maps)
    print(f"\n{run.total} measurements in {info['elapsed_s']:.0f} s")
    if args.json:
        doc = {
            "machine": info,
            "date": info["date"],
            "import_summary": summaries,
            "rows": [*raw, *stats, *maps],
        }
        args.json.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(HERE))
    raise SystemExit(main())
