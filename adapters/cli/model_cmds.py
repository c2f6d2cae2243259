"""``twin import``, ``stats``, ``export``, ``query`` and ``sample``: build the graph and look into it."""

from __future__ import annotations

import argparse
import json
import re
import shutil
import sys
import time
from pathlib import Path

from adapters.cli.common import (
    check_site,
    human_size,
    open_store,
    remote_store_of,
    store_exists,
    store_label,
    store_path_of,
)
from adapters.cli.progress import progress_bar
from twin.config import Config
from twin.errors import ModelError, QueryError, StoreError


# --- commands ---------------------------------------------------------------------------------------
def import_site(args: argparse.Namespace, cfg: Config, model_path: Path) -> tuple[str, str]:
    """(the site an import names its model, where that name comes from): ``--site``, else the
    configuration's ``site.name`` if a configuration file sets it, else the model file's name."""
    from twin.graph.vocab import site_slug

    if args.site:
        return check_site(args.site), "--site"
    if cfg.site_set:
        return cfg.site, "site.name of the configuration"
    return site_slug(model_path.name), "from the file name; --site to choose"


def cmd_import(args: argparse.Namespace, cfg: Config) -> int:
    from adapters.cli.import_file import import_ifc
    from twin.graph.vocab import check_base

    model_path = Path(args.model)
    site, site_from = import_site(args, cfg, model_path)
    base_iri = check_base(args.base_iri or cfg.base_iri(site))
    if not model_path.is_file():
        kind = "a directory" if model_path.is_dir() else "not a regular file"
        msg = (
            f"{model_path} is {kind}, not an IFC file"
            if model_path.exists()
            else f"No such file: {model_path}"
        )
        raise ModelError(msg)
    t0 = time.perf_counter()
    new_store = not store_exists(args, cfg)
    try:
        with progress_bar("meshing", unit="elements") as advance, open_store(args, cfg) as store:
            summary = import_ifc(
                model_path,
                store,
                base_iri=base_iri,
                site=site,
                static_types=cfg.import_.static_types,
                kernels=cfg.import_.kernels,
                threads=cfg.import_.threads,
                replace=args.replace,
                progress=advance,
            )
    except BaseException:
        if new_store:  # a failed import leaves no empty store behind
            shutil.rmtree(store_path_of(args, cfg), ignore_errors=True)
        raise
    if remote_store_of(args, cfg) is None:  # the daemon's derived state is of the store's old contents
        from twin.live.snapshots import snapshot_path  # here: stats, query, ... load no live twin

        snapshot_path(store_path_of(args, cfg)).unlink(missing_ok=True)
    seconds = time.perf_counter() - t0
    print(
        f"imported {model_path} into {store_label(args, cfg)} as site {site!r} ({site_from}) under "
        f"{base_iri}: {plural(summary.elements, 'element')} "
        f"({summary.meshes:,} with meshes), {plural(summary.spaces, 'space')}, "
        f"{plural(summary.storeys, 'storey')}, {plural(summary.triples, 'triple')} in {seconds:.1f} s"
    )
    if summary.kernel_fallbacks:
        print(f"{plural(len(summary.kernel_fallbacks), 'element')} meshed by a fallback kernel")
    failed = len(summary.mesh_failures)
    without = summary.elements - summary.meshes
    if without > 0 or failed:
        parts = [f"{failed:,} that no kernel could mesh ('twin stats --json' lists them)"] if failed else []
        if without - failed > 0:
            parts.append(f"{without - failed:,} with no body in the file (nothing to mesh)")
        print(f"{plural(without, 'element')} without geometry: {'; '.join(parts)}")
    return 0


def plural(n: int, word: str) -> str:
    """``1 storey``, ``2 storeys``, ``1,660 elements``."""
    return f"{n:,} {word}{'' if n == 1 else 's'}"


def cmd_stats(args: argparse.Namespace, cfg: Config) -> int:
    from twin.graph.stats import model_stats

    with open_store(args, cfg, read_only=True) as store:
        stats = model_stats(store)
    if args.json:
        print(json.dumps(stats.as_dict(), indent=2))
        return 0
    rows = [
        ("source", f"{stats.source} ({stats.schema})"),
        ("lines in IFC file", f"{stats.ifc_lines:,}"),
        ("triples", f"{stats.triples:,}"),
        ("Turtle size", human_size(stats.turtle_bytes)),
        ("elements", f"{stats.elements:,}" + (f" (and {stats.removed:,} removed)" if stats.removed else "")),
        ("meshes", f"{stats.meshes:,} ({stats.triangles:,} triangles)"),
        ("spaces", f"{stats.spaces:,}"),
        ("storeys", f"{len(stats.storeys)}"),
        ("meshed by kernel", ", ".join(f"{k} {n:,}" for k, n in stats.meshes_per_kernel.items()) or "-"),
        ("mesh failures", f"{stats.mesh_failures}"),
        ("kernel fallbacks", f"{stats.kernel_fallbacks}"),
    ]
    w = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"{k:<{w}}  {v}")
    print("\nstoreys (key, elevation, spaces, elements, name):")
    for s in stats.storeys:
        print(f"  {s.key:<24} {s.elevation_m:8.3f} m {s.spaces:5d} {s.elements:7d}  {s.name}")
    if stats.failed_elements:
        print("\nelements without geometry (no geometry kernel could mesh their body):")
        for iri in stats.failed_elements:
            print(f"  {iri}")
    print("\nelements per IFC class:")
    for cls, n in stats.elements_per_class.items():
        print(f"  {cls:<32} {n:6d}")
    return 0


def cmd_export(args: argparse.Namespace, cfg: Config) -> int:
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with open_store(args, cfg, read_only=True) as store:
        store.dump_turtle(out)
    print(f"wrote {out} ({human_size(out.stat().st_size)})")
    return 0


def cmd_backup(args: argparse.Namespace, cfg: Config) -> int:
    out = Path(args.out)
    from twin.graph.store import EmbeddedStore

    with open_store(args, cfg, read_only=True) as store:
        if not isinstance(store, EmbeddedStore):
            msg = "twin backup copies an embedded store (--store DIR): back up the SPARQL server itself."
            raise StoreError(msg)
        store.backup(out)
        triples = len(store)
    size = sum(f.stat().st_size for f in out.rglob("*") if f.is_file())
    print(f"wrote {out} ({triples:,} triples, {human_size(size)}): 'twin serve --store {out}' serves it")
    return 0


_UPDATE_WORDS = ("INSERT", "DELETE", "LOAD", "CLEAR", "CREATE", "DROP", "COPY", "MOVE", "ADD", "WITH")
_PROLOGUE = re.compile(r"\s*(?:#[^\n]*\n|PREFIX\s+[^:\s]*:\s*<[^>]*>|BASE\s*<[^>]*>)", re.IGNORECASE)


def update_keyword(sparql: str) -> str | None:
    """The keyword that makes ``sparql`` an update (``INSERT``, ``DELETE``, ``LOAD``, ...), or None."""
    pos = 0
    while (m := _PROLOGUE.match(sparql, pos)) is not None and m.end() > pos:
        pos = m.end()
    word = re.match(r"\s*([A-Za-z]+)", sparql[pos:])
    keyword = word.group(1).upper() if word else ""
    return keyword if keyword in _UPDATE_WORDS else None


def cmd_query(args: argparse.Namespace, cfg: Config) -> int:
    sparql = Path(args.sparql[1:]).read_text() if args.sparql.startswith("@") else args.sparql
    keyword = update_keyword(sparql)
    if keyword is not None:
        msg = (
            f"twin query runs read-only queries (SELECT, ASK, CONSTRUCT, DESCRIBE); this is an update "
            f"({keyword}), which is not allowed: robots change the twin through observations."
        )
        raise QueryError(msg)
    with open_store(args, cfg, read_only=True) as store:
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
    # columns line up up to 60 characters; a longer value is printed whole and pushes the rest along
    widths = [min(60, max([len(n), *(len(r[i]) for r in rows)])) for i, n in enumerate(names)]
    print("  ".join(n.ljust(w) for n, w in zip(names, widths, strict=True)).rstrip())
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(v.ljust(w) for v, w in zip(r, widths, strict=True)).rstrip())
    print(f"({len(rows)} row{'s' if len(rows) != 1 else ''})")
    return 0


def cmd_sample(args: argparse.Namespace, cfg: Config) -> int:
    from adapters.ifc.sample_lab import write_lab

    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_lab(out, length_unit=args.unit, storeys=args.storeys)
    print(f"wrote the sample lab building to {out}")
    return 0
