"""Validation errors as one :class:`~twin.errors.ConfigError` that names each offending key the way
the file spells it: ``[zenoh] listen: expected a list of endpoints, got 5``,
``[rerun] rotate_evry_s: unknown key (did you mean rotate_every_s?)``."""

from __future__ import annotations

import difflib
import types
from collections.abc import Mapping, Sequence
from typing import Annotated, Any, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError
from pydantic_core import ErrorDetails

from twin.errors import ConfigError

_EXPECTED = {
    "bool_type": "true or false",
    "int_type": "an integer",
    "int_from_float": "an integer",
    "float_type": "a number",
    "finite_number": "a finite number",
    "string_type": "a string",
    "list_type": "a list",
    "tuple_type": "a list",
    "set_type": "a list",
    "frozen_set_type": "a list",
    "dict_type": "a table",
    "model_type": "a table",
    "model_attributes_type": "a table",
}
_BOUNDS = {"greater_than": ">", "greater_than_equal": ">=", "less_than": "<", "less_than_equal": "<="}
_BOUND_KEYS = {"greater_than": "gt", "greater_than_equal": "ge", "less_than": "lt", "less_than_equal": "le"}


def config_error(err: ValidationError, root: type[BaseModel]) -> ConfigError:
    """One error for every problem pydantic found, each naming its table and key."""
    problems = [_describe(e, root) for e in err.errors(include_url=False)]
    return ConfigError("Configuration " + "; ".join(problems) + ".")


def _describe(e: ErrorDetails, root: type[BaseModel]) -> str:
    loc, kind, value = tuple(e["loc"]), e["type"], e.get("input")
    if kind == "extra_forbidden":
        return _unknown(loc, root)
    if loc and loc[-1] == "[key]":  # a table's key (a robot's name) is itself wrong
        return f"[{_dotted(loc[:-2])}] name {loc[-2]!r}: {_problem(e, value)}"
    if kind not in _EXPECTED and _table_at(root, loc) is not None:  # a check of the whole table
        return f"[{_dotted(loc)}]: {_problem(e, value)}"
    if kind == "missing":
        return f"{_place(loc)}: is required"
    return f"{_place(loc)}: {_problem(e, value)}"


def _problem(e: ErrorDetails, value: Any) -> str:
    kind, ctx = e["type"], e.get("ctx") or {}
    if kind in ("value_error", "assertion_error") and "error" in ctx:
        return str(ctx["error"])  # our own checks say what they expected and what they got
    if kind in _EXPECTED:
        expected = _EXPECTED[kind]
    elif kind in _BOUNDS:
        expected = f"a number {_BOUNDS[kind]} {ctx[_BOUND_KEYS[kind]]}"
    elif kind == "literal_error":
        expected = str(ctx["expected"])
    elif kind == "string_pattern_mismatch":
        expected = f"a string matching {ctx['pattern']}"
    elif kind == "too_short":
        expected = f"at least {ctx['min_length']} item(s)"
    else:
        return f"{e['msg'][:1].lower()}{e['msg'][1:]}, got {value!r}"
    return f"expected {expected}, got {value!r}"


def _unknown(loc: tuple[Any, ...], root: type[BaseModel]) -> str:
    table, key = loc[:-1], str(loc[-1])
    model = _table_at(root, table)
    known = sorted(f.alias or name for name, f in model.model_fields.items()) if model is not None else []
    close = difflib.get_close_matches(key, known, n=1)
    hint = f" (did you mean {close[0]}?)" if close else f" (known: {', '.join(known)})" if known else ""
    if not table:
        return f"[{key}]: unknown table{hint}"
    return f"[{_dotted(table)}] {key}: unknown key{hint}"


def _dotted(parts: Sequence[Any]) -> str:
    return ".".join(str(p) for p in parts)


def _place(loc: tuple[Any, ...]) -> str:
    """``("zenoh", "listen", 0)`` -> ``[zenoh] listen[0]``; a top-level key has no table."""
    names: list[str] = []
    for part in loc:
        if isinstance(part, int) and names:
            names[-1] += f"[{part}]"
        else:
            names.append(str(part))
    if len(names) == 1:
        return f"[{names[0]}]"
    return f"[{'.'.join(names[:-1])}] {names[-1]}"


def _table_at(root: type[BaseModel], loc: Sequence[Any]) -> type[BaseModel] | None:
    """The table model at ``loc`` of the file model, or None where ``loc`` is not a table."""
    node: Any = root
    for part in loc:
        if isinstance(node, type) and issubclass(node, BaseModel):
            fields = {f.alias or name: f for name, f in node.model_fields.items()}
            if part not in fields:
                return None
            node = _bare(fields[part].annotation)
        elif get_origin(node) in (dict, Mapping):
            node = _bare(get_args(node)[1])
        else:
            return None
    return node if isinstance(node, type) and issubclass(node, BaseModel) else None


def _bare(annotation: Any) -> Any:
    """``Annotated[X, ...]`` and ``X | None`` -> ``X``."""
    while True:
        origin = get_origin(annotation)
        if origin is Annotated:
            annotation = get_args(annotation)[0]
        elif origin in (Union, types.UnionType):
            args = [a for a in get_args(annotation) if a is not type(None)]
            if len(args) != 1:
                return annotation
            annotation = args[0]
        else:
            return annotation
