"""Neuron-size building benchmark: the generated building (``neuron_gen.py``) against the issue's targets.

Rows (see README.md, "Neuron-size building"):

- import: twin import against the bare manifold iterator on the same file, each in fresh child
  processes (``run.py``'s machinery: wall time and peak RSS of the process and its meshing child);
- Table 1: IFC lines, elements, meshes, triples, Turtle size of the imported store, next to the paper's;
- full maps: every configured skill on every storey (a ``storey-maps`` child on the imported store);
- live: ``live.py`` on the same file: daemon start to all maps published, update latency p50/p99 of
  observations on the busiest storey, daemon RSS.

Usage::

    python benchmarks/neuron.py [--seed 1] [--storeys 6] [--scale 1.0] [--unit m] [--ifc FILE]
                                [--import-repeat 3] [--repeat 3] [--count 200] [--skip-live] [--json OUT]

The building is generated into ``benchmarks/.cache/`` (ignored by git) unless it is there already.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import shutil
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
CACHE = HERE / ".cache"
PAPER = {"ifc_lines": 3.8e6, "elements": 11_500, "meshes": 10_822, "triples": 2.4e5}
"""The Neuron building in the paper's Table 1."""
TARGET_OVERHEAD = 1.3
TARGET_FULL_MAP_S = 1.0
TARGET_P50_MS = 20.0
TARGET_P99_MS = 50.0
TARGET_RSS_MB = 2048.0

Row = dict[str, Any]


def cached_building(seed: int, storeys: int, scale: float, unit: str) -> tuple[Path, float | None]:
    """The generated file (generated now if absent) and the seconds generation took (None: cached)."""
    import neuron_gen

    path = CACHE / f"neuron-seed{seed}-{storeys}st-x{scale:g}-{unit}.ifc"
    if path.exists():
        return path, None
    options = neuron_gen.Options(seed=seed, storeys=storeys, unit=unit, scale=scale)  # type: ignore[arg-type]
    t0 = time.perf_counter()
    tmp = path.with_suffix(".part")
    neuron_gen.generate(tmp, options, lambda msg: print(f"  {msg}", file=sys.stderr, flush=True))
    tmp.rename(path)
    return path, time.perf_counter() - t0


def measure_imports(ifc: Path, repeat: int, work: Path) -> tuple[list[Row], Row, Row | None, Path | None]:
    """Bare iterator and twin import, alternating in fresh processes; then Table 1 of one store."""
    import report
    import run

    runner = run.Runner(total=2 * repeat + 1)
    bare, twin = [], []
    kept: Path | None = None
    for i in range(repeat):
        o = runner(f"bare iterator #{i + 1}", ["bare", "--model", str(ifc)])
        bare.append(o.row(section="import", model=ifc.stem, row="bare iterator", repeat=i))
        store = work / f"store-{i}"
        o = runner(f"twin import #{i + 1}", ["import", "--model", str(ifc), "--store-dir", str(store)])
        twin.append(o.row(section="import", model=ifc.stem, row="twin import", repeat=i))
        if o.ok and kept is None:
            kept = store
        elif o.ok:
            shutil.rmtree(store, ignore_errors=True)
    stats = None
    if kept is not None:
        o = runner("table 1", ["stats", "--model", str(ifc), "--store-dir", str(kept)])
        stats = o.row(section="table1", model=ifc.stem)
    return [*bare, *twin], report.import_summary(ifc.stem, bare, twin), stats, kept


def measure_maps(ifc: Path, store: Path, repeat: int) -> Row:
    import run

    o = run.Runner(total=1)(
        "full maps, every storey and skill",
        ["storey-maps", "--model", str(ifc), "--store-dir", str(store), "--repeat", str(repeat)],
    )
    return o.row(section="maps", model=ifc.stem)


def measure_live(ifc: Path, count: int) -> Row:
    import live

    print(f"live: daemon on {ifc.name}, {count} observations ...", file=sys.stderr, flush=True)
    return {"section": "live", **live.run_model(str(ifc), count)}


# --- the report ------------------------------------------------------------------------------------


def _pass(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def report_text(doc: dict[str, Any]) -> str:
    import report

    lines: list[str] = []
    m = doc["machine"]
    lines.append(f"machine: {m['cpu_model']}, {m['cores']} cores, {m['memory_gb']} GB; Python {m['python']}")
    lines.append("packages: " + ", ".join(f"{k} {v}" for k, v in m["packages"].items()))
    gen = doc["building"]
    made = f"generated in {gen['generate_s']:.1f} s" if gen.get("generate_s") else "cached"
    lines.append(f"date: {doc['date']}; building: {gen['file']} ({gen['mb']:.1f} MB, {made})\n")

    rows: list[list[str]] = []
    s = doc.get("import_summary") or {}
    if s:
        ratio = s.get("overhead")
        rows.append(
            [
                "import: bare manifold iterator",
                f"{report.secs(s.get('bare_s'))} s",
                f"peak {report.mb(s.get('bare_peak_mb'))} MB",
                "",
            ]
        )
        rows.append(
            [
                "import: twin import",
                f"{report.secs(s.get('twin_s'))} s",
                f"peak {report.mb(s.get('twin_peak_mb'))} MB; "
                f"meshed after {report.secs(s.get('meshed_s'))} s",
                "",
            ]
        )
        if ratio is not None:
            rows.append(
                [
                    "import: twin / bare",
                    f"{ratio:.2f}x",
                    f"< {TARGET_OVERHEAD}x",
                    _pass(ratio < TARGET_OVERHEAD),
                ]
            )
    t1 = doc.get("table1") or {}
    if t1.get("ok"):
        for key, label in (
            ("ifc_lines", "IFC lines"),
            ("elements", "elements"),
            ("meshes", "meshes"),
            ("triples", "triples"),
        ):
            paper = PAPER[key]
            shown = f"{paper:.1e}" if isinstance(paper, float) else f"{paper:,}"
            rows.append([f"Table 1: {label}", f"{t1[key]:,}", f"paper {shown}", ""])
        rows.append(["Table 1: Turtle size", f"{t1['turtle_bytes'] / 1e6:.1f} MB", "paper -", ""])
    maps = (doc.get("maps") or {}).get("maps") or []
    if maps:
        worst = max(maps, key=lambda r: r["median_s"])
        first = max(maps, key=lambda r: r["first_s"])
        per_skill: dict[str, list[float]] = {}
        for r in maps:
            per_skill.setdefault(r["skill"], []).append(r["median_s"])
        for skill, times in per_skill.items():
            rows.append(
                [
                    f"full map: {skill}",
                    f"{min(times) * 1e3:.0f}-{max(times) * 1e3:.0f} ms",
                    f"{len(times)} storeys, median of runs",
                    "",
                ]
            )
        rows.append(
            [
                "full map: slowest",
                f"{worst['median_s'] * 1e3:.0f} ms",
                f"{worst['storey']}/{worst['skill']} (first run {first['first_s'] * 1e3:.0f} ms); < 1 s",
                _pass(first["first_s"] < TARGET_FULL_MAP_S),
            ]
        )
    live = doc.get("live")
    if live:
        rows.append(
            [
                "daemon: start to all maps published",
                f"{live['startup_to_serving_s']:.1f} s",
                f"maps built and published in {live['maps_published_s']:.2f} s",
                "",
            ]
        )
        rows.append(
            [
                "update latency p50",
                f"{live['update_latency_p50_ms']:.1f} ms",
                f"< {TARGET_P50_MS:.0f} ms ({live['updates_received']} updates, {live['storey']})",
                _pass(live["update_latency_p50_ms"] < TARGET_P50_MS),
            ]
        )
        rows.append(
            [
                "update latency p99",
                f"{live['update_latency_p99_ms']:.1f} ms",
                f"< {TARGET_P99_MS:.0f} ms",
                _pass(live["update_latency_p99_ms"] < TARGET_P99_MS),
            ]
        )
        rows.append(
            ["ack round trip p50 / p99", f"{live['ack_p50_ms']:.1f} / {live['ack_p99_ms']:.1f} ms", "", ""]
        )
        rss = max(live["rss_peak_mb"], live["rss_end_mb"])
        rows.append(
            [
                "daemon RSS start / end / peak",
                f"{live['rss_start_mb']} / {live['rss_end_mb']} / {live['rss_peak_mb']} MB",
                f"< {TARGET_RSS_MB:.0f} MB",
                _pass(rss < TARGET_RSS_MB),
            ]
        )
    lines.append(report.table(["row", "figure", "context / target", "verdict"], rows))
    if maps:
        lines.append("\nfull maps (ms, median of runs; first run in brackets):")
        skills = list(dict.fromkeys(r["skill"] for r in maps))
        storeys = list(dict.fromkeys(r["storey"] for r in maps))
        by = {(r["storey"], r["skill"]): r for r in maps}
        body = [
            [st, *(f"{by[st, k]['median_s'] * 1e3:.0f} ({by[st, k]['first_s'] * 1e3:.0f})" for k in skills)]
            for st in storeys
        ]
        lines.append(report.table(["storey", *skills], body))
    return "\n".join(lines)


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--storeys", type=int, default=6)
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--unit", choices=("m", "mm"), default="m")
    p.add_argument("--ifc", type=Path, help="measure this file instead of a generated one")
    p.add_argument("--import-repeat", type=int, default=3, help="fresh processes per import row")
    p.add_argument("--repeat", type=int, default=3, help="runs per full map (median)")
    p.add_argument("--count", type=int, default=200, help="observations in the live rows")
    p.add_argument("--skip-live", action="store_true")
    p.add_argument("--json", type=Path, metavar="OUT.json")
    p.add_argument("--report", type=Path, metavar="IN.json", help="only print the table of an earlier --json")
    return p.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    if args.report:
        print(report_text(json.loads(args.report.read_text(encoding="utf-8"))))
        return 0
    import run

    started = time.perf_counter()
    if args.ifc:
        ifc, generate_s = args.ifc.resolve(), None
    else:
        ifc, generate_s = cached_building(args.seed, args.storeys, args.scale, args.unit)
    doc: dict[str, Any] = {
        "date": dt.date.today().isoformat(),
        "machine": run.machine_info(),
        "building": {
            "file": ifc.name,
            "mb": ifc.stat().st_size / 1e6,
            "generate_s": generate_s,
            "seed": args.seed,
            "storeys": args.storeys,
            "scale": args.scale,
            "unit": args.unit,
        },
        "paper": PAPER,
    }
    work = Path(tempfile.mkdtemp(prefix="neuron-bench-"))
    try:
        raw, doc["import_summary"], doc["table1"], store = measure_imports(ifc, args.import_repeat, work)
        doc["import_rows"] = raw
        if store is not None:
            doc["maps"] = measure_maps(ifc, store, args.repeat)
        if not args.skip_live:
            doc["live"] = measure_live(ifc, args.count)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    doc["elapsed_s"] = time.perf_counter() - started
    print()
    print(report_text(doc))
    print(f"\n{doc['elapsed_s']:.0f} s in all")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(HERE))
    raise SystemExit(main())
