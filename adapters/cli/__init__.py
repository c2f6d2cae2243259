"""The ``twin`` command line: the composition root (builds the store, the service, the Zenoh session
and the recorder, and wires them). Nothing imports this package."""

from __future__ import annotations

from adapters.cli.app import main

__all__ = ["main"]
