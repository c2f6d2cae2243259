"""Sense times as observations write them: an ``xsd:dateTime`` read to the nanosecond."""

from __future__ import annotations

import datetime
import re

_FRACTION = re.compile(r"(\.\d{6})\d+")


def sense_time_ns(text: str) -> int:
    """An ``xsd:dateTime`` as nanoseconds since the epoch (no zone: UTC); ValueError if it is none."""
    value = text.strip()
    if value.endswith(("Z", "z")):
        value = value[:-1] + "+00:00"
    nanos = 0
    m = _FRACTION.search(value)
    if m is not None:  # Python keeps microseconds: the digits past them are added back as ns
        extra = m.group(0)[7:]
        nanos = int((extra + "000")[:3]) if extra else 0
        value = value[: m.start()] + m.group(1) + value[m.end() :]
    moment = datetime.datetime.fromisoformat(value)
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=datetime.UTC)
    whole = moment.replace(microsecond=0)
    return int(whole.timestamp()) * 1_000_000_000 + moment.microsecond * 1000 + nanos
