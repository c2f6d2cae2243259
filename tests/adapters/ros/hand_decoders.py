"""What the tests of the hand decoders (``Detection3DArray``, ``TFMessage``) share: values compared bit
for bit, a message's bytes damaged as hostile input would be, and the check that the hand decoder
accepts nothing the reference refuses."""

from __future__ import annotations

import dataclasses
import struct
from collections.abc import Callable
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


def accepts_nothing_refused(
    payload: bytes,
    fast: Callable[[bytes], Any],
    reference: Callable[[bytes], Any],
    refused: type[Exception],
) -> None:
    """Assert that ``fast`` (None: left to the reference) accepts ``payload`` only if ``reference``
    does (it raises ``refused`` otherwise), and then decodes it to the same bits."""
    got = fast(payload)
    try:
        expected = reference(payload)
    except refused:
        expected = None
    if got is not None:
        assert expected is not None, "the hand decoder accepted what rosbags refuses"
        assert bits(got) == bits(expected)
