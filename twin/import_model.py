"""Import a building model into the graph store (the paper's Algorithm 1, records -> triples).

Every storey, space and element becomes a node with an IFCtoLBD IRI; spaces are ``bot:adjacentElement``
to the elements bounding them and ``bot:containsElement`` the elements they contain; elements carry
their class (BOT + BEO/FURN + the IFC class), GlobalId, name, materials, ``twin:isStatic`` and, through
``omg:hasGeometry``, their local mesh (a FOG PLY literal) and 4x4 placement.

Example::

    model = adapters.ifc.read_model(Path("lab.ifc"))
    with EmbeddedStore.open(Path("lab.store")) as store:
        summary = import_model(store, model, base_iri="https://example.org/lab#", site="lab")
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from dataclasses import dataclass

import pyoxigraph as ox

from twin import vocab
from twin.errors import ModelError, StoreNotEmptyError
from twin.extents import format_extent, storey_extents
from twin.meshcodec import encode_mesh, encode_placement
from twin.records import BuildingModel, Geometry
from twin.store import GraphStore

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class ImportSummary:
    triples: int
    elements: int
    meshes: int
    spaces: int
    storeys: int
    mesh_failures: tuple[str, ...]
    kernel_fallbacks: tuple[str, ...]


def _n(iri: str) -> ox.NamedNode:
    return ox.NamedNode(iri)


_TYPE = _n(vocab.RDF_TYPE)


def _geometry_quads(node: str, geometry: Geometry, cache: dict[int, ox.Literal]) -> Iterator[ox.Quad]:
    g = _n(vocab.geometry_iri(node))
    key = id(geometry.mesh)
    ply = cache.get(key)
    if ply is None:
        ply = ox.Literal(encode_mesh(geometry.mesh), datatype=_n(vocab.XSD_BASE64))
        cache[key] = ply
    yield ox.Quad(_n(node), _n(vocab.OMG_HAS_GEOMETRY), g)
    yield ox.Quad(g, _TYPE, _n(vocab.OMG_GEOMETRY))
    yield ox.Quad(g, _n(vocab.FOG_PLY_BINARY_LE), ply)
    yield ox.Quad(
        g,
        _n(vocab.TWIN_PLACEMENT),
        ox.Literal(encode_placement(geometry.placement), datatype=_n(vocab.TWIN_MATRIX4)),
    )
    yield ox.Quad(g, _n(vocab.TWIN_CLOSED), ox.Literal(geometry.mesh.closed))
    yield ox.Quad(g, _n(vocab.TWIN_TRIANGLES), ox.Literal(geometry.mesh.triangle_count))


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


def model_quads(model: BuildingModel, *, base_iri: str, site: str) -> Iterator[ox.Quad]:
    """All triples (in the default graph) of ``model``; IRIs minted under ``base_iri``."""
    iri_of = mint_iris(model, base_iri)

    def name_quads(node: str, guid: str, name: str) -> Iterator[ox.Quad]:
        yield ox.Quad(_n(node), _n(vocab.PROPS_GLOBAL_ID), ox.Literal(guid))
        if name:
            yield ox.Quad(_n(node), _n(vocab.PROPS_NAME), ox.Literal(name))
            yield ox.Quad(_n(node), _n(vocab.RDFS_LABEL), ox.Literal(name))

    m = _n(vocab.model_iri(vocab.check_base(base_iri)))
    yield ox.Quad(m, _TYPE, _n(vocab.TWIN_MODEL))
    yield ox.Quad(m, _n(vocab.RDFS_LABEL), ox.Literal(site))
    yield ox.Quad(m, _n(vocab.TWIN_SOURCE), ox.Literal(model.source_name))
    yield ox.Quad(m, _n(vocab.TWIN_SCHEMA), ox.Literal(model.schema))
    yield ox.Quad(m, _n(vocab.TWIN_SOURCE_LINES), ox.Literal(model.source_lines))
    yield ox.Quad(m, _n(vocab.TWIN_REVISION), ox.Literal(0))

    for s in model.sites:
        yield ox.Quad(_n(iri_of[s.guid]), _TYPE, _n(vocab.BOT_SITE))
        yield from name_quads(iri_of[s.guid], s.guid, s.name)
    for b in model.buildings:
        node = iri_of[b.guid]
        yield ox.Quad(_n(node), _TYPE, _n(vocab.BOT_BUILDING))
        yield from name_quads(node, b.guid, b.name)
        if b.site_guid in iri_of:
            yield ox.Quad(_n(iri_of[b.site_guid]), _n(vocab.BOT_HAS_BUILDING), _n(node))
    used_keys: set[str] = set()
    extents = storey_extents(model)
    for st in sorted(model.storeys, key=lambda s: (s.elevation_m, s.name)):
        node = iri_of[st.guid]
        yield ox.Quad(_n(node), _TYPE, _n(vocab.BOT_STOREY))
        yield from name_quads(node, st.guid, st.name)
        yield ox.Quad(_n(node), _n(vocab.TWIN_ELEVATION), ox.Literal(float(st.elevation_m)))
        yield ox.Quad(_n(node), _n(vocab.TWIN_STOREY_KEY), ox.Literal(vocab.storey_key(st.name, used_keys)))
        if st.guid in extents:
            yield ox.Quad(_n(node), _n(vocab.TWIN_EXTENT), ox.Literal(format_extent(extents[st.guid])))
        if st.building_guid in iri_of:
            yield ox.Quad(_n(iri_of[st.building_guid]), _n(vocab.BOT_HAS_STOREY), _n(node))
    cache: dict[int, ox.Literal] = {}
    for sp in model.spaces:
        node = iri_of[sp.guid]
        yield ox.Quad(_n(node), _TYPE, _n(vocab.BOT_SPACE))
        yield from name_quads(node, sp.guid, sp.name)
        if sp.storey_guid in iri_of:
            yield ox.Quad(_n(iri_of[sp.storey_guid]), _n(vocab.BOT_HAS_SPACE), _n(node))
        if sp.geometry is not None:
            yield from _geometry_quads(node, sp.geometry, cache)
    failed = set(model.mesh_failures)
    fallbacks = set(model.kernel_fallbacks)
    for el in model.elements:
        node = iri_of[el.guid]
        yield ox.Quad(_n(node), _TYPE, _n(vocab.BOT_ELEMENT))
        semantic = vocab.semantic_class(el.ifc_class)
        if semantic is not None:
            yield ox.Quad(_n(node), _TYPE, _n(semantic))
        yield ox.Quad(_n(node), _n(vocab.TWIN_IFC_CLASS), ox.Literal(el.ifc_class))
        for t in el.ifc_types or (el.ifc_class,):
            yield ox.Quad(_n(node), _n(vocab.TWIN_IFC_TYPE), ox.Literal(t))
        yield from name_quads(node, el.guid, el.name)
        for mat in el.materials:
            yield ox.Quad(_n(node), _n(vocab.TWIN_MATERIAL), ox.Literal(mat))
        for mat in el.facing_materials:
            yield ox.Quad(_n(node), _n(vocab.TWIN_FACING_MATERIAL), ox.Literal(mat))
        yield ox.Quad(_n(node), _n(vocab.TWIN_IS_STATIC), ox.Literal(el.is_static))
        if el.geometry is not None:
            yield from _geometry_quads(node, el.geometry, cache)
        if el.mesh_kernel and el.geometry is not None:
            yield ox.Quad(_n(node), _n(vocab.TWIN_MESH_KERNEL), ox.Literal(el.mesh_kernel))
        if el.guid in failed:
            yield ox.Quad(_n(node), _n(vocab.TWIN_MESH_FAILED), ox.Literal(True))
        if el.guid in fallbacks:
            yield ox.Quad(_n(node), _n(vocab.TWIN_KERNEL_FALLBACK), ox.Literal(True))
    for rel, pred in (
        (model.adjacent, vocab.BOT_ADJACENT_ELEMENT),
        (model.contained, vocab.BOT_CONTAINS_ELEMENT),
        (model.decomposed, vocab.BOT_HAS_SUB_ELEMENT),
    ):
        for r in sorted(rel, key=lambda r: (r.subject, r.object)):
            if r.subject in iri_of and r.object in iri_of:
                yield ox.Quad(_n(iri_of[r.subject]), _n(pred), _n(iri_of[r.object]))
            else:
                log.debug(
                    "Skipping %s relation %s -> %s: an end is not in the model", pred, r.subject, r.object
                )


def ensure_importable(store: GraphStore, *, replace: bool) -> None:
    """Raise StoreNotEmptyError if ``store`` holds a model and ``replace`` is unset (check before meshing)."""
    if not replace and not store.is_empty():
        msg = "The store already holds a model."
        raise StoreNotEmptyError(msg)


def import_model(
    store: GraphStore, model: BuildingModel, *, base_iri: str, site: str, replace: bool = False
) -> ImportSummary:
    """Write ``model`` into ``store``. A non-empty store is an error unless ``replace`` is set."""
    ensure_importable(store, replace=replace)
    quads = list(model_quads(model, base_iri=base_iri, site=site))  # every check passes before a clear
    if replace:
        store.clear()
    store.bulk_add(quads)
    meshes = sum(1 for e in model.elements if e.geometry is not None)
    if model.mesh_failures:
        log.info(
            "%d element(s) are in the graph without geometry (twin:meshFailed)", len(model.mesh_failures)
        )
    return ImportSummary(
        triples=len(store),
        elements=len(model.elements),
        meshes=meshes,
        spaces=len(model.spaces),
        storeys=len(model.storeys),
        mesh_failures=model.mesh_failures,
        kernel_fallbacks=model.kernel_fallbacks,
    )
