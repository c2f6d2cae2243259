"""Errors of the IFC adapter: re-raised as the core's ModelError so callers catch one type."""

from __future__ import annotations

from twin.errors import ModelError


class IfcFileError(ModelError):
    """The file is missing, not IFC/STEP, truncated, of an unsupported schema, or holds no building."""
