"""Little-endian CDR read by hand: what the hand decoders of fixed-layout messages share
(``Detection3DArray`` in :mod:`adapters.ros.detections`, ``TFMessage`` in :mod:`adapters.ros.tf`).

rosbags decodes any message, but builds a Python object per field; the hot messages (a robot's arrays
and TF, many a second) are read with :mod:`struct` instead, and anything unusual (another encoding, a
length that does not fit, trailing bytes) goes back to rosbags, so both refuse the same messages.

Example::

    data = body(payload)            # None: not little-endian CDR, let rosbags decide
    frame, pos = read_string(data, 8)
    pos = padded(pos, 4)
"""

from __future__ import annotations

import struct

U32 = struct.Struct("<I")
TIME = struct.Struct("<iI")
"""``builtin_interfaces/msg/Time``: sec (int32), nanosec (uint32)."""
MAX_PADDING = 3
"""Bytes rosbags allows after a message's last field."""


def body(payload: bytes | bytearray | memoryview) -> bytes | None:
    """The message's bytes after the encapsulation header when ``payload`` is little-endian CDR (header
    ``00 01``), else None."""
    if not isinstance(payload, bytes | bytearray | memoryview) or bytes(payload[:2]) != b"\x00\x01":
        return None
    return bytes(payload[4:])


def read_string(data: bytes, pos: int) -> tuple[str, int]:
    """The CDR string at ``pos`` (aligned to 4 first) and the position after it; ValueError when its
    length does not fit, it has no terminator or is empty (UnicodeDecodeError if not UTF-8)."""
    pos += -pos % 4
    (n,) = U32.unpack_from(data, pos)
    stop = pos + 4 + n
    if n < 1 or stop > len(data) or data[stop - 1] != 0:
        raise ValueError
    return data[pos + 4 : stop - 1].decode(), stop


def ends_at(pos: int, data: bytes) -> bool:
    """Whether a message read up to ``pos`` is the whole of ``data`` (at most :data:`MAX_PADDING` bytes
    after it, as rosbags allows)."""
    return pos <= len(data) <= pos + MAX_PADDING
