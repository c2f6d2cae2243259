"""Open an IFC file with clear errors for everything that can be wrong with it.

Example::

    f, lines = open_ifc(Path("model.ifc"))
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import ifcopenshell

from adapters.ifc.errors import IfcFileError

log = logging.getLogger(__name__)

SUPPORTED_SCHEMAS = ("IFC2X3", "IFC4", "IFC4X3", "IFC4X3_ADD2")
_CHUNK = 1 << 20
_MAGIC = b"ISO-10303-21;"
_END = b"END-ISO-10303-21;"


def _scan(path: Path) -> tuple[int, bytes, bytes]:
    """``(lines, first KiB, last 4 KiB)`` of the file, read in chunks (never the whole file at once)."""
    lines = 0
    head = b""
    last = b"\n"
    tail = b""
    with path.open("rb") as fh:
        while chunk := fh.read(_CHUNK):
            if not head:
                head = chunk[:1024]
            lines += chunk.count(b"\n")
            last = chunk[-1:]
            tail = (tail + chunk)[-4096:]
    return lines + (0 if last == b"\n" else 1), head, tail


def open_ifc(path: Path) -> tuple[Any, int]:
    """Return ``(ifcopenshell.file, number of lines)``; raise IfcFileError naming the problem."""
    path = Path(path)
    if not path.exists():
        msg = f"No such file: {path}"
        raise IfcFileError(msg)
    if not path.is_file():
        msg = f"Not a file: {path}"
        raise IfcFileError(msg)
    lines, head, tail = _scan(path)
    if not head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(_MAGIC):
        msg = f"{path} is not an IFC/STEP file: it does not start with 'ISO-10303-21;'"
        raise IfcFileError(msg)
    if _END not in tail:
        msg = f"{path} is truncated: it does not end with 'END-ISO-10303-21;'"
        raise IfcFileError(msg)
    try:
        f = ifcopenshell.open(str(path))
    except Exception as err:  # ifcopenshell raises bare Exception/RuntimeError/SchemaError subclasses
        text = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        msg = f"{path} cannot be read as IFC: {text}"
        raise IfcFileError(msg) from err
    schema = str(f.schema).upper()
    if schema not in SUPPORTED_SCHEMAS:
        msg = f"{path} uses schema {f.schema}, supported are {', '.join(SUPPORTED_SCHEMAS)}"
        raise IfcFileError(msg)
    if not f.by_type("IfcElement"):
        msg = f"{path} is an empty model: it holds no IfcElement"
        raise IfcFileError(msg)
    return f, lines
