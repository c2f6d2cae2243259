"""Open an IFC file with clear errors for everything that can be wrong with it.

What is checked before anything is meshed: the file is a regular file, starts and ends like STEP,
has a header that declares its schemas (a malformed one crashes the parser), parses, declares a
supported schema and holds an ``IfcElement``; entities the parser had to skip or
references it could not resolve (``#999999``) are warnings naming the entity; reference cycles in
what geometry kernels recurse into (placements relative to themselves, boolean operands, mapped
representations, composite curves and profiles) are errors naming the cycle, since a kernel would
loop on them forever.

Example::

    f, lines = open_ifc(Path("model.ifc"))
"""

from __future__ import annotations

import logging
import re
from pathlib import Path
from typing import Any, NamedTuple

import ifcopenshell

from adapters.ifc.attributes import Attributes
from adapters.ifc.errors import IfcFileError

log = logging.getLogger(__name__)

SUPPORTED_SCHEMAS = ("IFC2X3", "IFC4", "IFC4X3", "IFC4X3_ADD2")
_CHUNK = 1 << 20
_MAGIC = b"ISO-10303-21;"
_END = b"END-ISO-10303-21;"
_MAX_PROBLEMS_NAMED = 10
_OFFSET = re.compile(r" at offset (\d+)")
_DANGLING = re.compile(
    r"Instance reference #(\d+) used by instance #(\d+) at attribute index (\d+) not found"
)
_HEAD_BYTES = 1 << 16  # a header is a few hundred bytes
_FILE_SCHEMA = re.compile(rb"FILE_SCHEMA\s*\(\s*\(\s*'[^']*'(?:\s*,\s*'[^']*')*\s*\)\s*\)\s*;")
_LEVEL = re.compile(r"^\[(error|warning|notice)\]\s*(?:\[[^\]]*\]\s*)*", re.IGNORECASE)

# Attributes through which placements and geometry nest; the kernels follow them recursively.
_NESTING: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("IfcObjectPlacement", ("PlacementRelTo",)),
    ("IfcBooleanResult", ("FirstOperand", "SecondOperand")),
    ("IfcCsgSolid", ("TreeRootExpression",)),
    ("IfcMappedItem", ("MappingSource",)),
    ("IfcRepresentationMap", ("MappedRepresentation",)),
    ("IfcCompositeCurve", ("Segments",)),
    ("IfcCompositeCurveSegment", ("ParentCurve",)),
    ("IfcTrimmedCurve", ("BasisCurve",)),
    ("IfcOffsetCurve2D", ("BasisCurve",)),
    ("IfcOffsetCurve3D", ("BasisCurve",)),
    ("IfcDerivedProfileDef", ("ParentProfile",)),
    ("IfcCompositeProfileDef", ("Profiles",)),
    ("IfcRepresentation", ("Items",)),
)
_PLACEMENT_OR_BODY = (
    "IfcObjectPlacement",
    "IfcRepresentationItem",
    "IfcRepresentation",
    "IfcProductRepresentation",
    "IfcRepresentationMap",
    "IfcProfileDef",
    "IfcCompositeCurveSegment",
)
_WALK_FROM = tuple(t for t, _ in _NESTING if t != "IfcRepresentation")  # reached through mapped items


def _scan(path: Path) -> tuple[int, bytes, bytes, int | None]:
    """``(lines, first 64 KiB, last 4 KiB, line of the first NUL byte or None)`` of the file, read in
    chunks (never the whole file at once)."""
    lines = 0
    head = b""
    last = b"\n"
    tail = b""
    nul_line = None
    with path.open("rb") as fh:
        while chunk := fh.read(_CHUNK):
            if not head:
                head = chunk[:_HEAD_BYTES]
            if nul_line is None and (at := chunk.find(b"\0")) >= 0:
                nul_line = lines + chunk.count(b"\n", 0, at) + 1
            lines += chunk.count(b"\n")
            last = chunk[-1:]
            tail = (tail + chunk)[-4096:]
    return lines + (0 if last == b"\n" else 1), head, tail, nul_line


class CheckedIfc(NamedTuple):
    """An opened IFC file, its number of lines, and the products no geometry can be made for."""

    file: Any
    lines: int
    unplaceable: frozenset[int]
    """Ids of products whose placement or body reaches a reference the parser could not resolve
    (``#999999``): where they are is unknown, and one of them can make the geometry iterator drop
    every product meshed with it. Each is named in a warning."""


def _check_header(path: Path, head: bytes) -> None:
    """Raise IfcFileError unless the HEADER section (``head``: the file's first bytes) declares its
    schemas as a list of texts: ifcopenshell 0.9's parser crashes the process on some malformed
    FILE_SCHEMA statements."""
    end = head.find(b"ENDSEC;")
    if end < 0:
        end = len(head)
    if not _FILE_SCHEMA.search(head[:end]):
        found = re.search(rb"FILE_SCHEMA[^;]{0,60}", head[:end])
        said = found.group().decode("ascii", "replace") if found else "no FILE_SCHEMA"
        msg = f"{path} has a broken header: FILE_SCHEMA must name its schemas as (('IFC4')), found {said!r}"
        raise IfcFileError(msg)


def open_ifc(path: Path) -> tuple[Any, int]:
    """Return ``(ifcopenshell.file, number of lines)``; raise IfcFileError naming the problem."""
    checked = open_ifc_checked(path)
    return checked.file, checked.lines


def open_ifc_checked(path: Path, *, cycles: bool = True) -> CheckedIfc:
    """Open ``path`` as :func:`open_ifc` does, and find the products it cannot place or mesh.
    ``cycles=False`` leaves :func:`check_cycles` to the caller (before any geometry is made to wait)."""
    path = Path(path)
    if not path.exists():
        msg = f"No such file: {path}"
        raise IfcFileError(msg)
    if not path.is_file():
        msg = f"Not a file: {path}"
        raise IfcFileError(msg)
    lines, head, tail, nul_line = _scan(path)
    if not head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(_MAGIC):
        msg = f"{path} is not an IFC/STEP file: it does not start with 'ISO-10303-21;'"
        raise IfcFileError(msg)
    if _END not in tail:
        msg = f"{path} is truncated: it does not end with 'END-ISO-10303-21;'"
        raise IfcFileError(msg)
    if nul_line is not None:
        msg = f"{path} is not a text STEP file: line {nul_line} holds a NUL byte"
        raise IfcFileError(msg)
    _check_header(path, head)
    ifcopenshell.get_log()  # reading the parser's log empties it: drop what earlier files left there
    try:
        f = ifcopenshell.open(str(path))
    except Exception as err:  # ifcopenshell raises bare Exception/RuntimeError/SchemaError subclasses
        text = str(err).strip().splitlines()[0].strip() if str(err).strip() else type(err).__name__
        problems, _ = _parse_problems(path, None)
        if problems and "check logs" in text.lower():
            text = f"{text.removesuffix(', check logs')}: {problems[0]}"
        msg = f"{path} cannot be read as IFC: {text}"
        raise IfcFileError(msg) from err
    schema = str(f.schema).upper()
    if schema not in SUPPORTED_SCHEMAS:
        msg = f"{path} uses schema {f.schema}, supported are {', '.join(SUPPORTED_SCHEMAS)}"
        raise IfcFileError(msg)
    problems, dangling_users = _parse_problems(path, f)
    _warn_parse_problems(path, problems)
    if not f.by_type("IfcElement"):
        msg = f"{path} is an empty model: it holds no IfcElement"
        raise IfcFileError(msg)
    if cycles:
        check_cycles(f, path)
    return CheckedIfc(f, lines, _unplaceable(f, path, dangling_users))


def _unplaceable(f: Any, path: Path, broken: set[int]) -> frozenset[int]:
    """The products whose placement or body reaches one of the ``broken`` entities (walking up through
    placements and geometry only: a broken owner history or property set does not count)."""
    products: set[int] = set()
    seen = set(broken)
    todo = list(broken)
    while todo:
        entity = f.by_id(todo.pop())
        if entity.is_a("IfcProduct"):
            products.add(entity.id())
            continue
        if not any(entity.is_a(t) for t in _PLACEMENT_OR_BODY):
            continue
        for user in f.get_inverse(entity):
            if user.id() not in seen:
                seen.add(user.id())
                todo.append(user.id())
    named = [f"{p.is_a()} {p.GlobalId} {p.Name!r}" for p in map(f.by_id, sorted(products))]
    if named:
        more = len(named) - _MAX_PROBLEMS_NAMED
        log.warning(
            "%s: %d product(s) refer in their placement or body to an entity missing from the file and "
            "are imported without geometry: %s%s",
            path,
            len(named),
            "; ".join(named[:_MAX_PROBLEMS_NAMED]),
            f"; and {more} more" if more > 0 else "",
        )
    return frozenset(products)


def _describe(f: Any, entity_id: int) -> str:
    """``#85=IfcWall 'Wall A south'``: an entity as a user finds it in the file."""
    try:
        entity = f.by_id(entity_id)
    except RuntimeError:
        return f"#{entity_id}"
    name = getattr(entity, "Name", None) if entity.is_a("IfcRoot") else None
    return f"#{entity_id}={entity.is_a()}" + (f" {str(name)!r}" if name else "")


def _line_at(path: Path, offset: int) -> str:
    """``line 117 (#110)``: where byte ``offset`` of the file is, for a parser message."""
    with path.open("rb") as fh:
        before = fh.read(offset)
    newline = b"\n"
    start = before.rfind(newline) + 1
    entity = re.match(rb"\s*(#\d+)\s*=", before[start:])
    where = f"line {before.count(newline) + 1}"
    return f"{where} ({entity.group(1).decode()})" if entity else where


def _parse_problems(path: Path, f: Any | None) -> tuple[list[str], set[int]]:
    """The parser's errors and warnings since the log was last read, each naming the entity or line;
    and the ids of the entities that refer to an instance missing from the file."""
    problems = []
    users: set[int] = set()
    for raw in ifcopenshell.get_log().splitlines():
        level = _LEVEL.match(raw)
        if level is None or level.group(1).lower() == "notice":
            continue
        text = raw[level.end() :].strip()
        dangling = _DANGLING.search(text)
        if dangling is not None and f is not None:
            missing, user, index = (int(g) for g in dangling.groups())
            users.add(user)
            try:
                attribute = f.by_id(user).attribute_name(index)
            except (RuntimeError, IndexError):
                attribute = f"attribute {index}"
            problems.append(
                f"{_describe(f, user)}: {attribute} refers to #{missing}, which is not in the file "
                "(read as empty)"
            )
            continue
        offset = _OFFSET.search(text)
        if offset is not None:  # located only for the problems that are named one by one
            where = _line_at(path, int(offset.group(1))) if len(problems) < _MAX_PROBLEMS_NAMED else ""
            text = (text[: offset.start()] + text[offset.end() :]).strip()
            text = f"{where}: {text}" if where else text
        problems.append(text)
    return problems, users


def _warn_parse_problems(path: Path, problems: list[str]) -> None:
    for text in problems[:_MAX_PROBLEMS_NAMED]:
        log.warning("%s: %s", path, text)
    if len(problems) > _MAX_PROBLEMS_NAMED:
        log.warning("%s: %d more problems the parser skipped", path, len(problems) - _MAX_PROBLEMS_NAMED)


def _nested(entity: Any, names: tuple[str, ...], attributes: Attributes) -> list[Any]:
    """The entities ``entity`` refers to through the attributes ``names`` (lists flattened)."""
    found = []
    for name in names:
        try:
            value = attributes.get_or_none(entity, name)
        except RuntimeError:  # an attribute the parser could not read
            continue
        for v in value if isinstance(value, tuple) else (value,):
            if isinstance(v, ifcopenshell.entity_instance):
                found.append(v)
    return found


def check_cycles(f: Any, path: Path) -> None:
    """Raise IfcFileError naming the first reference cycle through placements or nested geometry.

    Walks only what placements, boolean results, mapped items, composite curves and profiles reach
    (about 0.05 s on Janesville), depth first without recursion.
    """
    names_of: dict[str, tuple[str, ...]] = {}
    attributes = Attributes()

    def links(entity: Any) -> list[Any]:
        names = names_of.get(entity.is_a())
        if names is None:
            names = tuple(n for t, ns in _NESTING if entity.is_a(t) for n in ns)
            names_of[entity.is_a()] = names
        return _nested(entity, names, attributes) if names else []

    done: set[int] = set()
    for ifc_type in _WALK_FROM:
        try:
            roots = f.by_type(ifc_type)
        except RuntimeError:  # a type this schema does not have
            continue
        for root in roots:
            if root.id() in done:
                continue
            trail = [root.id()]
            on_trail = {root.id()}
            stack = [iter(links(root))]
            while stack:
                child = next(stack[-1], None)
                if child is None:
                    stack.pop()
                    node = trail.pop()
                    on_trail.discard(node)
                    done.add(node)
                    continue
                cid = child.id()
                if cid in on_trail:
                    _raise_cycle(f, path, [*trail[trail.index(cid) :], cid])
                if cid not in done:
                    trail.append(cid)
                    on_trail.add(cid)
                    stack.append(iter(links(child)))


def _raise_cycle(f: Any, path: Path, cycle: list[int]) -> None:
    if len(cycle) == 2:
        what = f"{_describe(f, cycle[0])} refers to itself"
    else:
        what = "a reference cycle: " + " -> ".join(_describe(f, i) for i in cycle)
    msg = f"{path} is broken: {what}; no geometry can be made of it"
    raise IfcFileError(msg)
