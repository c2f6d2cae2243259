"""IFC element classes and their supertypes, per schema (IFC2X3, IFC4, IFC4X3), without ifcopenshell.

Robots name the class of what they observe (``IfcFurniture``); the twin gives the new element its
supertypes like an imported one (``IfcFurniture`` is an ``IfcFurnishingElement``), so skill filters
select it the same way. The table (``ifc_classes.json``) lists every subtype of ``IfcElement`` and is
checked against ifcopenshell's schemas by the test suite.

Example::

    supertypes("IFC4", "IfcFurniture")   # ("IfcFurniture", "IfcFurnishingElement", "IfcElement", ...)
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

_TABLE = Path(__file__).resolve().parent / "ifc_classes.json"
SCHEMAS = ("IFC2X3", "IFC4", "IFC4X3")


@functools.cache
def _table() -> dict[str, dict[str, tuple[str, ...]]]:
    raw = json.loads(_TABLE.read_text())
    return {schema: {k: tuple(v) for k, v in classes.items()} for schema, classes in raw.items()}


def schema_family(schema: str) -> str:
    """``"IFC4X3_ADD2"`` -> ``"IFC4X3"``; unknown schemas fall back to IFC4."""
    upper = schema.upper()
    for s in ("IFC4X3", "IFC2X3", "IFC4"):
        if upper.startswith(s):
            return s
    return "IFC4"


def supertypes(schema: str, ifc_class: str) -> tuple[str, ...] | None:
    """``ifc_class`` and its supertypes, most specific first; None if it is no ``IfcElement`` subtype.

    The model's ``schema`` is asked first, then the other schemas (newest first), so a robot may name
    ``IfcFurniture`` in an IFC2X3 building. Names match case-insensitively and come back in the
    schema's spelling.
    """
    family = schema_family(schema)
    for name in (family, *(s for s in ("IFC4X3", "IFC4", "IFC2X3") if s != family)):
        classes = _table()[name]
        chain = classes.get(ifc_class)
        if chain is None:
            chain = {k.lower(): v for k, v in classes.items()}.get(ifc_class.lower())
        if chain is not None:
            return chain
    return None


def element_classes(schema: str) -> tuple[str, ...]:
    """Every ``IfcElement`` subtype of ``schema``, sorted."""
    return tuple(sorted(_table()[schema_family(schema)]))
