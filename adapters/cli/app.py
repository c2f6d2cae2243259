"""The ``twin`` command: the composition root that wires the core to its adapters.

Run ``twin --help`` or ``twin COMMAND --help``. Every error is one line on stderr and a non-zero exit.
Each command lives in its own module (``model_cmds``, ``map_cmd``, ...) and registers its parser here.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from adapters.cli import (
    config_cmd,
    demo_cmd,
    explain_cmd,
    map_cmd,
    model_cmds,
    network_cmds,
    record_cmd,
    robot_cmds,
    serve_cmd,
    watch_cmd,
    zone_cmd,
)
from adapters.cli.common import add_store_args
from twin.errors import StoreNotEmptyError, StoreNotFoundError, TwinError

BROKEN_PIPE = 128 + 13
"""The exit code of a command whose output's reader went away (as if killed by SIGPIPE, like ``cat``)."""


def _store_arg(sp: argparse.ArgumentParser) -> None:
    add_store_args(sp)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="twin", description="building-twin: IFC -> graph world model -> robot maps, served live"
    )
    _global_options(p, after=False)
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    sp = sub.add_parser("import", help="build the graph world model of an IFC file into a store")
    sp.add_argument("model", help="the IFC file")
    _store_arg(sp)
    sp.add_argument(
        "--site", help="site name (default: site.name if configured, else the file's name: A_b.ifc -> a-b)"
    )
    sp.add_argument("--base-iri", help="base IRI of the site's nodes (default from the configuration)")
    sp.add_argument("--replace", action="store_true", help="replace the contents of a non-empty store")
    sp.set_defaults(func=model_cmds.cmd_import)

    sp = sub.add_parser("stats", help="the model's statistics (the paper's Table 1, storeys, classes)")
    _store_arg(sp)
    sp.add_argument("--json", action="store_true", help="print JSON")
    sp.set_defaults(func=model_cmds.cmd_stats)

    sp = sub.add_parser("export", help="write the graph as Turtle")
    _store_arg(sp)
    sp.add_argument("out", help="the Turtle file to write")
    sp.set_defaults(func=model_cmds.cmd_export)

    sp = sub.add_parser(
        "backup", help="copy the store into a new directory (consistent, also while the daemon runs)"
    )
    _store_arg(sp)
    sp.add_argument("out", help="the new directory to write the copy to")
    sp.set_defaults(func=model_cmds.cmd_backup)

    sp = sub.add_parser(
        "query", help="run a read-only SPARQL query (prefixes bot, beo, twin, ... predefined)"
    )
    _store_arg(sp)
    sp.add_argument("sparql", help="the query, or @FILE to read it from a file")
    sp.add_argument("--json", action="store_true", help="print SPARQL JSON results")
    sp.set_defaults(func=model_cmds.cmd_query)

    sp = sub.add_parser("sample", help="write a bundled sample building")
    sp.add_argument(
        "which", choices=["lab"], help="which sample: 'lab' (the paper's lab, two rooms and a corridor)"
    )
    sp.add_argument("out", help="the IFC file to write")
    sp.add_argument("--unit", choices=["metre", "foot"], default="metre", help="length unit of the file")
    sp.add_argument(
        "--storeys",
        type=int,
        choices=[1, 2],
        default=2,
        help="number of storeys (default 2: a first floor above)",
    )
    sp.set_defaults(func=model_cmds.cmd_sample)

    sp = sub.add_parser(
        "map", help="write skill maps (map_server YAML+PGM, PNG, CDR; points skills: PCD) per storey"
    )
    _store_arg(sp)
    sp.add_argument("--skill", action="append", help="a configured skill (repeatable)")
    sp.add_argument("--all-skills", action="store_true", help="every configured skill")
    sp.add_argument("--storey", help="one storey key (see 'twin stats'); default: every storey")
    sp.add_argument("--out", help="output directory (default: maps.out of the configuration)")
    sp.add_argument(
        "--force", action="store_true", help="build points clouds estimated over [maps] max_points_per_storey"
    )
    sp.set_defaults(func=map_cmd.cmd_map)

    serve_cmd.add_parser(sub)
    robot_cmds.add_parsers(sub)
    watch_cmd.add_parser(sub)
    zone_cmd.add_parsers(sub)
    explain_cmd.add_parser(sub)
    record_cmd.add_parser(sub)
    demo_cmd.add_parser(sub)
    network_cmds.add_parsers(sub)
    config_cmd.add_parsers(sub)
    for command in sub.choices.values():  # `twin serve --config FILE` as well as `twin --config FILE serve`
        _global_options(command, after=True)
    return p


def _version() -> str:
    """The installed distribution's version (``0.1.0``); ``unknown`` in a checkout not installed."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("building-twin")
    except PackageNotFoundError:
        return "unknown (not installed: pip install -e .)"


def _global_options(p: argparse.ArgumentParser, *, after: bool) -> None:
    """``--config`` and ``-v``, accepted before the command and after it (kept apart: see _merge)."""
    prefix = "after_" if after else ""
    p.add_argument(
        "--config", dest=f"{prefix}config", type=Path, help="a TOML file merged over config/default.toml"
    )
    p.add_argument(
        "-v", "--verbose", dest=f"{prefix}verbose", action="count", default=0,
        help="more logging (-vv for debug)",
    )  # fmt: skip


def _merge_global_options(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """One ``config`` and one ``verbose`` from both places; two different config files are an error."""
    after = getattr(args, "after_config", None)
    if after is not None and args.config is not None and after != args.config:
        parser.error(f"--config given twice: {args.config} before the command and {after} after it")
    args.config = args.config if args.config is not None else after
    args.verbose += getattr(args, "after_verbose", 0)


def _hint(err: TwinError, args: argparse.Namespace) -> str:
    """The error's message with what to do next, in this command's words."""
    if isinstance(err, StoreNotFoundError):
        return f"{err} Run 'twin import MODEL.ifc --store DIR' first."
    if isinstance(err, StoreNotEmptyError):
        return f"{err} Pass --replace to re-import into it."
    return str(err)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    _merge_global_options(parser, args)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    try:
        cfg = config_cmd.load(args.config)
        code: int = args.func(args, cfg)
        return code
    except TwinError as err:
        print(f"twin: error: {_hint(err, args)}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # `twin stats | head`: the reader has gone; end quietly, as cat would
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # nothing more to flush at exit
        os.close(devnull)
        return BROKEN_PIPE
    except OSError as err:  # files the user named: unreadable, missing, a directory, disk full ...
        where = f" {err.filename}:" if getattr(err, "filename", None) else ""
        print(f"twin: error:{where} {err.strerror or err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("twin: interrupted", file=sys.stderr)
        return 130
