"""``twin config schema``: the JSON Schema of ``config/*.toml``, and the sections every command loads.

The core validates its own tables; each adapter owns the table it reads. This module is where the
two meet: :data:`SECTIONS` lists the adapters' tables, so that ``twin`` checks the whole file at once
(an unknown table or key is an error naming it) and the schema covers every table.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from adapters.cli.serve_settings import ServeSettings
from adapters.rerun.settings import RerunSettings
from adapters.ros.settings import ROS_SECTIONS
from adapters.sparql.settings import RemoteStoreSettings
from adapters.zenoh.settings import ZenohSettings
from twin.config import Config, ConfigSection, config_schema, load_config

SECTIONS: tuple[type[ConfigSection], ...] = (
    ZenohSettings, RerunSettings, RemoteStoreSettings, ServeSettings, *ROS_SECTIONS
)  # fmt: skip
"""The adapters' tables: ``[zenoh]``, ``[rerun]``, ``[serve]``, the remote store's keys of ``[store]``,
``[ros]`` and the ROS 2 keys of every ``[robots.NAME]`` and ``[sources.NAME]``."""


def load(path: Path | None = None) -> Config:
    """The configuration as every ``twin`` command sees it: the core's tables and every section."""
    return load_config(path, sections=SECTIONS)


def schema_text() -> str:
    """The JSON Schema, as committed in ``config/schema.json``."""
    return json.dumps(config_schema(SECTIONS), indent=2) + "\n"


def add_parsers(sub: Any) -> None:
    sp = sub.add_parser("config", help="the configuration's JSON Schema (for editors)")
    what = sp.add_subparsers(dest="config_command", required=True, metavar="WHAT")
    schema = what.add_parser(
        "schema", help="write the JSON Schema of config/*.toml (Taplo, Even Better TOML: '#:schema FILE')"
    )
    schema.add_argument("--out", type=Path, help="the file to write (default: standard output)")
    schema.set_defaults(func=cmd_schema)


def cmd_schema(args: argparse.Namespace, cfg: Config) -> int:
    text = schema_text()
    if args.out is None:
        sys.stdout.write(text)
    else:
        args.out.write_text(text)
        print(f"wrote {args.out}")
    return 0
