"""Mesh and placement literals of the graph (FOG / OMG geometry).

A mesh is stored as a binary little-endian PLY file (``fog:asPly_v1.0-binaryLE``) in an
``xsd:base64Binary`` literal: vertices as float64 (exact round trip), faces as int32 triangles.
A placement is a ``twin:Matrix4x4`` literal: 16 numbers, row-major, separated by spaces.

Example::

    text = encode_mesh(mesh)
    again = decode_mesh(text)           # same vertices and faces, bit for bit
"""

from __future__ import annotations

import base64
import binascii
from collections.abc import Sequence

import numpy as np

from twin.errors import ModelError
from twin.records import FloatArray, Mesh, check_placement

_FACE_DTYPE = np.dtype([("n", "u1"), ("v", "<i4", (3,))])


def _header(n_vertices: int, n_faces: int, closed: bool, solid: bool) -> bytes:
    return (
        "ply\nformat binary_little_endian 1.0\n"
        f"comment closed {int(closed)}\n"
        + ("comment solid 1\n" if solid else "")  # only when set: older literals stay byte-identical
        + f"element vertex {n_vertices}\n"
        "property double x\nproperty double y\nproperty double z\n"
        f"element face {n_faces}\n"
        "property list uchar int vertex_indices\n"
        "end_header\n"
    ).encode("ascii")


def encode_mesh(mesh: Mesh) -> str:
    """Encode ``mesh`` as base64 text of a binary little-endian PLY file."""
    faces = np.empty(len(mesh.faces), dtype=_FACE_DTYPE)
    faces["n"] = 3
    faces["v"] = mesh.faces
    body = (
        _header(len(mesh.vertices), len(mesh.faces), mesh.closed, mesh.solid)
        + np.ascontiguousarray(mesh.vertices, dtype="<f8").tobytes()
        + faces.tobytes()
    )
    return base64.b64encode(body).decode("ascii")


def decode_mesh(text: str) -> Mesh:
    """Decode :func:`encode_mesh` output; raise ModelError naming what is wrong."""
    try:
        raw = base64.b64decode(text, validate=True)
    except (binascii.Error, ValueError) as err:
        msg = f"Mesh literal is not valid base64: {err}."
        raise ModelError(msg) from err
    end = raw.find(b"end_header\n")
    if not raw.startswith(b"ply\n") or end < 0:
        msg = "Mesh literal is not a PLY file (no 'ply' magic or no 'end_header')."
        raise ModelError(msg)
    header = raw[:end].decode("ascii", errors="replace").splitlines()
    counts: dict[str, int] = {}
    closed = solid = False
    for line in header:
        parts = line.split()
        if parts[:1] == ["element"] and len(parts) == 3:
            counts[parts[1]] = int(parts[2])
        elif parts[:2] == ["comment", "closed"] and len(parts) == 3:
            closed = parts[2] == "1"
        elif parts[:2] == ["comment", "solid"] and len(parts) == 3:
            solid = parts[2] == "1"
    if "binary_little_endian" not in raw[:end].decode("ascii", errors="replace"):
        msg = "Mesh literal must be a binary_little_endian PLY."
        raise ModelError(msg)
    nv, nf = counts.get("vertex", -1), counts.get("face", -1)
    if nv < 0 or nf < 0:
        msg = f"Mesh literal PLY header lacks vertex or face counts: {header!r}."
        raise ModelError(msg)
    start = end + len(b"end_header\n")
    need = nv * 24 + nf * _FACE_DTYPE.itemsize
    if len(raw) - start != need:
        msg = (
            f"Mesh literal body has {len(raw) - start} bytes, expected {need} for {nv} vertices, {nf} faces."
        )
        raise ModelError(msg)
    vertices = np.frombuffer(raw, dtype="<f8", count=nv * 3, offset=start).reshape(nv, 3).astype(np.float64)
    faces_rec = np.frombuffer(raw, dtype=_FACE_DTYPE, count=nf, offset=start + nv * 24)
    if nf and not (faces_rec["n"] == 3).all():
        msg = "Mesh literal has faces that are not triangles."
        raise ModelError(msg)
    return Mesh(vertices, faces_rec["v"].astype(np.int32), closed, solid)


def encode_placement(matrix: FloatArray) -> str:
    """A 4x4 matrix as 16 space-separated numbers, row-major, shortest exact repr."""
    m = check_placement(matrix)
    return " ".join(map(repr, m.ravel().tolist()))  # tolist: Python floats, as repr(float(x))


def encode_placements(matrices: Sequence[FloatArray]) -> list[str]:
    """:func:`encode_placement` of each matrix, checked and formatted all at once: the same texts, and
    the same error for the first matrix that is not a placement."""
    try:
        m = np.stack([np.asarray(x, dtype=np.float64) for x in matrices]) if matrices else np.empty((0, 4, 4))
    except ValueError:  # matrices of different shapes: one by one names the first bad one
        return [encode_placement(x) for x in matrices]
    if m.shape[1:] != (4, 4):
        return [encode_placement(x) for x in matrices]
    last = np.abs(m[:, 3, 0]) + np.abs(m[:, 3, 1]) + np.abs(m[:, 3, 2]) + np.abs(m[:, 3, 3] - 1.0)
    if not (np.isfinite(m).all(axis=(1, 2)) & ~(last > 1e-9)).all():
        return [encode_placement(x) for x in matrices]
    return [" ".join(map(repr, row)) for row in m.reshape(len(m), 16).tolist()]


def decode_placement(text: str) -> FloatArray:
    """Inverse of :func:`encode_placement`; raise ModelError naming the bad literal."""
    try:
        values = [float(x) for x in text.split()]
    except ValueError as err:
        msg = f"Placement literal is not 16 numbers: {text[:80]!r}."
        raise ModelError(msg) from err
    if len(values) != 16:
        msg = f"Placement literal must hold 16 numbers, got {len(values)}."
        raise ModelError(msg)
    return check_placement(np.array(values).reshape(4, 4))
