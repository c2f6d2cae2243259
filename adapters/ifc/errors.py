"""Errors of the IFC adapter: re-raised as the core's ModelError so callers catch one type."""

from __future__ import annotations

from twin.errors import ModelError


class IfcFileError(ModelError):
    """The file is missing, not IFC/STEP, truncated, of an unsupported schema, or holds no building."""


ENTITY_ERRORS = (RuntimeError, AttributeError, TypeError, ValueError, AssertionError, IndexError, KeyError)
"""What reading a malformed entity raises: ifcopenshell parses lazily (RuntimeError wherever a corrupt
entity is first read), and an attribute of the wrong type or a reference read as empty (None) fails
in whatever uses it."""
