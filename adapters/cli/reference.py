"""The documentation's reference pages, generated so that they cannot drift: the CLI reference from
``twin``'s argument parser and the configuration reference from the JSON Schema of ``config/*.toml``.

The documentation site's build hook (``docs/hooks.py``) calls :func:`cli_markdown` and
:func:`config_markdown`; nothing else does. Both return Markdown text.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Iterator
from typing import Any

_GLOBAL_DESTS = frozenset({"help", "config", "verbose", "after_config", "after_verbose"})


def subcommands(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()) -> Iterator[
    tuple[tuple[str, ...], argparse.ArgumentParser, str]
]:  # fmt: skip
    """Every command and sub-command of ``parser``, depth first: ``(("config", "schema"), parser, help)``."""
    for action in parser._actions:  # argparse keeps no public list of its subparsers
        if not isinstance(action, argparse._SubParsersAction):
            continue
        helps = {a.dest: a.help or "" for a in action._choices_actions}
        for name, sub in action.choices.items():
            yield (*path, name), sub, helps.get(name, "")
            yield from subcommands(sub, (*path, name))


def _flags(action: argparse.Action) -> str:
    if not action.option_strings:
        return f"`{action.metavar or action.dest}`"
    metavar = ""
    if action.nargs != 0:
        if action.choices is not None and action.metavar is None:
            metavar = " {" + ",".join(str(c) for c in action.choices) + "}"
        else:
            metavar = " " + str(action.metavar or action.dest.upper())
            if action.nargs in ("+", "*"):
                metavar += " ..."
            elif isinstance(action.nargs, int) and action.nargs > 1:
                metavar = " " + " ".join([metavar.strip()] * action.nargs)
    return ", ".join(f"`{flag}{metavar}`" for flag in action.option_strings)


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def _describe(action: argparse.Action) -> str:
    text = _cell(action.help or "") if action.help != argparse.SUPPRESS else ""
    if action.choices is not None and not action.option_strings:
        text += f" (one of: {', '.join(f'`{c}`' for c in action.choices)})"
    default = action.default
    shown = default not in (None, False, argparse.SUPPRESS, [], 0) or isinstance(default, float)
    if shown and action.nargs != 0 and "default" not in text:
        text += f" (default: `{default}`)"
    if action.required and action.option_strings:
        text += " (required)"
    return text.strip()


def cli_markdown(parser: argparse.ArgumentParser) -> str:
    """The CLI reference page: every command of ``parser`` with its usage and its arguments."""
    prog = parser.prog
    lines = [
        "# Command reference",
        "",
        f"Generated from `{prog}`'s argument parser when the documentation is built: it is the `--help` of",
        "every command, on one page. Every command also takes `--config FILE` (a TOML file merged over",
        "`config/default.toml`, before or after the command's name) and `-v` / `-vv` (more logging).",
        "",
        "| command | what it does |",
        "|---|---|",
    ]
    commands = list(subcommands(parser))
    for path, _, help_text in commands:
        name = " ".join((prog, *path))
        lines.append(f"| [`{name}`](#{'-'.join((prog, *path))}) | {_cell(help_text)} |")
    for path, sub, help_text in commands:
        name = " ".join((prog, *path))
        lines += ["", f"## `{name}` {{ #{'-'.join((prog, *path))} }}", ""]
        if help_text:
            lines += [help_text[0].upper() + help_text[1:] + ".", ""]
        usage = " ".join(sub.format_usage().removeprefix("usage: ").split())
        for shared in (" [-h]", " [--config AFTER_CONFIG]", " [-v]"):  # said once, at the top
            usage = usage.replace(shared, "")
        lines += ["```text", usage, "```"]
        rows = [
            a for a in sub._actions
            if a.dest not in _GLOBAL_DESTS and not isinstance(a, argparse._SubParsersAction)
        ]  # fmt: skip
        if rows:
            lines += ["", "| argument | meaning |", "|---|---|"]
            lines += [f"| {_flags(a)} | {_describe(a)} |" for a in rows]
    return "\n".join(lines) + "\n"


def _resolve(node: dict[str, Any], defs: dict[str, Any]) -> dict[str, Any]:
    """``node`` with its ``$ref`` followed; an optional table (``anyOf: [table, null]``) is the table."""
    options = [n for n in node.get("anyOf", []) if n.get("type") != "null"]
    if len(options) == 1 and "$ref" in options[0]:
        node = options[0]
    ref = node.get("$ref")
    if isinstance(ref, str):
        resolved: dict[str, Any] = defs[ref.rsplit("/", 1)[-1]]
        return resolved
    return node


def _type(node: dict[str, Any], defs: dict[str, Any]) -> str:
    node = _resolve(node, defs)
    if "enum" in node:
        return " \\| ".join(f"`{json.dumps(v)}`" for v in node["enum"])
    if "anyOf" in node:
        return " or ".join(_type(n, defs) for n in node["anyOf"])
    kind = node.get("type", "any")
    if kind == "array":
        return f"list of {_type(node.get('items', {}), defs)}"
    if kind == "object" and isinstance(node.get("additionalProperties"), dict):
        return f"table of {_type(node['additionalProperties'], defs)}"
    if kind == "object":
        return "table"
    return str(kind)


def _is_table(node: dict[str, Any], defs: dict[str, Any]) -> bool:
    """Whether ``node`` is a table of keys (``[zenoh]``), or of named tables (``[skills.NAME]``)."""
    node = _resolve(node, defs)
    if "properties" in node:
        return True
    if any(_is_table(option, defs) for option in node.get("anyOf", [])):  # a string or a table
        return True
    named = [*node.get("patternProperties", {}).values()]
    if isinstance(node.get("additionalProperties"), dict):
        named.append(node["additionalProperties"])
    return any(_is_table(child, defs) for child in named)


def _tables(name: str, node: dict[str, Any], defs: dict[str, Any]) -> Iterator[tuple[str, dict[str, Any]]]:
    """Every table under ``name`` (``skills`` -> ``skills.NAME``), the table itself first."""
    node = _resolve(node, defs)
    for option in node.get("anyOf", []):  # a value that is a string or a table: the table's keys
        if _is_table(option, defs):
            yield from _tables(name, option, defs)
    if "properties" in node:
        yield name, node
        for key, child in node["properties"].items():
            if _is_table(child, defs):
                yield from _tables(f"{name}.{key}", child, defs)
    for child in node.get("patternProperties", {}).values():
        yield from _tables(f"{name}.NAME", child, defs)
    extra = node.get("additionalProperties")
    if isinstance(extra, dict) and "properties" not in node:
        yield from _tables(f"{name}.NAME", extra, defs)


def config_markdown(schema: dict[str, Any]) -> str:
    """The configuration reference page: every table and key of ``schema`` (``config/schema.json``)."""
    defs: dict[str, Any] = schema.get("$defs", {})
    lines = [
        "# Configuration reference",
        "",
        "Generated from `config/schema.json` (`twin config schema`) when the documentation is built: every",
        "table and key that `twin` accepts, with its type and default. `config/default.toml` holds the",
        "defaults; a file given with `--config FILE` is merged over it, and an unknown table or key is an",
        "error that names it. How to use them: [Getting started](../getting-started.md).",
    ]
    for top, node in schema.get("properties", {}).items():
        for table, body in _tables(top, node, defs):
            lines += ["", f"## `[{table}]`", ""]
            if body.get("description"):
                lines += [_cell(body["description"]), ""]
            keys = [(k, v) for k, v in body["properties"].items() if not _is_table(v, defs)]
            if not keys:
                continue
            required = set(body.get("required", []))
            lines += ["| key | type | default | meaning |", "|---|---|---|---|"]
            for key, child in keys:
                default = "required" if key in required else f"`{json.dumps(child.get('default'))}`"
                if "default" not in child and key not in required:
                    default = "(none)"
                described = _resolve(child, defs).get("description") or child.get("description") or ""
                lines.append(f"| `{key}` | {_type(child, defs)} | {default} | {_cell(described)} |")
    return "\n".join(lines) + "\n"
