"""``[rerun]``: where ``twin serve`` records the twin's history. The Rerun adapter owns this table."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

from pydantic import Field

from twin.config import ConfigSection
from twin.config.base import Flag, Number, OptionalText, PathSetting, Whole, check

MIN_FILE_BYTES = 2**20


class RerunSettings(ConfigSection):
    """``[rerun]``: record to ``<directory>/<site>-<start time>.rrd`` files, and/or stream to a viewer."""

    table = "rerun"

    record: Flag = Field(True, description="Record each 'twin serve' run unless --no-record.")
    directory: PathSetting = Path("var/recordings")
    connect_url: OptionalText = Field(
        None, description='Also stream to a viewer, e.g. "rerun+http://127.0.0.1:9876/proxy"; "" = none.'
    )
    rotate_every_s: Annotated[Number, Field(ge=0.0, le=7 * 86400.0)] = Field(
        0.0, description="Start a new file this often, seconds (0: never); each file replays on its own."
    )
    max_bytes: Annotated[
        Whole,
        check(
            lambda v: not isinstance(v, int) or v == 0 or v >= MIN_FILE_BYTES,
            f"0 (no limit) or >= {MIN_FILE_BYTES}",
        ),
    ] = Field(0, description="Start a new file once the current one is this big (0: no limit).")
