"""A ``twin`` command builds only its own module's parsers and imports only what it runs: the same
parser as with every command, and no SciPy, NumPy or daemon in ``twin observe``."""

from __future__ import annotations

import subprocess
import sys

from adapters.cli.app import COMMAND_MODULES, OWN_COMMANDS, build_parser, command_of
from adapters.cli.reference import subcommands


def test_each_command_parses_alike_when_only_its_module_builds_its_parser() -> None:
    full = {path: p.format_help() for path, p, _ in subcommands(build_parser())}
    named = {name for _, names in COMMAND_MODULES for name in names}
    for module, names in COMMAND_MODULES:
        for name in names:
            alone = {path: p.format_help() for path, p, _ in subcommands(build_parser(name))}
            assert set(alone) >= {path for path in full if path[0] == name}, (module, name)
            for path, text in alone.items():
                assert text == full[path], (module, path)
    # every command a module adds is named there (one that is not would still run, by every parser)
    added = {path[0] for path in full} - set(OWN_COMMANDS)
    assert added == named and set(OWN_COMMANDS) <= {path[0] for path in full}
    for name in OWN_COMMANDS:
        alone = {path: p.format_help() for path, p, _ in subcommands(build_parser(name))}
        assert set(alone) == {path for path in full if path[0] in OWN_COMMANDS}, name
        assert all(text == full[path] for path, text in alone.items()), name
    argv = ["--config", "x.toml", "observe", "--robot", "r1", "--box", "1,2,0,1,1,1,0", "-v"]
    assert vars(build_parser("observe").parse_args(argv)) == vars(build_parser().parse_args(argv))


def test_command_of_names_a_command_only_after_global_options_spelled_out() -> None:
    assert command_of(["observe", "--robot", "r1"]) == "observe"
    assert command_of(["--config", "x.toml", "-vv", "serve", "--help"]) == "serve"
    assert command_of(["--config=x.toml", "--verbose", "status"]) == "status"
    assert command_of(["--config", "serve", "status"]) == "status"  # serve is the file's name here
    assert command_of(["-h", "serve"]) is None
    assert command_of(["--conf", "x.toml", "serve"]) is None  # an abbreviation: argparse decides
    assert command_of(["import", "lab.ifc"]) == "import"  # app.py's own: no module's parsers
    assert command_of(["nosuch"]) is None
    assert command_of([]) is None


def test_twin_observe_imports_neither_scipy_nor_numpy_nor_the_daemon() -> None:
    heavy = ("scipy", "numpy", "networkx", "rich", "yaml", "rdflib", "twin.live", "twin.routes", "rerun")
    code = (
        "import sys\n"
        "from adapters.cli.app import main\n"
        "try:\n"
        "    main(['observe', '--robot', 'r1', '--remove', 'urn:x', '--connect', 'tcp/127.0.0.1:1',"
        " '--timeout', '0.1'])\n"
        "finally:\n"
        f"    print(sorted(m for m in {heavy!r} if m in sys.modules))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False
    )
    assert "No daemon found at tcp/127.0.0.1:1" in done.stderr, done.stderr  # it ran, and failed so
    assert done.stdout.strip().splitlines()[-1] == "[]", done.stdout

