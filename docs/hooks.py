"""MkDocs hooks (``mkdocs.yml``: ``hooks``): the pages generated at build time, so that they cannot drift.

- ``index.md``: the repository's README.md, its ``docs/`` links made relative to this folder (and its
  link to ``benchmarks/README.md`` made one to ``benchmarks.md``);
- ``reference/cli.md``: every ``twin`` command, from its argument parser;
- ``reference/configuration.md``: every table and key, from ``config/schema.json``;
- ``benchmarks.md``: ``benchmarks/README.md``, its ``../docs/`` links made relative to this folder, and
  the pictures it links in ``benchmarks/*/`` (e.g. ``routes-png/``) copied beside it.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # `mkdocs build` from a checkout that is not the installed one
    sys.path.insert(0, str(ROOT))


def generated_pages() -> dict[str, str]:
    """Each generated page's path under docs/ and its Markdown."""
    from adapters.cli.app import build_parser
    from adapters.cli.reference import cli_markdown, config_markdown

    readme = (ROOT / "README.md").read_text().replace("](docs/", "](")
    readme = readme.replace("](benchmarks/README.md)", "](benchmarks.md)")
    benchmarks = (ROOT / "benchmarks" / "README.md").read_text().replace("](../docs/", "](")
    schema = json.loads((ROOT / "config" / "schema.json").read_text())
    return {
        "index.md": readme,
        "reference/cli.md": cli_markdown(build_parser()),
        "reference/configuration.md": config_markdown(schema),
        "benchmarks.md": benchmarks,
    }


def on_files(files: Any, config: Any) -> Any:
    from mkdocs.structure.files import File

    for path, text in generated_pages().items():
        files.append(File.generated(config, path, content=text))
    for picture in sorted((ROOT / "benchmarks").glob("*/*.png")):
        uri = picture.relative_to(ROOT / "benchmarks").as_posix()
        files.append(File.generated(config, uri, abs_src_path=str(picture)))
    return files
