"""The ``twin`` command as a user runs it: a real process, real files, one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from adapters.ros import read_map_server

HEADER = (
    b"ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nFILE_NAME('','',(''),(''),'','','');\n"
    b"FILE_SCHEMA(('IFC4'));\nENDSEC;\n"
)


def twin(*args: str | Path, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "adapters.cli", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=300,
        check=False,
    )


@pytest.fixture(scope="module")
def lab_store_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("cli")
    r = twin("sample", "lab", root / "lab.ifc", "--storeys", "2")
    assert r.returncode == 0, r.stderr
    r = twin("import", root / "lab.ifc", "--store", root / "store", "--site", "lab")
    assert r.returncode == 0, r.stderr
    assert "imported" in r.stdout
    return root / "store"


def test_stats_prints_table_one_and_the_storey_keys(lab_store_dir: Path) -> None:
    r = twin("stats", "--store", lab_store_dir)
    assert r.returncode == 0, r.stderr
    for label in ("lines in IFC file", "triples", "Turtle size", "elements", "meshes", "ground-floor"):
        assert label in r.stdout


def test_stats_json_counts_the_lab(lab_store_dir: Path) -> None:
    r = twin("stats", "--store", lab_store_dir, "--json")
    data = json.loads(r.stdout)
    assert data["spaces"] == 4
    assert [s["key"] for s in data["storeys"]] == ["ground-floor", "first-floor"]
    assert data["elements_per_class"]["IfcFurnishingElement"] == 1
    assert data["triples"] > 0
    assert data["turtle_bytes"] > 0


def test_reimport_into_a_non_empty_store_needs_replace(lab_store_dir: Path, tmp_path: Path) -> None:
    model = tmp_path / "lab.ifc"
    twin("sample", "lab", model)
    r = twin("import", model, "--store", lab_store_dir)
    assert r.returncode != 0
    assert "--replace" in r.stderr


def test_export_writes_turtle_with_lbd_prefixes(lab_store_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "lab.ttl"
    r = twin("export", "--store", lab_store_dir, out)
    assert r.returncode == 0, r.stderr
    text = out.read_text()
    assert "@prefix bot: <https://w3id.org/bot#>" in text
    assert "bot:adjacentElement" in text


def test_query_prints_a_table_and_sparql_json(lab_store_dir: Path) -> None:
    q = "SELECT ?s WHERE { ?s a bot:Space }"
    r = twin("query", "--store", lab_store_dir, q)
    assert r.returncode == 0, r.stderr
    assert "(4 rows)" in r.stdout
    r = twin("query", "--store", lab_store_dir, q, "--json")
    assert len(json.loads(r.stdout)["results"]["bindings"]) == 4


def test_query_refuses_updates_saying_so_and_a_typo_as_not_parsing(lab_store_dir: Path) -> None:
    r = twin("query", "--store", lab_store_dir, "PREFIX x: <urn:x#>\nDELETE WHERE { ?s ?p ?o }")
    assert r.returncode == 1
    assert r.stderr.startswith("twin: error: twin query runs read-only queries")
    assert "this is an update (DELETE), which is not allowed" in r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.splitlines()) == 1
    r = twin("query", "--store", lab_store_dir, "SELCT ?s WHERE { ?s ?p ?o }")
    assert r.returncode == 1
    assert r.stderr.startswith("twin: error: SPARQL query does not parse")


def test_query_prints_whole_values_that_open_takes(lab_store_dir: Path) -> None:
    query = 'SELECT ?door WHERE { ?door twin:ifcClass "IfcDoor" }'
    table = twin("query", "--store", lab_store_dir, query)
    assert table.returncode == 0, table.stderr
    data = json.loads(twin("query", "--store", lab_store_dir, query, "--json").stdout)
    iris = sorted(b["door"]["value"] for b in data["results"]["bindings"])
    assert iris and all(len(iri) > 60 for iri in iris)
    assert sorted(line.strip() for line in table.stdout.splitlines()[2:-1]) == iris


def test_a_reader_that_goes_away_ends_the_command_quietly(lab_store_dir: Path) -> None:
    """``twin query ... | head -c 100``: no 'Broken pipe' error, the exit code of a SIGPIPE."""
    process = subprocess.Popen(
        [sys.executable, "-m", "adapters.cli", "query", "--store", str(lab_store_dir), "--json",
         "SELECT * WHERE { ?s ?p ?o }"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip
    assert process.stdout is not None and process.stderr is not None
    assert len(process.stdout.read(100)) == 100  # more than a pipe holds follows (meshes in base64)
    process.stdout.close()
    assert process.wait(timeout=60) == 141
    assert process.stderr.read() == b""


def test_router_acl_without_robots_is_refused_as_twin_acl_refuses_it(tmp_path: Path) -> None:
    (tmp_path / "users.txt").write_text("robot1:secret\n")
    config = tmp_path / "site.toml"
    config.write_text(f'[zenoh.auth]\nusers_file = "{tmp_path / "users.txt"}"\n')
    acl = twin("acl", "--config", config, "--site", "lab")
    router = twin("router", "--acl", "--listen", "tcp/127.0.0.1:0", "--config", config, "--site", "lab")
    assert acl.returncode == router.returncode == 1
    assert router.stderr == acl.stderr
    assert "Access control needs at least one robot ([robots.NAME]) or operator" in router.stderr


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (None, "No such file"),
        (b"PK\x03\x04zip", "not an IFC/STEP file"),
        (b"ISO-10303-21;\nHEADER;", "truncated"),
        (HEADER.replace(b"IFC4", b"IFC9") + b"DATA;\nENDSEC;\nEND-ISO-10303-21;\n", "IFC9"),
        (HEADER + b"DATA;\nENDSEC;\nEND-ISO-10303-21;\n", "empty model"),
    ],
    ids=["missing", "not-ifc", "truncated", "unsupported-schema", "empty"],
)
def test_import_errors_are_one_line_without_traceback(
    tmp_path: Path, content: bytes | None, message: str
) -> None:
    model = tmp_path / "bad.ifc"
    if content is not None:
        model.write_bytes(content)
    r = twin("import", model, "--store", tmp_path / "store")
    assert r.returncode == 1
    assert message in r.stderr
    assert r.stderr.count("\n") == 1
    assert "Traceback" not in r.stderr


def test_commands_on_a_missing_store_say_how_to_make_one(tmp_path: Path) -> None:
    r = twin("stats", "--store", tmp_path / "nothing")
    assert r.returncode == 1
    assert "twin import" in r.stderr


def test_map_writes_map_server_files_for_every_skill_and_storey(lab_store_dir: Path, tmp_path: Path) -> None:
    r = twin("map", "--store", lab_store_dir, "--all-skills", "--out", tmp_path)
    assert r.returncode == 0, r.stderr
    yamls = sorted(p.name for p in tmp_path.glob("*.yaml"))
    assert len(yamls) == 2 * 4
    grid = read_map_server(tmp_path / "ground-floor__lab-navigation.yaml")
    assert grid.occupied().any()
    assert (tmp_path / "ground-floor__lab-navigation.png").stat().st_size > 0
    assert (tmp_path / "ground-floor__lab-navigation.cdr").stat().st_size > grid.data.size


def test_map_rejects_an_unknown_skill_naming_the_known_ones(lab_store_dir: Path, tmp_path: Path) -> None:
    r = twin("map", "--store", lab_store_dir, "--skill", "flying", "--out", tmp_path)
    assert r.returncode == 1
    assert "Unknown skill 'flying'" in r.stderr
    assert "lab-navigation" in r.stderr


def test_a_store_in_use_by_another_process_gives_a_clear_error(lab_store_dir: Path, tmp_path: Path) -> None:
    from twin.graph.store import EmbeddedStore

    model = tmp_path / "lab.ifc"
    twin("sample", "lab", model)
    with EmbeddedStore.open(lab_store_dir):
        r = twin("import", model, "--store", lab_store_dir, "--replace")
    assert r.returncode == 1
    assert "another process" in r.stderr
    assert "Traceback" not in r.stderr


def test_map_of_one_storey_writes_only_that_storey(lab_store_dir: Path, tmp_path: Path) -> None:
    r = twin(
        "map",
        "--store",
        lab_store_dir,
        "--skill",
        "lab-navigation",
        "--storey",
        "first-floor",
        "--out",
        tmp_path,
    )
    assert r.returncode == 0, r.stderr
    assert [p.name for p in tmp_path.glob("*.yaml")] == ["first-floor__lab-navigation.yaml"]
    r = twin(
        "map", "--store", lab_store_dir, "--skill", "lab-navigation", "--storey", "attic", "--out", tmp_path
    )
    assert r.returncode == 1
    assert "Unknown storey 'attic'" in r.stderr


def test_stats_json_lists_every_element_without_geometry(lab_store_dir: Path) -> None:
    data = json.loads(twin("stats", "--store", lab_store_dir, "--json").stdout)
    assert data["failed_elements"] == []
    assert data["mesh_failures"] == 0


def test_a_bad_config_or_query_file_is_a_one_line_error(lab_store_dir: Path, tmp_path: Path) -> None:
    r = twin("--config", tmp_path, "stats", "--store", lab_store_dir)
    assert r.returncode == 1
    assert "Traceback" not in r.stderr
    r = twin("query", "--store", lab_store_dir, f"@{tmp_path / 'missing.rq'}")
    assert r.returncode == 1
    assert "missing.rq" in r.stderr
    assert "Traceback" not in r.stderr


def test_the_progress_bar_draws_on_a_terminal_and_prints_a_line_per_phase_in_a_pipe() -> None:
    import io

    from rich.console import Console

    from adapters.cli.progress import progress_bar

    out = io.StringIO()
    with progress_bar("meshing", console=Console(file=out, force_terminal=True, width=80)) as advance:
        for done in (1, 50, 100):
            advance(done, 100)
    assert "100/100" in out.getvalue()
    assert "meshing" in out.getvalue()
    piped = io.StringIO()
    console = Console(file=piped, force_terminal=False)
    with progress_bar("meshing", unit="elements", console=console) as advance:
        for done in range(1, 1661):
            advance(done, 1660)
    lines = piped.getvalue().splitlines()
    assert len(lines) == 2 and lines[0] == "meshing: 1,660 elements ..."
    assert lines[1].startswith("meshing: 1,660 of 1,660 elements in ") and lines[1].endswith(" s")
    idle = io.StringIO()
    with progress_bar("meshing", console=Console(file=idle, force_terminal=False)):
        pass
    assert idle.getvalue() == ""


@pytest.mark.parametrize("where", ["before", "after"])
def test_global_options_are_accepted_before_and_after_the_command(
    lab_store_dir: Path, tmp_path: Path, where: str
) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[maps]\nmargin_m = 500\n")  # only an error if the file is read
    options = ["--config", str(bad), "-v"]
    command = ["stats", "--store", str(lab_store_dir)]
    r = twin(*(options + command if where == "before" else command + options))
    assert r.returncode == 1
    assert "Configuration [maps] margin_m: expected a number <= 100.0, got 500." in r.stderr


def test_two_different_config_files_before_and_after_the_command_are_refused(tmp_path: Path) -> None:
    r = twin("--config", tmp_path / "a.toml", "stats", "--config", tmp_path / "b.toml")
    assert r.returncode == 2
    assert "--config given twice" in r.stderr and "a.toml" in r.stderr and "b.toml" in r.stderr


def _site_of(store: Path) -> tuple[str, str]:
    """(the site label of the store's model node, the IRI of one storey)."""
    from twin.graph import vocab
    from twin.graph.rdf import literal_value
    from twin.graph.store import EmbeddedStore

    with EmbeddedStore.open(store, read_only=True) as s:
        site = s.select(f"SELECT ?s WHERE {{ ?m a <{vocab.TWIN_MODEL}> ; <{vocab.RDFS_LABEL}> ?s }}")
        storey = s.select(f"SELECT ?st WHERE {{ ?st a <{vocab.BOT_STOREY}> }} LIMIT 1")
    return str(literal_value(site[0]["s"])), str(storey[0]["st"]).strip("<>")


def test_an_import_without_site_names_the_site_and_its_iris_after_the_file(tmp_path: Path) -> None:
    model = tmp_path / "North_Wing (v2).ifc"
    assert twin("sample", "lab", model).returncode == 0
    r = twin("import", model, "--store", tmp_path / "store")
    assert r.returncode == 0, r.stderr
    base = "https://example.org/building-twin/north-wing-v2#"
    assert f"as site 'north-wing-v2' (from the file name; --site to choose) under {base}" in r.stdout
    site, storey = _site_of(tmp_path / "store")
    assert site == "north-wing-v2"
    assert storey.startswith(base)


def test_site_and_a_configured_site_name_win_over_the_file_name(tmp_path: Path) -> None:
    model = tmp_path / "North_Wing.ifc"
    assert twin("sample", "lab", model).returncode == 0
    r = twin("import", model, "--store", tmp_path / "a", "--site", "east")
    assert r.returncode == 0, r.stderr
    assert "as site 'east' (--site)" in r.stdout
    assert _site_of(tmp_path / "a")[0] == "east"
    config = tmp_path / "site.toml"
    config.write_text('[site]\nname = "west"\n')
    r = twin("--config", config, "import", model, "--store", tmp_path / "b")
    assert r.returncode == 0, r.stderr
    assert "as site 'west' (site.name of the configuration)" in r.stdout
    site, storey = _site_of(tmp_path / "b")
    assert site == "west"
    assert storey.startswith("https://example.org/building-twin/west#")


def test_the_import_line_counts_in_agreeing_words(tmp_path: Path) -> None:
    assert twin("sample", "lab", tmp_path / "one.ifc", "--storeys", "1").returncode == 0
    r = twin("import", tmp_path / "one.ifc", "--store", tmp_path / "store")
    assert r.returncode == 0, r.stderr
    assert ", 1 storey, " in r.stdout and "17 elements (17 with meshes)" in r.stdout
    assert "without geometry" not in r.stdout  # every element of the lab has a mesh


def test_watch_counts_a_speed_masks_cells_by_their_limit() -> None:
    import numpy as np

    from adapters.cli.watch_cmd import cell_counts

    mask = np.zeros((10, 10), np.int8)
    mask[:3, :10] = 30
    mask[9, 9] = 100
    assert cell_counts(mask) == "1 occupied, 30 at 30"
    assert cell_counts(np.full((2, 2), -1, np.int8)) == "0 occupied"
