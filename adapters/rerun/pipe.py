"""The pipe between the recorder sink and the recorder process: length-prefixed pickled messages."""

from __future__ import annotations

import pickle
from typing import IO, Any

HEADER = 8
"""Bytes of the little-endian length that precedes each message."""


def read_message(stream: IO[bytes]) -> Any:
    """The next message on ``stream``, or None at its end."""
    header = stream.read(HEADER)
    if len(header) < HEADER:
        return None
    return pickle.loads(stream.read(int.from_bytes(header, "little")))


def write_message(stream: IO[bytes], message: object) -> None:
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(len(data).to_bytes(HEADER, "little"))
    stream.write(data)
