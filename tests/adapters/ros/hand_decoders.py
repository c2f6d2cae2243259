"""What the tests of the hand decoders (``Detection3DArray``, ``TFMessage``) share: values compared bit
for bit, and a message's bytes damaged as hostile input would be."""

from __future__ import annotations

import dataclasses
import struct
from typing import Any


def bits(value: Any) -> Any:
    """``value`` with every float as its 8 bytes (NaN's sign and payload compared too)."""
    if isinstance(value, float):
        return struct.pack("<d", value)
    if isinstance(value, tuple) and hasattr(value, "_fields"):  # a named tuple: its fields
        return tuple(bits(v) for v in value)
    if isinstance(value, tuple | list):
        return type(value)(bits(v) for v in value)
    if dataclasses.is_dataclass(value):
        return tuple(bits(getattr(value, f.name)) for f in dataclasses.fields(value))
    return value


def mutated(payload: bytes, cut: int, flips: list[tuple[int, int]], tail: bytes) -> bytes:
    """``payload`` with the bytes at ``flips``' positions set to their values, cut after ``cut`` bytes
    (if shorter) and ``tail`` appended."""
    raw = bytearray(payload)
    for at, value in flips:
        if at < len(raw):
            raw[at] = value
    return bytes(raw[: max(cut, 0)]) + tail if cut < len(raw) else bytes(raw) + tail
