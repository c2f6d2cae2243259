"""Broken IFC files make ``twin import`` end with a clear error or per-element warnings, never with a
hang or a traceback (issue 10, hostile input).

Every broken file is made here from the bundled lab: truncated, of a wrong schema, random bytes,
empty, not IFC at all, entities that refer to missing ids or to themselves, degenerate geometry; and,
with hypothesis, the lab with mutated bytes. Each import runs in its own process with a timeout, so a
hang fails the test instead of stalling the suite. The explicit cases run the real command
(``python -m adapters.cli import``); the mutated files run the same ``main()`` in processes forked from
a warm interpreter (the forkserver preloads the CLI), which makes an example cost the import and not
the interpreter start-up.

A longer fuzz run: ``HYPOTHESIS_PROFILE=long .venv/bin/python -m pytest tests/adapters/ifc/test_broken_ifc.py
-k mutated`` (500 examples; ``HYPOTHESIS_MAX_EXAMPLES=N`` for another count).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from adapters.ifc.sample_lab import write_lab
from tests.conftest import examples

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

TIMEOUT_S = 60.0
MUTATED_EXAMPLES = examples(30)


@dataclass(frozen=True, slots=True)
class Outcome:
    code: int | None  # None: killed after TIMEOUT_S
    stdout: str
    stderr: str


def import_by_command(ifc: Path, store: Path) -> Outcome:
    """``twin import`` as a user runs it, killed after :data:`TIMEOUT_S`."""
    try:
        r = subprocess.run(
            [sys.executable, "-m", "adapters.cli", "import", str(ifc), "--store", str(store)],
            capture_output=True,
            text=True,
            timeout=TIMEOUT_S,
            check=False,
        )
    except subprocess.TimeoutExpired as err:
        return Outcome(None, str(err.stdout or ""), str(err.stderr or ""))
    return Outcome(r.returncode, r.stdout, r.stderr)


def _run_main(argv: list[str], out: str, err: str) -> None:
    """In a forked process: the ``twin`` command's ``main`` with stdout and stderr going to files."""
    for fd, name in ((1, out), (2, err)):
        os.dup2(os.open(name, os.O_WRONLY | os.O_CREAT | os.O_TRUNC), fd)
    from adapters.cli.app import main

    code = main(argv)
    sys.stdout.flush()
    sys.stderr.flush()
    sys.exit(code)


def import_forked(ifc: Path, store: Path) -> Outcome:
    """``twin import`` run by ``main()`` in a process forked from a warm forkserver, killed after
    :data:`TIMEOUT_S`; an uncaught exception prints its traceback to the process's stderr."""
    ctx = mp.get_context("forkserver")
    out, err = store.parent / "stdout", store.parent / "stderr"
    child = ctx.Process(
        target=_run_main, args=(["import", str(ifc), "--store", str(store)], str(out), str(err))
    )
    child.start()
    child.join(TIMEOUT_S)
    code = child.exitcode
    if child.is_alive():
        child.kill()
        child.join()
        code = None
    return Outcome(code, out.read_text(errors="replace"), err.read_text(errors="replace"))


def assert_clear_outcome(outcome: Outcome, ifc: Path) -> None:
    """Exit 0, or exit 1 with one ``twin: error:`` line naming the file; never a hang or a traceback."""
    assert outcome.code is not None, f"twin import {ifc} hung (killed after {TIMEOUT_S:.0f} s)"
    assert "Traceback" not in outcome.stderr, outcome.stderr
    if outcome.code == 0:
        assert "imported" in outcome.stdout
        return
    assert outcome.code == 1, outcome
    errors = [line for line in outcome.stderr.splitlines() if line.startswith("twin: error:")]
    assert len(errors) == 1, outcome.stderr
    assert outcome.stderr.rstrip().endswith(errors[0]), outcome.stderr
    assert ifc.name in errors[0], errors[0]


@pytest.fixture(scope="module")
def lab_text(tmp_path_factory: pytest.TempPathFactory) -> str:
    path = tmp_path_factory.mktemp("broken") / "lab.ifc"
    write_lab(path)
    return path.read_text()


# --- the broken files ------------------------------------------------------------------------------
def edited(text: str, entities: dict[int, str], extra: dict[int, str] | None = None) -> bytes:
    """The lab with entities ``#id`` redefined and ``extra`` ones appended to its DATA section."""
    for eid, body in entities.items():
        text, n = re.subn(rf"^#{eid}=.*;$", lambda _m, e=eid, b=body: f"#{e}={b};", text, flags=re.M)
        assert n == 1, f"#{eid} is not in the lab"
    added = "".join(f"#{eid}={body};\n" for eid, body in (extra or {}).items())
    return text.replace("ENDSEC;\nEND-ISO", added + "ENDSEC;\nEND-ISO").encode()


def entity_line(text: str, eid: int) -> str:
    match = re.search(rf"^#{eid}=(.*);$", text, flags=re.M)
    assert match is not None
    return match.group(1)


def with_wall(text: str, **attributes: str) -> bytes:
    """The lab with wall #85 ('Wall A south', placement #114, body #125) given other attributes."""
    placement = attributes.get("placement", "#114")
    body = attributes.get("body", "#125")
    return edited(
        text, {85: f"IFCWALL('00jPQmd71Sv8dnzvUClz1H',$,'Wall A south',$,$,{placement},{body},$,$)"}
    )


def body_of_wall(text: str, items: str, extra: dict[int, str]) -> bytes:
    """The lab with the body of wall #85 (shape representation #124) made of ``items``."""
    return edited(text, {124: f"IFCSHAPEREPRESENTATION(#11,'Body','SweptSolid',({items}))"}, extra)


Make = Callable[[str], bytes]
WALL = "Wall A south"
CASES: dict[str, tuple[Make, str, str]] = {
    # name: (file maker, "error" or "warning", what stderr must say)
    "truncated mid-header": (lambda t: t.encode()[:60], "error", "truncated"),
    "truncated mid-entity": (lambda t: t.encode()[: t.index("#123=") + 20], "error", "truncated"),
    "truncated before END-ISO-10303-21": (lambda t: t.encode()[: t.rindex("END-ISO")], "error", "truncated"),
    "cut mid-entity with the end glued back": (
        lambda t: t.encode()[: t.index("#123=") + 20] + b"\nENDSEC;\nEND-ISO-10303-21;\n",
        "warning",
        "IFCEXTRUDEDAREAENDSEC.*|missing from the file.*" + WALL,
    ),
    "unknown schema IFC9": (lambda t: t.replace("('IFC4')", "('IFC9')").encode(), "error", "IFC9"),
    "no FILE_SCHEMA": (lambda t: t.replace("FILE_SCHEMA(('IFC4'));\n", "").encode(), "error", "header"),
    "IFC4 entities under an IFC2X3 header": (
        lambda t: t.replace("('IFC4')", "('IFC2X3')").encode(),
        "warning",
        "IfcIndexedPolyCurve|no geometry kernel could mesh.*" + WALL,
    ),
    "random bytes": (lambda t: os.urandom(4096), "error", "not an IFC/STEP file"),
    "random bytes framed as STEP": (
        lambda t: b"ISO-10303-21;\n" + bytes(range(256)) * 8 + b"\nEND-ISO-10303-21;\n",
        "error",
        "NUL byte",
    ),
    "an empty file": (lambda t: b"", "error", "not an IFC/STEP file"),
    "JSON": (lambda t: b'{"type": "building", "walls": [1, 2]}', "error", "not an IFC/STEP file"),
    "a huge entity id": (
        lambda t: edited(t, {}, {10**20: "IFCCARTESIANPOINT((0.,0.,0.))"}),
        "error",
        "line \\d+.*invalid instance name",
    ),
    "a NAN coordinate": (
        lambda t: edited(t, {110: "IFCCARTESIANPOINT((NAN,0.,0.))"}),
        "warning",
        "line \\d+ \\(#110\\).*NAN",
    ),
    "a placement that refers to #999999": (
        lambda t: with_wall(t, placement="#999999"),
        "warning",
        "ObjectPlacement refers to #999999.*\n.*without geometry: IfcWall .*" + WALL,
    ),
    "a body that refers to #999999": (lambda t: with_wall(t, body="#999999"), "warning", WALL + ".*#999999"),
    "a profile that refers to #999999": (
        lambda t: edited(t, {123: "IFCEXTRUDEDAREASOLID(#999999,#122,#117,2.7)"}),
        "warning",
        "SweptArea refers to #999999.*\n.*without geometry: IfcWall .*" + WALL,
    ),
    "a mapped item whose source is missing": (
        lambda t: body_of_wall(
            t,
            "#9003",
            {
                9003: "IFCMAPPEDITEM(#999999,#9004)",
                9004: "IFCCARTESIANTRANSFORMATIONOPERATOR3D($,$,#119,$,$)",
            },
        ),
        "warning",
        "MappingSource refers to #999999.*\n.*without geometry: IfcWall .*" + WALL,
    ),
    "a containment that lists #999999": (
        lambda t: edited(
            t,
            {109: "IFCRELCONTAINEDINSPATIALSTRUCTURE('04xU2XIS9OZ9Jsj6_vr14g',$,$,$,(#91,#999999,#85),#26)"},
        ),
        "warning",
        "#109=IfcRelContainedInSpatialStructure: RelatedElements refers to #999999",
    ),
    "an opening that is missing": (
        lambda t: edited(t, {106: "IFCRELVOIDSELEMENT('34GU3VgerOafbD8yoZ2CPv',$,$,$,#85,#999999)"}),
        "warning",
        "RelatedOpeningElement refers to #999999",
    ),
    "a placement relative to itself": (
        lambda t: edited(t, {114: "IFCLOCALPLACEMENT(#114,#113)"}),
        "error",
        "#114=IfcLocalPlacement refers to itself",
    ),
    "a cycle of placements": (
        lambda t: edited(t, {114: "IFCLOCALPLACEMENT(#130,#113)", 130: "IFCLOCALPLACEMENT(#114,#129)"}),
        "error",
        "reference cycle: #114=IfcLocalPlacement -> #130=IfcLocalPlacement -> #114",
    ),
    "a cycle through the storey's placement": (
        lambda t: edited(t, {32: "IFCLOCALPLACEMENT(#39,#31)"}),
        "error",
        "reference cycle: #32=IfcLocalPlacement -> #39=IfcLocalPlacement -> #32",
    ),
    "a boolean result that is its own operand": (
        lambda t: body_of_wall(t, "#9006", {9006: "IFCBOOLEANRESULT(.DIFFERENCE.,#9006,#123)"}),
        "error",
        "#9006=IfcBooleanResult refers to itself",
    ),
    "a mapped representation that maps itself": (
        lambda t: body_of_wall(
            t,
            "#9003",
            {
                9003: "IFCMAPPEDITEM(#9005,#9004)",
                9004: "IFCCARTESIANTRANSFORMATIONOPERATOR3D($,$,#119,$,$)",
                9005: "IFCREPRESENTATIONMAP(#9,#124)",
            },
        ),
        "error",
        "reference cycle: #9003=IfcMappedItem -> #9005=IfcRepresentationMap -> #124",
    ),
    "an aggregate that contains itself": (
        lambda t: edited(t, {34: "IFCRELAGGREGATES('2IdWy97oDJ7ea5VmauC0tR',$,$,$,#26,(#26,#33,#51))"}),
        "warning",
        "",
    ),
    "a placement that is a point": (
        lambda t: edited(t, {114: "IFCLOCALPLACEMENT(#32,#110)"}),
        "warning",
        "no geometry kernel could mesh.*" + WALL,
    ),
    "a storey placed by a point": (
        lambda t: edited(t, {32: "IFCLOCALPLACEMENT(#25,#110)"}),
        "warning",
        "IfcBuildingStorey .*'Ground floor': its elevation cannot be read",
    ),
    "a storey elevation that is text": (
        lambda t: edited(
            t, {26: "IFCBUILDINGSTOREY('1EYFXagcLJJPUQ7LH2wdQg',$,'Ground floor',$,$,$,$,$,$,'high')"}
        ),
        "warning",
        "'Ground floor': its elevation cannot be read",
    ),
    "a length unit of zero": (
        lambda t: edited(
            t,
            {2: "IFCCONVERSIONBASEDUNIT(#9010,.LENGTHUNIT.,'zero',#9011)"},
            {
                9010: "IFCDIMENSIONALEXPONENTS(1,0,0,0,0,0,0)",
                9011: "IFCMEASUREWITHUNIT(IFCLENGTHMEASURE(0.),#9012)",
                9012: "IFCSIUNIT(*,.LENGTHUNIT.,$,.METRE.)",
            },
        ),
        "error",
        "length unit of 0.0 m",
    ),
    "a zero-thickness extrusion": (
        lambda t: edited(t, {123: "IFCEXTRUDEDAREASOLID(#118,#122,#117,0.)"}),
        "warning",
        "no geometry kernel could mesh.*" + WALL,
    ),
    "a zero-area profile": (
        lambda t: edited(t, {115: "IFCCARTESIANPOINTLIST2D(((0.,0.),(0.,0.),(0.,0.),(0.,0.),(0.,0.)))"}),
        "warning",
        "no geometry kernel could mesh.*" + WALL,
    ),
    "a zero extrusion direction": (
        lambda t: edited(t, {117: "IFCDIRECTION((0.,0.,0.))"}),
        "warning",
        "no geometry kernel could mesh.*" + WALL,
    ),
    "1e308 coordinates in a profile": (
        lambda t: edited(
            t, {115: "IFCCARTESIANPOINTLIST2D(((0.,0.),(0.,1.E308),(1.E308,1.E308),(1.E308,0.),(0.,0.)))"}
        ),
        "warning",
        "no geometry kernel could mesh.*" + WALL,
    ),
    "a wall placed at 1e308": (
        lambda t: edited(t, {110: "IFCCARTESIANPOINT((1.E308,-1.E308,0.))"}),
        "warning",
        "IfcWall .*" + WALL + ": its body reaches .* from the origin",
    ),
    "a wall without representation": (lambda t: with_wall(t, body="$"), "warning", ""),
    "a polyline with one point": (
        lambda t: edited(
            t,
            {118: "IFCARBITRARYCLOSEDPROFILEDEF(.AREA.,$,#9002)"},
            {9001: "IFCCARTESIANPOINT((0.,0.))", 9002: "IFCPOLYLINE((#9001))"},
        ),
        "warning",
        "no geometry kernel could mesh.*" + WALL,
    ),
    "a wall without GlobalId": (
        lambda t: edited(t, {85: "IFCWALL($,$,'Wall A south',$,$,#114,#125,$,$)"}),
        "error",
        "IfcWall 'Wall A south' has an invalid GlobalId",
    ),
    "a FILE_SCHEMA that names no list of schemas": (  # crashed ifcopenshell's parser (found by fuzzing)
        lambda t: t.replace(
            "FILE_SCHEMA(('IFC4'));\nENDSEC;\nDATA;\n#1=IFCPROJECT(", "FILE_SCHEMA("
        ).encode(),
        "error",
        "broken header: FILE_SCHEMA must name its schemas",
    ),
    "an entity defined twice": (
        lambda t: edited(t, {}, {114: "IFCLOCALPLACEMENT(#32,#113)"}),
        "warning",
        "Overwriting instance with name #114",
    ),
}


@dataclass(frozen=True, slots=True)
class CaseRun:
    ifc: Path
    outcome: Outcome
    store_left: bool  # whether the import left a store behind


@pytest.fixture(scope="module")
def case_run(lab_text: str, tmp_path_factory: pytest.TempPathFactory) -> Callable[[str], CaseRun]:
    """``twin import`` of a case's broken file, run once per module: the tests below check the same
    import for different things (each import meshes in children: seconds)."""
    runs: dict[str, CaseRun] = {}

    def run(case: str) -> CaseRun:
        if case not in runs:
            root = tmp_path_factory.mktemp("case")
            ifc = root / "broken.ifc"
            ifc.write_bytes(CASES[case][0](lab_text))
            outcome = import_by_command(ifc, root / "store")
            runs[case] = CaseRun(ifc, outcome, (root / "store").exists())
        return runs[case]

    return run


@pytest.mark.parametrize("case", list(CASES))
def test_a_broken_file_gives_a_clear_error_or_warnings_naming_the_element(
    case: str, case_run: Callable[[str], CaseRun]
) -> None:
    _, kind, said = CASES[case]
    ran = case_run(case)
    outcome = ran.outcome
    assert_clear_outcome(outcome, ran.ifc)
    assert outcome.code == (1 if kind == "error" else 0), outcome.stderr
    assert re.search(said, outcome.stderr), outcome.stderr
    assert ran.store_left == (kind != "error")  # a failed import leaves no store behind


@pytest.mark.parametrize("case", [c for c in CASES if "cycle" in c or "its own operand" in c])
def test_a_reference_cycle_is_one_error_without_warnings_from_the_children_it_stops(
    case: str, case_run: Callable[[str], CaseRun]
) -> None:
    """The cycle check runs while the kernel children mesh; the children it kills are not reported as
    kernels that crashed."""
    _, kind, said = CASES[case]
    assert kind == "error"
    outcome = case_run(case).outcome
    assert outcome.code == 1 and re.search(said, outcome.stderr), outcome.stderr
    assert "crashed" not in outcome.stderr and "failed" not in outcome.stderr, outcome.stderr


@pytest.mark.parametrize("what", ["a directory", "a path below a file", "a missing file"])
def test_a_path_that_is_no_file_gives_a_one_line_error(what: str, tmp_path: Path) -> None:
    (tmp_path / "dir.ifc").mkdir()
    (tmp_path / "file").write_text("x")
    path, said = {
        "a directory": (tmp_path / "dir.ifc", "is a directory"),
        "a path below a file": (tmp_path / "file" / "lab.ifc", "No such file"),
        "a missing file": (tmp_path / "missing.ifc", "No such file"),
    }[what]
    outcome = import_by_command(path, tmp_path / "store")
    assert_clear_outcome(outcome, path)
    assert outcome.code == 1
    assert said in outcome.stderr


# --- mutated bytes ---------------------------------------------------------------------------------
TOKENS = [b"#999999", b"$", b"(", b")", b"'", b",", b";", b"=", b"1.E308", b"-0.", b"#1", b"*", b".T.", b"\n"]


@st.composite
def mutations(draw: st.DrawFn, size: int) -> list[tuple[str, int, int, bytes]]:
    """Up to 8 edits of a file of ``size`` bytes: (kind, at, length, bytes)."""
    edits = []
    for _ in range(draw(st.integers(1, 8))):
        kind = draw(st.sampled_from(["byte", "delete", "repeat", "token", "cut"]))
        at = draw(st.integers(0, size - 1))
        length = draw(st.integers(1, 64))
        data = draw(st.binary(min_size=1, max_size=1) if kind == "byte" else st.sampled_from(TOKENS))
        edits.append((kind, at, length, data))
    return edits


def mutate(data: bytes, edits: list[tuple[str, int, int, bytes]]) -> bytes:
    out = bytearray(data)
    for kind, position, length, token in edits:
        at = min(position, max(len(out) - 1, 0))
        if kind == "byte":
            out[at : at + 1] = token
        elif kind == "delete":
            del out[at : at + length]
        elif kind == "repeat":
            out[at:at] = out[at : at + length]
        elif kind == "token":
            out[at:at] = token
        else:  # cut, and glue the end back so that the parser, not the tail check, meets the damage
            out = out[:at] + b"\nENDSEC;\nEND-ISO-10303-21;\n"
    return bytes(out)


@pytest.fixture(scope="module")
def lab_bytes(lab_text: str) -> bytes:
    ctx = mp.get_context("forkserver")
    # the CLI and what `twin import` runs (the CLI imports a command's module when it runs)
    ctx.set_forkserver_preload(
        ["adapters.cli.app", "adapters.cli.config_cmd", "adapters.cli.model_cmds", "adapters.cli.import_file"]
    )
    return lab_text.encode()


@settings(
    max_examples=MUTATED_EXAMPLES,
    deadline=None,
    derandomize=False,
    suppress_health_check=list(HealthCheck),
)
@given(data=st.data())
def test_mutated_bytes_of_the_lab_give_a_clear_error_or_an_import(
    lab_bytes: bytes, data: st.DataObject
) -> None:
    edits = data.draw(mutations(len(lab_bytes)))
    work = Path(tempfile.mkdtemp(prefix="mutated-"))
    try:
        ifc = work / "mutated.ifc"
        ifc.write_bytes(mutate(lab_bytes, edits))
        assert_clear_outcome(import_forked(ifc, work / "store"), ifc)
    finally:
        shutil.rmtree(work, ignore_errors=True)
