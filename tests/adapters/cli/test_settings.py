"""The adapters' own tables: ``[zenoh]`` (adapters/zenoh/settings.py), ``[rerun]``
(adapters/rerun/settings.py), the remote store's keys of ``[store]`` (adapters/sparql/settings.py), as
the ``twin`` command loads them (adapters/cli/config_cmd.py), and the JSON Schema editors use."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest

from adapters.cli import main
from adapters.cli.config_cmd import SECTIONS, load, schema_text
from adapters.rerun.settings import RerunSettings
from adapters.sparql.settings import RemoteStoreSettings
from adapters.zenoh.settings import ZenohSettings
from twin.config import DEFAULT_CONFIG
from twin.errors import ConfigError

REPO = Path(__file__).resolve().parents[3]


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "site.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "[zenoh]\nlisten = 5",
            '[zenoh] listen: expected a list of endpoints such as "tcp/127.0.0.1:7447", got 5',
        ),
        (
            '[zenoh]\nconnect = ["tcp/h:7447", "h:7447"]',
            "[zenoh] connect[1]: expected an endpoint such as \"tcp/127.0.0.1:7447\", got 'h:7447'",
        ),
        ('[zenoh]\nmode = "server"', "[zenoh] mode: expected 'peer', 'client' or 'router', got 'server'"),
        (
            '[zenoh]\nprefix = "twin/*"',
            "[zenoh] prefix: expected a key expression without wildcards, got 'twin/*'",
        ),
        ("[zenoh]\nconfig_file = 5", "[zenoh] config_file: expected a path, got 5"),
        ("[zenoh]\nmulticast_scouting = 0", "[zenoh] multicast_scouting: expected true or false, got 0"),
        ("[zenoh]\ntls = 5", "[zenoh] tls: expected a table, got 5"),
        ("[rerun]\nrotate_evry_s = 60", "[rerun] rotate_evry_s: unknown key (did you mean rotate_every_s?)"),
        (
            "[rerun]\nrotate_every_s = 864000",
            "[rerun] rotate_every_s: expected a number <= 604800.0, got 864000",
        ),
        ("[rerun]\nmax_bytes = 1000", "[rerun] max_bytes: expected 0 (no limit) or >= 1048576, got 1000"),
        ("[rerun]\nmax_bytes = 2e6", "[rerun] max_bytes: expected an integer, got 2000000.0"),
        ('[rerun]\ndirectory = ""', "[rerun] directory: expected a path, got ''"),
        ("[rerun]\nconnect_url = 9876", "[rerun] connect_url: expected a string, got 9876"),
        ("[zenho]\nmode = 'peer'", "[zenho]: unknown table (did you mean zenoh?)"),
        (
            '[store]\nurl = "127.0.0.1:7878"',
            '[store] url: expected "" or an http(s):// URL of a SPARQL server',
        ),
        ('[store]\npth = "x"', "[store] pth: unknown key (did you mean path?)"),
        ("[ros]\nframe_id = 3", "[ros] frame_id: expected a string, got 3"),
        ('[robots.r1]\nnamespace = "/r1"\nstorey = "g"\ndomian_id = 3', "[robots.r1] domian_id: unknown key"),
        (
            '[sources.s]\nkind = "rmf_doors"\ntopik = "x"',
            "[sources.s] topik: unknown key (did you mean topic?)",
        ),
    ],
)
def test_a_bad_adapter_setting_is_refused_at_load_naming_its_table_and_key(
    tmp_path: Path, text: str, message: str
) -> None:
    with pytest.raises(ConfigError, match=re.escape(f"Configuration {message}")):
        load(write(tmp_path, text + "\n"))


def test_each_adapter_reads_its_own_table_with_its_defaults(tmp_path: Path) -> None:
    cfg = load(write(tmp_path, '[zenoh]\nconnect = ["tls/h:7448"]\n[rerun]\nrotate_every_s = 3600\n'))
    zenoh, rerun = cfg.section(ZenohSettings), cfg.section(RerunSettings)
    assert (zenoh.connect, zenoh.listen, zenoh.mode) == (("tls/h:7448",), ("tcp/127.0.0.1:7447",), "peer")
    assert (zenoh.tls.root_ca, zenoh.auth.user, zenoh.access.enabled) == (None, None, False)
    assert zenoh.key_prefix(cfg.site) == "twin/lab"
    assert (rerun.rotate_every_s, rerun.directory, rerun.connect_url) == (
        3600.0,
        Path("var/recordings"),
        None,
    )
    assert cfg.section(RemoteStoreSettings).url == ""  # the embedded store
    assert cfg.store_path == Path("var/store")  # [store] path is still the core's


def test_the_defaults_file_shows_each_sections_defaults() -> None:
    with DEFAULT_CONFIG.open("rb") as fh:
        shipped = tomllib.load(fh)
    for section in SECTIONS:
        if section.each:  # keys of [robots.NAME], which the defaults only show in comments
            continue
        written = {k: v for k, v in shipped[section.table].items() if k in section.model_fields}
        assert section.model_validate(written) == section(), section.table


def test_the_committed_json_schema_is_up_to_date() -> None:
    assert (REPO / "config" / "schema.json").read_text() == schema_text(), (
        "run: twin config schema --out config/schema.json"
    )
    assert (REPO / "config" / "default.toml").read_text().startswith("#:schema ./schema.json\n")


def test_twin_config_schema_writes_the_schema_of_every_table(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "schema.json"
    assert main(["config", "schema", "--out", str(out)]) == 0
    assert out.read_text() == schema_text()
    text = out.read_text()
    for table in (
        "site",
        "store",
        "import",
        "maps",
        "skills",
        "zenoh",
        "limits",
        "rights",
        "ros",
        "rerun",
        "robots",
    ):
        assert f'"{table}":' in text, table
    assert '"graph_store_endpoint"' in text and '"flush_every_s"' in text  # both owners of [store]
