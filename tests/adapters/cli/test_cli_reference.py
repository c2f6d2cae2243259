"""The documentation's generated reference pages: every command and every configuration key."""

from __future__ import annotations

import json
from pathlib import Path

from adapters.cli.app import build_parser
from adapters.cli.config_cmd import schema_text
from adapters.cli.reference import cli_markdown, config_markdown, subcommands

ROOT = Path(__file__).resolve().parents[3]


def test_the_cli_reference_has_a_section_with_the_usage_of_every_command_and_sub_command() -> None:
    parser = build_parser()
    page = cli_markdown(parser)
    paths = [path for path, _, _ in subcommands(parser)]
    assert ("serve",) in paths and ("config", "schema") in paths and len(paths) > 15
    for path in paths:
        name = " ".join(("twin", *path))
        assert f"## `{name}`" in page, name
        assert f"\n{name} " in page or f"\n{name}\n" in page, f"no usage line for {name}"


def test_the_cli_reference_lists_every_option_of_a_command_with_its_help() -> None:
    page = cli_markdown(build_parser())
    section = page.split("## `twin watch`")[1].split("\n## ")[0]
    assert "`--skill SKILL`" in section
    assert "`--count COUNT`" in section
    assert "--config AFTER_CONFIG" not in page and "[-h]" not in page


def test_the_configuration_reference_names_every_table_and_key_of_the_schema() -> None:
    schema = json.loads(schema_text())
    page = config_markdown(schema)
    for table in ("[site]", "[zenoh]", "[zenoh.access]", "[skills.NAME]", "[robots.NAME]", "[fusion]"):
        assert f"## `{table}`" in page, table
    for name, node in schema["$defs"].items():
        for key in node.get("properties", {}):
            as_table = f".{key}]`" in page or f".{key}.NAME]`" in page
            assert f"| `{key}` |" in page or as_table, f"{name}.{key}"


def test_the_generated_pages_are_made_from_the_committed_readme_schema_and_benchmarks() -> None:
    import importlib.util

    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "docs" / "hooks.py")
    assert spec is not None and spec.loader is not None
    hooks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hooks)
    pages = hooks.generated_pages()
    assert set(pages) == {"index.md", "reference/cli.md", "reference/configuration.md", "benchmarks.md"}
    assert "](docs/" not in pages["index.md"]  # the README's links, relative to docs/
    assert "](../docs/" not in pages["benchmarks.md"]
