"""Plain-text tables and target verdicts of a benchmark run (see ``run.py``).

Rows come in as dicts (the JSON rows); everything here only formats them.
"""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from typing import Any

Row = dict[str, Any]

JANESVILLE = "janesville"
TARGET_IMPORT_S = 10.0
TARGET_OVERHEAD = 1.3
TARGET_FULL_MAP_S = 1.0
TARGET_REGION_S = 0.005


# --- formatting ------------------------------------------------------------------------------------


def table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """Aligned columns: text left, numbers (cells starting with a digit, sign or '<') right."""
    widths = [len(h) for h in headers]
    for row in rows:
        widths = [max(w, len(c)) for w, c in zip(widths, row, strict=True)]

    def numeric(cell: str) -> bool:
        return bool(cell) and (cell[0].isdigit() or cell[0] in "+-<") and not cell.startswith("-- ")

    def line(cells: Sequence[str]) -> str:
        out = [c.rjust(w) if numeric(c) else c.ljust(w) for c, w in zip(cells, widths, strict=True)]
        return "  ".join(out).rstrip()

    rule = "  ".join("-" * w for w in widths)
    return "\n".join([line(headers), rule, *(line(r) for r in rows)])


def secs(value: float | None, unit: str = "s") -> str:
    if value is None:
        return "-"
    if unit == "ms":
        return f"{value * 1e3:.1f}" if value < 10 else f"{value * 1e3:.0f}"
    return f"{value:.2f}"


def mb(value: float | None) -> str:
    return "-" if value is None else f"{value:.0f}"


def count(value: int | None) -> str:
    return "-" if value is None else f"{value:,}"


def verdict(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


ALIASES = {
    "revit2012_janesville_restaurant": "Janesville",
    "AC11-Institute-Var-2-IFC": "AC11-Institute",
    "Duplex_A_20110907": "Duplex",
}


def short(model: str) -> str:
    """A short table label for a model (file stem); the JSON keeps the full stem."""
    name = ALIASES.get(model, model)
    return name if len(name) <= 18 else name[:17] + "~"


def short_error(error: str) -> str:
    if error.startswith("crashed ("):
        return error[len("crashed (") : -1]
    return error[:40]


# --- import ----------------------------------------------------------------------------------------


def _median(rows: list[Row], key: str) -> float | None:
    values = [r[key] for r in rows if r.get(key) is not None]
    return statistics.median(values) if values else None


def import_summary(model: str, bare: list[Row], twin: list[Row], routed: Sequence[Row] = ()) -> Row:
    """One model's import numbers: medians over the fresh-process repeats, peak = max over them.

    ``routed`` are the bare iterators with our kernel routing (older JSON files have none).
    """
    ok_bare = [r for r in bare if r["ok"]]
    ok_twin = [r for r in twin if r["ok"]]
    out: Row = {"model": model}
    if ok_bare:
        out["bare_s"] = _median(ok_bare, "seconds")
        out["bare_peak_mb"] = max(r["peak_mb"] for r in ok_bare)
        out["bare_cpu_s"] = _median(ok_bare, "cpu_s")
        out["shapes"] = ok_bare[0]["shapes"]
        out["bare_triangles"] = ok_bare[0]["triangles"]
    else:
        out["bare_error"] = bare[0]["error"] if bare else "not run"
    if ok_twin:
        out["twin_s"] = _median(ok_twin, "seconds")
        out["meshed_s"] = _median(ok_twin, "meshed_s")
        out["twin_peak_mb"] = max(r["peak_mb"] for r in ok_twin)
        out["twin_cpu_s"] = _median(ok_twin, "cpu_s")
        for key in ("elements", "meshes", "kernel_fallbacks", "mesh_failures"):
            out[key] = ok_twin[0][key]
    else:
        out["twin_error"] = twin[0]["error"] if twin else "not run"
    ok_routed = [r for r in routed if r["ok"]]
    if ok_routed:
        out["routed_s"] = _median(ok_routed, "seconds")
    if out.get("bare_s") and out.get("twin_s"):
        out["overhead"] = out["twin_s"] / out["bare_s"]
    if out.get("routed_s") and out.get("twin_s"):
        out["overhead_routed"] = out["twin_s"] / out["routed_s"]
    return out


def import_targets(s: Row) -> str:
    parts = []
    if "overhead" in s:
        parts.append(f"x<{TARGET_OVERHEAD}: {verdict(s['overhead'] < TARGET_OVERHEAD)}")
    if JANESVILLE in s["model"].lower() and "twin_s" in s:
        parts.append(f"<{TARGET_IMPORT_S:.0f}s: {verdict(s['twin_s'] < TARGET_IMPORT_S)}")
    return ", ".join(parts)


def import_table(summaries: list[Row]) -> str:
    headers = [
        "model", "bare s", "bare MB", "shapes", "triangles", "twin s", "meshed s", "twin MB", "cpu s",
        "elements", "meshes", "fallbk", "fail", "routed s", "twin/bare", "twin/routed",
        "targets",
    ]  # fmt: skip
    rows = []
    for s in summaries:
        bare_s = secs(s.get("bare_s")) if "bare_s" in s else f"-- {short_error(s.get('bare_error', ''))}"
        twin_s = secs(s.get("twin_s")) if "twin_s" in s else f"-- {short_error(s.get('twin_error', ''))}"
        rows.append(
            [
                short(s["model"]), bare_s, mb(s.get("bare_peak_mb")), count(s.get("shapes")),
                count(s.get("bare_triangles")), twin_s, secs(s.get("meshed_s")), mb(s.get("twin_peak_mb")),
                secs(s.get("twin_cpu_s")), count(s.get("elements")), count(s.get("meshes")),
                count(s.get("kernel_fallbacks")), count(s.get("mesh_failures")),
                secs(s.get("routed_s")), f"{s['overhead']:.2f}x" if "overhead" in s else "-",
                f"{s['overhead_routed']:.2f}x" if "overhead_routed" in s else "-", import_targets(s),
            ]
        )  # fmt: skip
    return table(headers, rows)


def table1_table(stats: list[Row]) -> str:
    headers = ["model", "IFC lines", "triples", "Turtle MB", "elements", "meshes", "triangles", "stats s"]
    rows = [
        [
            short(r["model"]), count(r["ifc_lines"]), count(r["triples"]), f"{r['turtle_bytes'] / 1e6:.1f}",
            count(r["elements"]), count(r["meshes"]), count(r["triangles"]), secs(r["seconds"]),
        ]
        if r["ok"]
        else [short(r["model"]), f"-- {short_error(r['error'])}", "", "", "", "", "", ""]
        for r in stats
    ]  # fmt: skip
    return table(headers, rows)


# --- maps ------------------------------------------------------------------------------------------


def _note(r: Row) -> str:
    method = r["method"]
    if method == "twin-full":
        return (
            f"first (cold) run {secs(r['first_s'], 'ms')} ms; scene load {r['setup']['scene_load_s']:.2f} s; "
            f"{r['setup']['selected']} selected"
        )
    if method in ("twin-region", "twin-region-prepared"):
        note = f"{r['windows']} windows of {r['window_cells']}^2 cells, max {secs(r.get('max_s'), 'ms')} ms"
        if "prepare_s" in r:
            note += f"; slab prepared once in {secs(r['prepare_s'], 'ms')} ms"
        return note
    if method == "trimesh":
        drawn = r.get("segments", r.get("triangles_drawn", 0))
        what = "segments" if "segments" in r else "triangles"
        split = f"slice {secs(r['slice_s'], 'ms')} + draw {secs(r['raster_s'], 'ms')} ms"
        return f"{r['elements']} elements, {drawn:,} {what} drawn; {split}"
    dropped = r["dropped_open"] + r["dropped_rejected"]
    split = (
        f"build {secs(r['build_s'], 'ms')} + bool {secs(r['boolean_s'], 'ms')} + draw "
        f"{secs(r['raster_s'], 'ms')} ms"
    )
    same = r.get("twin_same_input_s")
    same_text = f"; twin raster on the kept input {secs(same, 'ms')} ms" if same is not None else ""
    return (
        f"dropped {dropped}/{r['elements']} ({r['dropped_open']} open, {r['dropped_rejected']} "
        f"rejected); {split}; weld {r['prep_s']:.2f} s untimed{same_text}"
    )


def map_targets(r: Row, peers: list[Row]) -> str:
    method = r["method"]
    if method in ("twin-region", "twin-region-prepared") and "median_s" in r:
        return f"<5ms: {verdict(r['median_s'] < TARGET_REGION_S)}"
    if method == "twin-full" and JANESVILLE in r["model"].lower():
        peer_times = [p["median_s"] for p in peers if p["ok"] and "median_s" in p]
        fast = r["median_s"] < TARGET_FULL_MAP_S
        beats = bool(peer_times) and all(r["median_s"] < t for t in peer_times)
        return f"<1s: {verdict(fast)}, <peers: {verdict(beats)}"
    return ""


def map_table(rows: list[Row]) -> str:
    headers = [
        "model", "skill", "method", "time ms", "runs", "peak MB", "+MB", "grid", "occupied", "XOR",
        "targets", "notes",
    ]  # fmt: skip
    out = []
    for r in rows:
        base = [short(r["model"]), r["skill"], r["method"]]
        if not r["ok"]:
            out.append([*base, f"-- {short_error(r['error'])}", "", "", "", "", "", "", "", ""])
            continue
        peers = [p for p in rows if p["model"] == r["model"] and p["skill"] == r["skill"]]
        peers = [p for p in peers if p["method"] in ("trimesh", "manifold3d")]
        grid = r["setup"]["grid"]
        out.append(
            [
                *base, secs(r.get("median_s"), "ms"), str(r.get("runs", "")), mb(r.get("method_peak_mb")),
                mb(r.get("method_extra_mb")), f"{grid[0]}x{grid[1]}", count(r.get("occupied")),
                count(r.get("xor_cells")), map_targets(r, peers), _note(r),
            ]
        )  # fmt: skip
    return table(headers, out)


def storeys_line(rows: list[Row]) -> str:
    seen: dict[str, str] = {}
    for r in rows:
        if r["ok"]:
            seen.setdefault(r["model"], r["setup"]["storey"])
    return "; ".join(f"{short(m)}: {s}" for m, s in seen.items())
