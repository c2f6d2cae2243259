"""``twin record``: write the current twin (building and every skill map) as a Rerun recording,
without running the daemon; or, with ``--from``, cut a revision or time range out of the daemon's
recordings into a file that replays alone."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from adapters.cli.common import add_store_args, human_size, open_store
from twin.config import Config
from twin.errors import ConfigError


def _revisions(text: str) -> tuple[int | None, int | None]:
    """``A:B``, ``A:`` or ``:B`` as a revision range (both ends included)."""
    first, sep, last = text.partition(":")
    try:
        if not sep:
            raise ValueError(text)
        return (int(first) if first else None, int(last) if last else None)
    except ValueError:
        msg = f"--revisions takes FIRST:LAST (either may be left out), got {text!r}."
        raise ConfigError(msg) from None


def _instant(text: str | None) -> int | None:
    """An ISO 8601 UTC time (``2026-11-25T08:00:00``) as ns since the epoch."""
    if text is None:
        return None
    try:
        return int(np.datetime64(text.removesuffix("Z"), "ns").astype(np.int64))
    except ValueError:
        msg = f"--since/--until take an ISO 8601 UTC time such as 2026-11-25T08:00:00, got {text!r}."
        raise ConfigError(msg) from None


def cmd_cut(args: argparse.Namespace, cfg: Config) -> int:
    from adapters.rerun.cut import cut

    out = Path(args.out)
    sources = [Path(p) for p in args.sources]
    if out.resolve() in {s.resolve() for s in sources}:
        msg = f"The cut would overwrite its source {out}."
        raise ConfigError(msg)
    if args.revisions and (args.since or args.until):
        msg = "Cut either --revisions or --since/--until, not both."
        raise ConfigError(msg)
    if args.revisions:
        start, end = _revisions(args.revisions)
        timeline = "revision"
    else:
        start, end = _instant(args.since), _instant(args.until)
        timeline = "time"
    if start is not None and end is not None and end < start:
        msg = f"The range to cut ends ({end}) before it starts ({start})."
        raise ConfigError(msg)
    summary = cut(sources, out, timeline=timeline, start=start, end=end, application=f"twin {cfg.site}")
    if summary.range_rows == 0:
        out.unlink(missing_ok=True)
        wanted = args.revisions or f"{args.since or '...'} to {args.until or '...'}"
        held = (
            f"{_show(summary.first, timeline)} to {_show(summary.last, timeline)}"
            if summary.first is not None and summary.last is not None
            else "nothing"
        )
        msg = (
            f"Nothing to cut: {', '.join(map(str, sources))} hold {timeline}s {held}, none in {wanted} "
            "(no file written)."
        )
        raise ConfigError(msg)
    print(
        f"wrote {out} ({human_size(out.stat().st_size)}): the building, the state at the start "
        f"({summary.state_rows} rows) and {summary.range_rows} rows of the range; replay: rerun {out}"
    )
    return 0


def _show(value: int | None, timeline: str) -> str:
    if value is None or timeline != "time":
        return str(value)
    return str(np.datetime64(value, "ns").astype("datetime64[s]")) + "Z"


def _output_of(args: argparse.Namespace) -> None:
    """``twin record --from A.rrd OUT.rrd``: ``--from`` took every file, the last is the output (as
    ``cp`` reads it) unless it exists (then which is meant cannot be told: refused)."""
    if args.out is not None:
        return
    if not args.sources or len(args.sources) < 2:
        msg = "Give the .rrd file to write: twin record OUT.rrd [--from FILE.rrd ...]."
        raise ConfigError(msg)
    *sources, out = args.sources
    if Path(out).exists():
        msg = (
            f"Which file is the output? {out} exists (a recording to cut?): give it first, "
            f"twin record OUT.rrd --from {' '.join(args.sources)}."
        )
        raise ConfigError(msg)
    args.sources, args.out = sources, out


def cmd_record(args: argparse.Namespace, cfg: Config) -> int:
    _output_of(args)
    if args.sources:
        return cmd_cut(args, cfg)
    if args.revisions or args.since or args.until:
        msg = (
            "--revisions, --since and --until cut the daemon's recordings: name them with --from FILE.rrd "
            "(e.g. var/recordings/lab-*.rrd)."
        )
        raise ConfigError(msg)
    from adapters.rerun import RerunRecorder  # here: importing Rerun costs every other command 0.3 s
    from twin.live import TwinService

    out = Path(args.out)

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
    sp = sub.add_parser(
        "record",
        help="write the twin (building and every map) as a Rerun recording, or cut a range of recordings",
    )
    add_store_args(sp)
    sp.add_argument(
        "out", nargs="?", help="the .rrd file to write (after --from's files, the last name is the output)"
    )
    cut = sp.add_argument_group("cut a range of the daemon's recordings (instead of the store)")
    cut.add_argument(
        "--from", dest="sources", nargs="+", metavar="FILE.rrd", help="recordings, in order (rotated files)"
    )
    cut.add_argument("--revisions", metavar="FIRST:LAST", help="the revision range to keep (ends included)")
    cut.add_argument("--since", metavar="TIME", help="keep from this UTC time on (ISO 8601)")
    cut.add_argument("--until", metavar="TIME", help="keep up to this UTC time (ISO 8601)")
    sp.set_defaults(func=cmd_record)
