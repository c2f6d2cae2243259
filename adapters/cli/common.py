"""What every ``twin`` command shares: the store a command works on, and readable sizes."""

from __future__ import annotations

import argparse
from pathlib import Path

from twin.config import Config


def store_path_of(args: argparse.Namespace, cfg: Config) -> Path:
    """The store directory a command works on: ``--store`` if given, else the configuration's."""
    store = getattr(args, "store", None)
    return Path(store) if store else cfg.store_path


def human_size(n: int) -> str:
    """``1234567`` -> ``"1.2 MB"``."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:,.1f} {unit}"
    return f"{n} B"
