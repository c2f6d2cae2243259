"""A building model as the graph's triples (the paper's Algorithm 1, records -> triples), written as
N-Triples text for the store's bulk loader, with the mesh literals built once per mesh.

Example::

    iri_of = mint_iris(model, "https://example.org/lab#")
    quads = list(model_quads(model, base_iri="https://example.org/lab#", site="lab"))
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Final

import pyoxigraph as ox

from twin.errors import ModelError
from twin.graph import vocab
from twin.graph.extents import format_extent, storey_extents
from twin.graph.meshcodec import encode_mesh, encode_placements
from twin.records import BuildingModel, FloatArray, Geometry, Mesh

log = logging.getLogger(__name__)

# The graph is written as N-Triples text and parsed by pyoxigraph into quads: about 4x faster than
# building each term as a Python object (an import has tens of thousands of triples). Only the mesh
# literals, large and shared by the instances of a representation, are built as objects, once per mesh
# (but for the first copy of each, which is text too).
_ESCAPES: Final = str.maketrans({"\\": "\\\\", '"': '\\"', "\n": "\\n", "\r": "\\r"})
_TRUE: Final = f'"true"^^<{vocab.XSD_BOOLEAN}>'
_FALSE: Final = f'"false"^^<{vocab.XSD_BOOLEAN}>'
_TYPE: Final = f"<{vocab.RDF_TYPE}>"
_LABEL: Final = f"<{vocab.RDFS_LABEL}>"
_GLOBAL_ID: Final = f"<{vocab.PROPS_GLOBAL_ID}>"
_NAME: Final = f"<{vocab.PROPS_NAME}>"
_HAS_GEOMETRY: Final = f"<{vocab.OMG_HAS_GEOMETRY}>"
_GEOMETRY: Final = f"<{vocab.OMG_GEOMETRY}>"
_PLACEMENT: Final = f"<{vocab.TWIN_PLACEMENT}>"
_CLOSED: Final = f"<{vocab.TWIN_CLOSED}>"
_TRIANGLES: Final = f"<{vocab.TWIN_TRIANGLES}>"
_SOLID: Final = f"<{vocab.TWIN_SOLID}>"
_BOT_ELEMENT: Final = f"<{vocab.BOT_ELEMENT}>"
_IFC_CLASS: Final = f"<{vocab.TWIN_IFC_CLASS}>"
_IFC_TYPE: Final = f"<{vocab.TWIN_IFC_TYPE}>"
_MATERIAL: Final = f"<{vocab.TWIN_MATERIAL}>"
_FACING_MATERIAL: Final = f"<{vocab.TWIN_FACING_MATERIAL}>"
_IS_STATIC: Final = f"<{vocab.TWIN_IS_STATIC}>"
_PREDEFINED_TYPE: Final = f"<{vocab.TWIN_PREDEFINED_TYPE}>"
_OPERATION_TYPE: Final = f"<{vocab.TWIN_OPERATION_TYPE}>"
_MESH_KERNEL: Final = f"<{vocab.TWIN_MESH_KERNEL}>"
_PLY: Final = ox.NamedNode(vocab.FOG_PLY_BINARY_LE)
_PLY_TEXT: Final = f"<{vocab.FOG_PLY_BINARY_LE}>"
_BASE64: Final = ox.NamedNode(vocab.XSD_BASE64)
MESH_QUADS_BYTES: Final = 32 << 20
"""Literal text per load of mesh quads (:meth:`ModelTriples.mesh_quads`): 32 MiB more at the peak, 4
loads on Janesville (each load costs about 0.01 s more than one)."""


def _iri(iri: str) -> str:
    return f"<{iri}>"


def _text(value: str) -> str:
    """An ``xsd:string`` literal in N-Triples."""
    return f'"{value.translate(_ESCAPES)}"'


def _typed(value: str, datatype: str) -> str:
    return f'"{value.translate(_ESCAPES)}"^^<{datatype}>'


def _integer(value: int) -> str:
    return f'"{int(value)}"^^<{vocab.XSD_INTEGER}>'


def _boolean(value: bool) -> str:
    return _TRUE if value else _FALSE


@dataclass(slots=True)
class _MeshLiteral:
    mesh: Mesh  # kept, so that its id() is not reused while the import runs
    text: str  # base64 PLY
    literal: ox.Literal | None = None  # made when first needed
    in_text: bool = False  # a part has written it as text


class MeshLiterals:
    """The mesh literals of one import, each encoded once and shared by all its parts: its base64 PLY
    text, the literal object (made when first needed), and whether a part has written it as text."""

    __slots__ = ("_of",)

    def __init__(self) -> None:
        self._of: dict[int, _MeshLiteral] = {}

    def text(self, mesh: Mesh) -> str:
        return self._entry(mesh).text

    def literal(self, mesh: Mesh) -> ox.Literal:
        entry = self._entry(mesh)
        if entry.literal is None:
            entry.literal = ox.Literal(entry.text, datatype=_BASE64)
        return entry.literal

    def first_text(self, mesh: Mesh) -> bool:
        """True the first time it is asked for ``mesh``: write its literal as text then, as an object
        after (the store parses and hashes each copy of a text: Janesville's instances repeat 105 MB
        of literals that are 7.8 MB once each)."""
        entry = self._entry(mesh)
        first, entry.in_text = not entry.in_text, True
        return first

    def _entry(self, mesh: Mesh) -> _MeshLiteral:
        entry = self._of.get(id(mesh))
        if entry is None:
            entry = self._of[id(mesh)] = _MeshLiteral(mesh, encode_mesh(mesh))
        return entry


class ModelTriples:
    """Triples being collected: N-Triples lines, plus the mesh triples as objects (instances share
    one literal object). With ``meshes_as_text``, the first triple of each mesh literal is a line too,
    so that the store parses it without the GIL; the instances' copies stay objects."""

    def __init__(self, literals: MeshLiterals | None = None, *, meshes_as_text: bool = False) -> None:
        self.lines: list[str] = []
        self.meshes: list[tuple[str, ox.Literal, int]] = []  # (geometry node IRI, mesh literal, its size)
        self._literals = literals if literals is not None else MeshLiterals()  # also across parts
        self._as_text = meshes_as_text

    def add(self, subject: str, predicate: str, obj: str) -> None:
        """Add one triple; each part is already in N-Triples syntax (``<iri>`` or a literal)."""
        self.lines.append(f"{subject} {predicate} {obj} .\n")

    def geometry(self, node: str, geometry: Geometry, placement: str) -> None:
        """The geometry node of ``node`` (an IRI): mesh, placement (``placement``, its
        :func:`~twin.graph.meshcodec.encode_placement` text), closedness, solidity, triangle count."""
        g = vocab.geometry_iri(node)
        mesh = geometry.mesh
        if self._as_text and self._literals.first_text(mesh):
            text = self._literals.text(mesh)
            self.add(_iri(g), _PLY_TEXT, f'"{text}"^^<{vocab.XSD_BASE64}>')  # base64: nothing to escape
        else:
            self.meshes.append((g, self._literals.literal(mesh), len(self._literals.text(mesh))))
        g = _iri(g)
        self.add(_iri(node), _HAS_GEOMETRY, g)
        self.add(g, _TYPE, _GEOMETRY)
        self.add(g, _PLACEMENT, _typed(placement, vocab.TWIN_MATRIX4))
        self.add(g, _CLOSED, _boolean(mesh.closed))
        self.add(g, _TRIANGLES, _integer(mesh.triangle_count))
        if mesh.solid:
            self.add(g, _SOLID, _boolean(True))

    def data(self, source: str) -> bytes:
        """The N-Triples text (UTF-8); ModelError if some text cannot be encoded (a lone surrogate)."""
        try:
            return "".join(self.lines).encode("utf-8")
        except UnicodeEncodeError as err:
            msg = f"{source}: the model cannot be written as RDF: {err}"
            raise ModelError(msg) from err

    def quads(self, source: str) -> Iterator[ox.Quad]:
        """Every triple as a quad in the default graph."""
        yield from ox.parse(self.data(source), format=ox.RdfFormat.N_QUADS)
        for quads in self.mesh_quads():
            yield from quads

    def mesh_quads(self, max_bytes: int = MESH_QUADS_BYTES) -> Iterator[list[ox.Quad]]:
        """The mesh triples that are objects (not lines), as quads in the default graph, in lists of
        at most ``max_bytes`` of literal text (or one quad): the store copies every literal of a load
        at once, which would hold each instance's copy (on Janesville 105 MB) at the same time."""
        chunk: list[ox.Quad] = []
        size = 0
        for node, ply, n in self.meshes:
            if chunk and size + n > max_bytes:
                yield chunk
                chunk, size = [], 0
            chunk.append(ox.Quad(ox.NamedNode(node), _PLY, ply))
            size += n
        if chunk:
            yield chunk


def mint_iris(model: BuildingModel, base_iri: str) -> dict[str, str]:
    """GlobalId -> IRI for every rooted node; ModelError names a bad or duplicated GlobalId."""
    base = vocab.check_base(base_iri)
    iri_of: dict[str, str] = {}
    nodes = [
        *((s.guid, "IfcSite", s.name) for s in model.sites),
        *((b.guid, "IfcBuilding", b.name) for b in model.buildings),
        *((s.guid, "IfcBuildingStorey", s.name) for s in model.storeys),
        *((s.guid, "IfcSpace", s.name) for s in model.spaces),
        *((e.guid, e.ifc_class, e.name) for e in model.elements),
    ]
    for guid, ifc_class, name in nodes:
        try:
            iri = vocab.entity_iri(base, ifc_class, guid)
        except ModelError as err:
            msg = f"{model.source_name}: {ifc_class} {name!r} has an invalid GlobalId {guid!r}."
            raise ModelError(msg) from err
        if guid in iri_of:
            msg = (
                f"{model.source_name}: GlobalId {guid!r} is used twice ({ifc_class} {name!r} and "
                f"{iri_of[guid]}); GlobalIds must be unique."
            )
            raise ModelError(msg)
        iri_of[guid] = iri
    return iri_of


def checked_iris(model: BuildingModel, base_iri: str) -> dict[str, str]:
    """GlobalId -> ``<IRI>`` (N-Triples) of every rooted node, each IRI (and its geometry node's) checked
    as pyoxigraph checks it, so the text written later always parses."""
    iri_of = mint_iris(model, base_iri)
    # A minted IRI is a prefix (base, class, "_") and a UUID of hex digits and dashes, characters that
    # are valid wherever the prefix leaves off: one IRI per prefix decides for all that share it.
    # Where one fails, every IRI is checked in order, to name the first that fails.
    one_per_prefix = {iri[:-_UUID_CHARS]: iri for iri in reversed(iri_of.values())}
    checks = [vocab.model_iri(base_iri), *one_per_prefix.values()]
    if not all(_parses(vocab.geometry_iri(iri)) for iri in checks):
        checks = [vocab.model_iri(base_iri), *iri_of.values()]
    for iri in checks:
        try:
            ox.NamedNode(vocab.geometry_iri(iri))
        except ValueError as err:
            msg = f"{model.source_name}: the model cannot be written as RDF: {err} in IRI {iri!r}."
            raise ModelError(msg) from err
    return {guid: _iri(iri) for guid, iri in iri_of.items()}


_UUID_CHARS: Final = 36  # vocab.expand_guid: 32 hex digits and 4 dashes


def _parses(iri: str) -> bool:
    try:
        ox.NamedNode(iri)
    except ValueError:
        return False
    return True


def structure_triples(
    model: BuildingModel, iri_of: dict[str, str], *, base_iri: str, site: str
) -> ModelTriples:
    """The triples that need no geometry: the model node, the spatial tree, classes, names, materials,
    static flags, predefined and operation types, and relations."""
    out = ModelTriples()
    add = out.add

    def names(node: str, guid: str, name: str) -> None:
        add(node, _GLOBAL_ID, _text(guid))
        if name:
            label = _text(name)
            add(node, _NAME, label)
            add(node, _LABEL, label)

    m = _iri(vocab.model_iri(base_iri))
    add(m, _TYPE, _iri(vocab.TWIN_MODEL))
    add(m, _LABEL, _text(site))
    add(m, _iri(vocab.TWIN_SOURCE), _text(model.source_name))
    add(m, _iri(vocab.TWIN_SCHEMA), _text(model.schema))
    add(m, _iri(vocab.TWIN_SOURCE_LINES), _integer(model.source_lines))
    add(m, _iri(vocab.TWIN_REVISION), _integer(0))

    for s in model.sites:
        add(iri_of[s.guid], _TYPE, _iri(vocab.BOT_SITE))
        names(iri_of[s.guid], s.guid, s.name)
    for b in model.buildings:
        node = iri_of[b.guid]
        add(node, _TYPE, _iri(vocab.BOT_BUILDING))
        names(node, b.guid, b.name)
        if b.site_guid in iri_of:
            add(iri_of[b.site_guid], _iri(vocab.BOT_HAS_BUILDING), node)
    used_keys: set[str] = set()
    for st in sorted(model.storeys, key=lambda s: (s.elevation_m, s.name)):
        node = iri_of[st.guid]
        add(node, _TYPE, _iri(vocab.BOT_STOREY))
        names(node, st.guid, st.name)
        add(node, _iri(vocab.TWIN_ELEVATION), str(ox.Literal(float(st.elevation_m))))  # xsd:double
        add(node, _iri(vocab.TWIN_STOREY_KEY), _text(vocab.storey_key(st.name, used_keys)))
        if st.building_guid in iri_of:
            add(iri_of[st.building_guid], _iri(vocab.BOT_HAS_STOREY), node)
    for sp in model.spaces:
        node = iri_of[sp.guid]
        add(node, _TYPE, _iri(vocab.BOT_SPACE))
        names(node, sp.guid, sp.name)
        if sp.storey_guid in iri_of:
            add(iri_of[sp.storey_guid], _iri(vocab.BOT_HAS_SPACE), node)
    # Elements of a class share their class triples, elements of a material (set) their material
    # triples: each such run of ``predicate object .`` endings is written once and kept.
    classes: dict[tuple[str, tuple[str, ...]], list[str]] = {}
    materials: dict[tuple[tuple[str, ...], tuple[str, ...]], list[str]] = {}
    lines = out.lines
    for el in model.elements:
        node = iri_of[el.guid]
        key = (el.ifc_class, el.ifc_types)
        class_ends = classes.get(key)
        if class_ends is None:
            semantic = vocab.semantic_class(el.ifc_class)
            class_ends = [f" {_TYPE} {_BOT_ELEMENT} .\n"]
            if semantic is not None:
                class_ends.append(f" {_TYPE} {_iri(semantic)} .\n")
            class_ends.append(f" {_IFC_CLASS} {_text(el.ifc_class)} .\n")
            class_ends += [f" {_IFC_TYPE} {_text(t)} .\n" for t in el.ifc_types or (el.ifc_class,)]
            classes[key] = class_ends
        lines += [node + end for end in class_ends]
        names(node, el.guid, el.name)
        key_m = (el.materials, el.facing_materials)
        material_ends = materials.get(key_m)
        if material_ends is None:
            material_ends = [f" {_MATERIAL} {_text(m)} .\n" for m in el.materials]
            material_ends += [f" {_FACING_MATERIAL} {_text(m)} .\n" for m in el.facing_materials]
            materials[key_m] = material_ends
        lines += [node + end for end in material_ends]
        add(node, _IS_STATIC, _boolean(el.is_static))
        if el.predefined_type:
            add(node, _PREDEFINED_TYPE, _text(el.predefined_type))
        if el.operation_type:
            add(node, _OPERATION_TYPE, _text(el.operation_type))
    for rel, pred in (
        (model.adjacent, vocab.BOT_ADJACENT_ELEMENT),
        (model.contained, vocab.BOT_CONTAINS_ELEMENT),
        (model.decomposed, vocab.BOT_HAS_SUB_ELEMENT),
    ):
        p = _iri(pred)
        for r in sorted(rel, key=lambda r: (r.subject, r.object)):
            if r.subject in iri_of and r.object in iri_of:
                add(iri_of[r.subject], p, iri_of[r.object])
            else:
                log.debug(
                    "Skipping %s relation %s -> %s: an end is not in the model", pred, r.subject, r.object
                )
    return out


def geometry_nodes(out: ModelTriples, items: Sequence[tuple[str, Geometry, str]]) -> None:
    """The geometry nodes of elements or spaces: ``items`` are ``(<IRI>, geometry, kernel)`` (kernel ""
    for none, as for spaces); the placements are formatted all at once."""
    placements = encode_placements([g.placement for _, g, _ in items])
    for (node, geometry, kernel), placement in zip(items, placements, strict=True):
        out.geometry(node[1:-1], geometry, placement)
        if kernel:
            out.add(node, _MESH_KERNEL, _text(kernel))


def geometry_triples(
    model: BuildingModel,
    iri_of: dict[str, str],
    *,
    written: Mapping[str, Geometry] | None = None,
    bounds: Mapping[str, FloatArray] | None = None,
) -> ModelTriples:
    """The triples that need the meshes: storey extents, geometry nodes, kernels, failures, fallbacks.

    The geometry nodes of the GlobalIds in ``written`` (already written with that geometry, by
    :func:`geometry_nodes`) are left out; ModelError if the model's geometry is another. ``bounds``:
    :func:`~twin.graph.extents.geometry_bounds` of written geometry, for the storey extents.
    """
    written = written or {}
    out = ModelTriples()
    extents = storey_extents(model, bounds)
    for st in model.storeys:
        if st.guid in extents:
            out.add(iri_of[st.guid], _iri(vocab.TWIN_EXTENT), _text(format_extent(extents[st.guid])))

    def unwritten(guid: str, geometry: Geometry | None) -> bool:
        if geometry is None:
            return False
        if guid not in written:
            return True
        if written[guid] is not geometry:
            msg = f"{model.source_name}: the geometry of {guid} is not the one written before."
            raise ModelError(msg)
        return False

    items = [(iri_of[sp.guid], sp.geometry, "") for sp in model.spaces if unwritten(sp.guid, sp.geometry)]
    items += [
        (iri_of[el.guid], el.geometry, el.mesh_kernel)
        for el in model.elements
        if unwritten(el.guid, el.geometry)
    ]
    geometry_nodes(out, [(node, g, kernel) for node, g, kernel in items if g is not None])
    failed = set(model.mesh_failures)
    fallbacks = set(model.kernel_fallbacks)
    for el in model.elements:
        node = iri_of[el.guid]
        if el.guid in failed:
            out.add(node, _iri(vocab.TWIN_MESH_FAILED), _TRUE)
        if el.guid in fallbacks:
            out.add(node, _iri(vocab.TWIN_KERNEL_FALLBACK), _TRUE)
    return out


def model_quads(model: BuildingModel, *, base_iri: str, site: str) -> Iterator[ox.Quad]:
    """All triples (in the default graph) of ``model``; IRIs minted under ``base_iri``."""
    base_iri = vocab.check_base(base_iri)
    iri_of = checked_iris(model, base_iri)
    yield from structure_triples(model, iri_of, base_iri=base_iri, site=site).quads(model.source_name)
    yield from geometry_triples(model, iri_of).quads(model.source_name)
