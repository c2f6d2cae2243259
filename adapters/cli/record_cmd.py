"""``twin record``: write the current twin (building and every skill map) as a Rerun recording,
without running the daemon."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from adapters.cli.common import add_store_args, human_size, open_store
from twin.config import Config
from twin.live import TwinService


def cmd_record(args: argparse.Namespace, cfg: Config) -> int:
    out = Path(args.out)
    from adapters.rerun import RerunRecorder  # here: importing Rerun costs every other command 0.3 s

    recorder = RerunRecorder(path=out, application=f"twin {cfg.site}")
    try:
        with open_store(args, cfg, read_only=True) as store:
            service = TwinService(store, cfg, sinks=[recorder])
            service.start()
            maps = len(service.published_maps())
    finally:
        recorder.close()
    print(
        f"wrote {out} ({human_size(out.stat().st_size)}): the building and {maps} maps; replay: rerun {out}"
    )
    return 0


def add_parser(sub: Any) -> None:
    sp = sub.add_parser("record", help="write the twin (building and every map) as a Rerun recording")
    add_store_args(sp)
    sp.add_argument("out", help="the .rrd file to write")
    sp.set_defaults(func=cmd_record)
