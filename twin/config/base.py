"""What every table of the configuration shares: a frozen schema that refuses unknown keys, and the
value types TOML files use (flags, whole numbers, finite numbers, strings, lists, paths), strict so
that ``1`` is not taken for ``true`` nor ``"5"`` for ``5``.

A table is a pydantic model: its fields are the table's keys, with their types, bounds, defaults and
descriptions in one place; the JSON Schema of ``config/*.toml`` is generated from them. The core's
tables live in :mod:`twin.config.tables`; an adapter's table is a :class:`ConfigSection` in that
adapter (``adapters/zenoh/settings.py`` for ``[zenoh]``), so that the core knows no transport.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, ClassVar

from pydantic import AllowInfNan, BaseModel, BeforeValidator, ConfigDict, Strict, WithJsonSchema

Flag = Annotated[bool, Strict()]
"""``true`` or ``false`` (not 0 or 1)."""
Whole = Annotated[int, Strict()]
"""An integer (not a float, not a flag)."""
Number = Annotated[float, Strict(), AllowInfNan(False)]
"""A finite number, integer or float (not ``inf``, ``nan`` or a string)."""
Text = Annotated[str, Strict()]


class ConfigTable(BaseModel):
    """A table of the configuration file: its keys, types, bounds and defaults. Unknown keys are
    errors; instances are immutable."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class ConfigSection(ConfigTable):
    """A top-level table that an adapter owns and reads (e.g. ``[zenoh]``, ``[rerun]``).

    ``table`` is its name in the file. A section may add keys to a table of the core (the remote
    store's keys sit in ``[store]`` beside the embedded store's ``path``): the core's keys stay the
    core's, the others are the section's, and a key that neither knows is an error. A key that both
    declare is the core's, which the section reads too (a robot's ``storey``). With ``each``, the
    section's keys sit in every ``[<table>.NAME]`` instead (the ROS keys of ``[robots.NAME]``). The
    composition root hands its sections to :func:`twin.config.load_config`; adapters read theirs with
    :meth:`twin.config.Config.section` (``each``: :meth:`twin.config.Config.each`).
    """

    table: ClassVar[str]
    each: ClassVar[bool] = False
    """True: keys of every ``[<table>.NAME]`` (a table of the core that holds one table per name)."""


def _path(value: Any) -> Path:
    if isinstance(value, Path):
        return value
    if not isinstance(value, str) or not value:
        msg = f"expected a path, got {value!r}"
        raise ValueError(msg)
    return Path(value)


def _optional_path(value: Any) -> Path | None:
    """An optional path: ``""`` (TOML has no null) means none."""
    return None if value is None or value == "" else _path(value)


def _optional_text(value: Any) -> str | None:
    if value is None or value == "":
        return None
    if not isinstance(value, str):
        msg = f"expected a string, got {value!r}"
        raise ValueError(msg)
    return value


PathSetting = Annotated[Path, BeforeValidator(_path), WithJsonSchema({"type": "string", "minLength": 1})]
"""A path; relative paths are relative to the working directory."""
OptionalPath = Annotated[Path | None, BeforeValidator(_optional_path), WithJsonSchema({"type": "string"})]
"""A path, or ``""`` for none."""
OptionalText = Annotated[str | None, BeforeValidator(_optional_text), WithJsonSchema({"type": "string"})]
"""A string, or ``""`` for none."""


def list_of(what: str) -> BeforeValidator:
    """Refuse anything but a TOML array before its items are checked, naming what the list holds:
    ``expected a list of endpoints, got 5``."""

    def check(value: Any) -> Any:
        if not isinstance(value, list | tuple):
            msg = f"expected a list of {what}, got {value!r}"
            raise ValueError(msg)
        return value

    return BeforeValidator(check)


def check(test: Callable[[Any], bool], expected: str) -> BeforeValidator:
    """A check of one value, refusing it as ``expected <expected>, got <value>``."""

    def run(value: Any) -> Any:
        if not test(value):
            msg = f"expected {expected}, got {value!r}"
            raise ValueError(msg)
        return value

    return BeforeValidator(run)
