"""A snapshot file: named numpy arrays and a JSON header, checksummed, written atomically.

The daemon keeps its derived state (the decoded scene and every map, see
:mod:`twin.live.snapshots`) in one such file next to the store, so that a restart reads a few
megabytes instead of decoding every mesh and rendering every map. Nothing in it is trusted blindly:
the whole file is covered by a SHA-256 digest checked before anything is read, and the header
carries the keys (the store's identity and revision, the skill profiles, the configuration) that the
caller compares with the live store before using it.

Layout: ``MAGIC`` (8 bytes), the header's length (8 bytes, little-endian), the header (UTF-8 JSON),
the arrays one after the other (each zlib-compressed; booleans bit-packed first), then the SHA-256
of everything before it (32 bytes). Only plain numeric and boolean dtypes are stored: no pickle.

Example::

    write_snapshot(path, {"revision": 7}, {"static": grid})
    header, arrays = read_snapshot(path)          # SnapshotError if missing, damaged or foreign
"""

from __future__ import annotations

import hashlib
import json
import os
import struct
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from twin.errors import SnapshotError

MAGIC = b"TWINSNAP"
FORMAT_VERSION = 3
"""Bump when what a snapshot holds, or how it is laid out, changes: older files are then rebuilt. (2: the
points maps' points computed more directly where a voxel's column lies inside a triangle, a last-bit
difference from 1's; 3: the points maps' rows hold each point's normal.)"""
_DTYPES = frozenset({"bool", "int8", "uint8", "int32", "int64", "float32", "float64"})
_LEVEL = 1  # zlib: fast; maps and mesh pools compress well even so

AnyArray = npt.NDArray[Any]


def write_snapshot(path: Path, header: Mapping[str, Any], arrays: Mapping[str, AnyArray]) -> int:
    """Write ``header`` (JSON-serialisable) and ``arrays`` to ``path`` atomically (a temporary file in
    the same directory, fsynced, then renamed over ``path``). Returns the file's size in bytes."""
    blobs: list[bytes] = []
    index: list[dict[str, Any]] = []
    offset = 0
    for name, array in arrays.items():
        a = np.ascontiguousarray(array)
        if a.dtype.name not in _DTYPES:
            msg = f"Snapshot array {name!r} has dtype {a.dtype}; only {sorted(_DTYPES)} are stored."
            raise SnapshotError(msg)
        if a.dtype == np.bool_:
            raw = np.packbits(a.ravel()).tobytes()
        else:
            raw = a.astype(a.dtype.newbyteorder("<")).tobytes()
        blob = zlib.compress(raw, _LEVEL)
        entry = {"name": name, "dtype": a.dtype.name, "shape": list(a.shape), "offset": offset}
        index.append({**entry, "size": len(blob)})
        blobs.append(blob)
        offset += len(blob)
    head = json.dumps({**header, "format_version": FORMAT_VERSION, "arrays": index}).encode()
    digest = hashlib.sha256()
    parts = [MAGIC, struct.pack("<Q", len(head)), head, *blobs]
    for part in parts:
        digest.update(part)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    for stale in path.parent.glob(f".{path.name}.*.tmp"):  # left by a process killed while writing
        stale.unlink(missing_ok=True)
    try:
        with tmp.open("wb") as f:
            for part in parts:
                f.write(part)
            f.write(digest.digest())
            f.flush()
            os.fsync(f.fileno())
        tmp.replace(path)
    except OSError as err:
        tmp.unlink(missing_ok=True)
        msg = f"Could not write the snapshot {path}: {err}."
        raise SnapshotError(msg) from err
    return sum(len(p) for p in parts) + digest.digest_size


def read_snapshot(path: Path) -> tuple[dict[str, Any], dict[str, AnyArray]]:
    """The header and arrays of the snapshot at ``path``; SnapshotError names what is wrong (missing,
    truncated, damaged, another format version), and nothing of a damaged file is returned."""
    try:
        data = path.read_bytes()
    except OSError as err:
        msg = f"No snapshot at {path}: {err.strerror or err}."
        raise SnapshotError(msg) from err
    if len(data) < len(MAGIC) + 8 + 32 or not data.startswith(MAGIC):
        msg = f"The snapshot {path} is not a snapshot file or is truncated ({len(data)} bytes)."
        raise SnapshotError(msg)
    body, stored = memoryview(data)[:-32], data[-32:]
    if hashlib.sha256(body).digest() != stored:
        msg = f"The snapshot {path} is damaged: its SHA-256 checksum does not match its contents."
        raise SnapshotError(msg)
    (n,) = struct.unpack_from("<Q", data, len(MAGIC))
    start = len(MAGIC) + 8
    try:
        header = json.loads(bytes(body[start : start + n]))
    except ValueError as err:
        msg = f"The snapshot {path} has an unreadable header: {err}."
        raise SnapshotError(msg) from err
    if not isinstance(header, dict) or header.get("format_version") != FORMAT_VERSION:
        got = header.get("format_version") if isinstance(header, dict) else None
        msg = f"The snapshot {path} is format version {got!r}; this daemon reads version {FORMAT_VERSION}."
        raise SnapshotError(msg)
    arrays: dict[str, AnyArray] = {}
    payload = start + n
    try:
        for entry in header.pop("arrays"):
            name, dtype = str(entry["name"]), str(entry["dtype"])
            shape = tuple(int(s) for s in entry["shape"])
            if dtype not in _DTYPES:
                msg = f"The snapshot {path} holds array {name!r} of dtype {dtype!r}."
                raise SnapshotError(msg)
            at = payload + int(entry["offset"])
            raw = zlib.decompress(body[at : at + int(entry["size"])])
            count = int(np.prod(shape))
            if dtype == "bool":
                flat = np.unpackbits(np.frombuffer(raw, dtype=np.uint8), count=count).astype(np.bool_)
            else:
                flat = np.frombuffer(raw, dtype=np.dtype(dtype).newbyteorder("<"), count=count).astype(dtype)
            arrays[name] = flat.reshape(shape)
    except (KeyError, TypeError, ValueError, zlib.error) as err:
        msg = f"The snapshot {path} has an inconsistent array index: {err}."
        raise SnapshotError(msg) from err
    return header, arrays
