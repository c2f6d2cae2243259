"""The ``twin`` command: the composition root that wires the core to its adapters.

Run ``twin --help`` or ``twin COMMAND --help``. Every error is one line on stderr and a non-zero exit.
Each command lives in its own module (``model_cmds``, ``map_cmd``, ...) and registers its parser here.
A command imports only its own module, when it runs: ``twin observe`` loads neither the daemon's
libraries nor SciPy (each ``twin`` process starts in a fraction of the time of loading them all).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from adapters.cli.args import add_store_args
from twin.errors import StoreNotEmptyError, StoreNotFoundError, TwinError

if TYPE_CHECKING:
    from twin.config import Config

BROKEN_PIPE = 128 + 13
"""The exit code of a command whose output's reader went away (as if killed by SIGPIPE, like ``cat``)."""

COMMAND_MODULES: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("serve_cmd", ("serve",)),
    ("robot_cmds", ("observe", "status", "storey")),
    ("watch_cmd", ("watch",)),
    ("zone_cmd", ("zone",)),
    ("explain_cmd", ("explain",)),
    ("record_cmd", ("record",)),
    ("demo_cmd", ("demo",)),
    ("network_cmds", ("router", "acl")),
    ("config_cmd", ("config",)),
)
"""The modules of ``adapters.cli`` that add their own commands' parsers (``add_parser`` or
``add_parsers``), in ``twin --help``'s order, with the commands each adds. A command named here builds
only its module's parsers, one of :data:`OWN_COMMANDS` none of them; any other name (or none, or
``--help``) builds them all."""

OWN_COMMANDS = ("import", "stats", "export", "backup", "query", "sample", "map")
"""The commands whose parsers :func:`build_parser` adds itself (their modules load when they run)."""


def _lazy(module: str, name: str) -> Callable[[argparse.Namespace, Config], int]:
    """The command function ``name`` of ``adapters.cli.<module>``, imported when the command runs."""

    def command(args: argparse.Namespace, cfg: Config) -> int:
        function: Callable[[argparse.Namespace, Config], int] = getattr(
            importlib.import_module(f"adapters.cli.{module}"), name
        )
        return function(args, cfg)

    return command


def _store_arg(sp: argparse.ArgumentParser) -> None:
    add_store_args(sp)


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The ``twin`` parser: with every command, or with only the parsers of ``only``'s module (see
    :data:`COMMAND_MODULES`) when one is named (what :func:`main` runs)."""
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
    sp.set_defaults(func=_lazy("model_cmds", "cmd_import"))

    sp = sub.add_parser("stats", help="the model's statistics (the paper's Table 1, storeys, classes)")
    _store_arg(sp)
    sp.add_argument("--json", action="store_true", help="print JSON")
    sp.set_defaults(func=_lazy("model_cmds", "cmd_stats"))

    sp = sub.add_parser("export", help="write the graph as Turtle")
    _store_arg(sp)
    sp.add_argument("out", help="the Turtle file to write")
    sp.set_defaults(func=_lazy("model_cmds", "cmd_export"))

    sp = sub.add_parser(
        "backup", help="copy the store into a new directory (consistent, also while the daemon runs)"
    )
    _store_arg(sp)
    sp.add_argument("out", help="the new directory to write the copy to")
    sp.set_defaults(func=_lazy("model_cmds", "cmd_backup"))

    sp = sub.add_parser(
        "query", help="run a read-only SPARQL query (prefixes bot, beo, twin, ... predefined)"
    )
    _store_arg(sp)
    sp.add_argument("sparql", help="the query, or @FILE to read it from a file")
    sp.add_argument("--json", action="store_true", help="print SPARQL JSON results")
    sp.set_defaults(func=_lazy("model_cmds", "cmd_query"))

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
    sp.set_defaults(func=_lazy("model_cmds", "cmd_sample"))

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
    sp.set_defaults(func=_lazy("map_cmd", "cmd_map"))

    for module, commands in COMMAND_MODULES:
        if only is None or only in commands:
            cmd_module = importlib.import_module(f"adapters.cli.{module}")
            add: Callable[[Any], None] = getattr(cmd_module, "add_parsers", None) or cmd_module.add_parser
            add(sub)
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


def command_of(argv: Sequence[str]) -> str | None:
    """The command ``argv`` runs when it is a known one (:data:`OWN_COMMANDS`, :data:`COMMAND_MODULES`);
    None when anything before it is not a global option spelled out (``-h``, ``--version``, an
    abbreviation): every parser then."""
    words = iter(argv)
    for word in words:
        if word == "--config":
            next(words, None)
        elif not (word.startswith("--config=") or word == "--verbose" or re.fullmatch(r"-v+", word)):
            known = {*OWN_COMMANDS, *(name for _, names in COMMAND_MODULES for name in names)}
            return word if word in known else None
    return None


def main(argv: Sequence[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(command_of(argv))
    args = parser.parse_args(argv)
    _merge_global_options(parser, args)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    try:
        from adapters.cli.config_cmd import load  # here: 'twin --help' needs no configuration

        cfg = load(args.config)
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
