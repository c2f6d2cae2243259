"""The ``twin`` command: import IFC into the graph, inspect it, and write skill maps.

Run ``twin --help`` or ``twin COMMAND --help``. Every error is one line on stderr and a non-zero exit.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

from twin.config import Config, load_config, store_path_of
from twin.errors import ModelError, TwinError
from twin.store import GraphStore


class ProgressBar:
    """A one-line progress bar on a terminal (nothing when the stream is not a TTY)."""

    def __init__(self, label: str, stream: TextIO | None = None) -> None:
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty()
        self.start = time.monotonic()
        self._last = -1.0
        self._finished = False

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled or total <= 0 or self._finished:
            return
        now = time.monotonic()
        if done < total and now - self._last < 0.1:
            return
        self._last = now
        width = 30
        filled = int(width * done / total)
        bar = "#" * filled + "-" * (width - filled)
        rate = done / max(now - self.start, 1e-9)
        self.stream.write(f"\r{self.label} [{bar}] {done}/{total} ({rate:.0f}/s)")
        if done >= total:
            self._finished = True
            self.stream.write("\n")
        self.stream.flush()


# --- commands ---------------------------------------------------------------------------------------
def cmd_import(args: argparse.Namespace, cfg: Config) -> int:
    from adapters.ifc import read_model
    from twin.import_model import ensure_importable, import_model
    from twin.vocab import check_base

    site = args.site or cfg.site
    base_iri = check_base(args.base_iri or cfg.base_iri(site))
    store_path = store_path_of(args, cfg)
    model_path = Path(args.model)
    if not model_path.is_file():
        msg = f"No such file: {model_path}"
        raise ModelError(msg)
    if store_path.exists():  # fail before meshing, which dominates the time
        with GraphStore.open(store_path) as store:
            ensure_importable(store, replace=args.replace)
    t0 = time.perf_counter()
    # Mesh before the store is open: the meshing child is forked, and the store runs threads.
    model = read_model(
        model_path,
        static_types=cfg.import_.static_types,
        kernels=cfg.import_.kernels,
        threads=cfg.import_.threads,
        progress=ProgressBar("meshing"),
    )
    t1 = time.perf_counter()
    with GraphStore.open(store_path) as store:
        summary = import_model(store, model, base_iri=base_iri, site=site, replace=args.replace)
    t2 = time.perf_counter()
    print(
        f"imported {model_path} into {store_path}: {summary.elements} elements "
        f"({summary.meshes} with meshes), {summary.spaces} spaces, {summary.storeys} storeys, "
        f"{summary.triples} triples in {t2 - t0:.1f} s (read+mesh {t1 - t0:.1f} s, store {t2 - t1:.1f} s)"
    )
    if summary.kernel_fallbacks:
        print(f"{len(summary.kernel_fallbacks)} element(s) meshed by a fallback kernel")
    if summary.mesh_failures:
        print(f"{len(summary.mesh_failures)} element(s) without geometry ('twin stats --json' lists them)")
    return 0


def _size(n: int) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:,.1f} {unit}"
    return f"{n} B"


def cmd_stats(args: argparse.Namespace, cfg: Config) -> int:
    from twin.stats import model_stats

    with GraphStore.open(store_path_of(args, cfg), read_only=True) as store:
        stats = model_stats(store)
    if args.json:
        print(json.dumps(stats.as_dict(), indent=2))
        return 0
    rows = [
        ("source", f"{stats.source} ({stats.schema})"),
        ("lines in IFC file", f"{stats.ifc_lines:,}"),
        ("triples", f"{stats.triples:,}"),
        ("Turtle size", _size(stats.turtle_bytes)),
        ("elements", f"{stats.elements:,}"),
        ("meshes", f"{stats.meshes:,} ({stats.triangles:,} triangles)"),
        ("spaces", f"{stats.spaces:,}"),
        ("storeys", f"{len(stats.storeys)}"),
        ("mesh failures", f"{stats.mesh_failures}"),
        ("kernel fallbacks", f"{stats.kernel_fallbacks}"),
    ]
    w = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"{k:<{w}}  {v}")
    print("\nstoreys (key, elevation, spaces, elements, name):")
    for s in stats.storeys:
        print(f"  {s.key:<24} {s.elevation_m:8.3f} m {s.spaces:5d} {s.elements:7d}  {s.name}")
    print("\nelements per IFC class:")
    for cls, n in stats.elements_per_class.items():
        print(f"  {cls:<32} {n:6d}")
    return 0


def cmd_export(args: argparse.Namespace, cfg: Config) -> int:
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with GraphStore.open(store_path_of(args, cfg), read_only=True) as store:
        store.dump_turtle(out)
    print(f"wrote {out} ({_size(out.stat().st_size)})")
    return 0


def cmd_query(args: argparse.Namespace, cfg: Config) -> int:
    sparql = Path(args.sparql[1:]).read_text() if args.sparql.startswith("@") else args.sparql
    with GraphStore.open(store_path_of(args, cfg), read_only=True) as store:
        media, body = store.query_serialized(sparql)
        if args.json or media == "text/turtle":
            sys.stdout.write(body.decode())
            if not body.endswith(b"\n"):
                sys.stdout.write("\n")
            return 0
        data = json.loads(body)
        if "boolean" in data:
            print("true" if data["boolean"] else "false")
            return 0
        names = data["head"]["vars"]
        rows = [[b.get(n, {}).get("value", "") for n in names] for b in data["results"]["bindings"]]
    widths = [min(60, max([len(n), *(len(r[i]) for r in rows)])) for i, n in enumerate(names)]
    print("  ".join(n.ljust(w) for n, w in zip(names, widths, strict=True)))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(v[:60].ljust(w) for v, w in zip(r, widths, strict=True)))
    print(f"({len(rows)} row{'s' if len(rows) != 1 else ''})")
    return 0


def cmd_sample(args: argparse.Namespace, cfg: Config) -> int:
    from adapters.sample_lab import write_lab

    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_lab(out, length_unit=args.unit, storeys=args.storeys)
    print(f"wrote the sample lab building to {out}")
    return 0


# --- parser -----------------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="twin", description="building-twin: IFC -> graph world model -> robot maps"
    )
    p.add_argument("--config", type=Path, help="a TOML file merged over config/default.toml")
    p.add_argument("-v", "--verbose", action="count", default=0, help="more logging (-vv for debug)")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def store_arg(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("--store", help="store directory (default: store.path of the configuration)")

    sp = sub.add_parser("import", help="build the graph world model of an IFC file into a store")
    sp.add_argument("model", help="the IFC file")
    store_arg(sp)
    sp.add_argument("--site", help="site name (default: site.name of the configuration)")
    sp.add_argument("--base-iri", help="base IRI of the site's nodes (default from the configuration)")
    sp.add_argument("--replace", action="store_true", help="replace the contents of a non-empty store")
    sp.set_defaults(func=cmd_import)

    sp = sub.add_parser("stats", help="the model's statistics (the paper's Table 1, storeys, classes)")
    store_arg(sp)
    sp.add_argument("--json", action="store_true", help="print JSON")
    sp.set_defaults(func=cmd_stats)

    sp = sub.add_parser("export", help="write the graph as Turtle")
    store_arg(sp)
    sp.add_argument("out", help="the Turtle file to write")
    sp.set_defaults(func=cmd_export)

    sp = sub.add_parser(
        "query", help="run a read-only SPARQL query (prefixes bot, beo, twin, ... predefined)"
    )
    store_arg(sp)
    sp.add_argument("sparql", help="the query, or @FILE to read it from a file")
    sp.add_argument("--json", action="store_true", help="print SPARQL JSON results")
    sp.set_defaults(func=cmd_query)

    sp = sub.add_parser("sample", help="write a bundled sample building")
    sp.add_argument(
        "which", choices=["lab"], help="which sample: 'lab' (the paper's lab, two rooms and a corridor)"
    )
    sp.add_argument("out", help="the IFC file to write")
    sp.add_argument("--unit", choices=["metre", "foot"], default="metre", help="length unit of the file")
    sp.add_argument("--storeys", type=int, choices=[1, 2], default=1, help="number of storeys")
    sp.set_defaults(func=cmd_sample)

    from twin.cli_map import add_map_parser

    add_map_parser(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    try:
        cfg = load_config(args.config)
        code: int = args.func(args, cfg)
        return code
    except TwinError as err:
        print(f"twin: error: {err}", file=sys.stderr)
        return 1
    except OSError as err:  # files the user named: unreadable, missing, a directory, disk full ...
        where = f" {err.filename}" if getattr(err, "filename", None) else ""
        print(f"twin: error:{where} {err.strerror or err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("twin: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
