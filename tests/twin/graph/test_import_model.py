"""The graph an import writes, checked against a plain reference writer.

``import_model`` writes most triples as N-Triples text that pyoxigraph parses (fast); the reference
below builds every term as a pyoxigraph object, the obvious way. Both must give the same graph, term for
term, on a model with awkward text (quotes, backslashes, line breaks, non-ASCII), shared meshes, mesh
failures, fallbacks and relations to unknown ends.
"""

from __future__ import annotations

import dataclasses
import io
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pyoxigraph as ox
import pytest

import twin.graph.import_model
from tests.twin.box_lab import BASE, box_lab
from twin.errors import ModelError
from twin.graph import vocab
from twin.graph.extents import _bounds, format_extent, storey_extents
from twin.graph.import_model import ModelImport, import_model
from twin.graph.meshcodec import encode_mesh, encode_placement
from twin.graph.model_triples import MeshLiterals, ModelTriples, checked_iris, mint_iris
from twin.graph.store import EmbeddedStore, TextLoader
from twin.maps.shapes import box_mesh, box_placement
from twin.records import BuildingModel, Geometry, Mesh, Relation, Space, Storey


def _n(iri: str) -> ox.NamedNode:
    return ox.NamedNode(iri)


def _reference_quads(model: BuildingModel, *, base_iri: str, site: str) -> Iterator[ox.Quad]:
    """Every triple of ``model``, each term built as an object (the writer before the text one)."""
    iri_of = mint_iris(model, base_iri)
    plys: dict[int, ox.Literal] = {}

    def names(node: str, guid: str, name: str) -> Iterator[ox.Quad]:
        yield ox.Quad(_n(node), _n(vocab.PROPS_GLOBAL_ID), ox.Literal(guid))
        if name:
            yield ox.Quad(_n(node), _n(vocab.PROPS_NAME), ox.Literal(name))
            yield ox.Quad(_n(node), _n(vocab.RDFS_LABEL), ox.Literal(name))

    def geometry(node: str, geo: Geometry) -> Iterator[ox.Quad]:
        g = _n(vocab.geometry_iri(node))
        ply = plys.setdefault(id(geo.mesh), ox.Literal(encode_mesh(geo.mesh), datatype=_n(vocab.XSD_BASE64)))
        yield ox.Quad(_n(node), _n(vocab.OMG_HAS_GEOMETRY), g)
        yield ox.Quad(g, _n(vocab.RDF_TYPE), _n(vocab.OMG_GEOMETRY))
        yield ox.Quad(g, _n(vocab.FOG_PLY_BINARY_LE), ply)
        yield ox.Quad(
            g,
            _n(vocab.TWIN_PLACEMENT),
            ox.Literal(encode_placement(geo.placement), datatype=_n(vocab.TWIN_MATRIX4)),
        )
        yield ox.Quad(g, _n(vocab.TWIN_CLOSED), ox.Literal(geo.mesh.closed))
        yield ox.Quad(g, _n(vocab.TWIN_TRIANGLES), ox.Literal(geo.mesh.triangle_count))

    m = _n(vocab.model_iri(base_iri))
    yield ox.Quad(m, _n(vocab.RDF_TYPE), _n(vocab.TWIN_MODEL))
    yield ox.Quad(m, _n(vocab.RDFS_LABEL), ox.Literal(site))
    yield ox.Quad(m, _n(vocab.TWIN_SOURCE), ox.Literal(model.source_name))
    yield ox.Quad(m, _n(vocab.TWIN_SCHEMA), ox.Literal(model.schema))
    yield ox.Quad(m, _n(vocab.TWIN_SOURCE_LINES), ox.Literal(model.source_lines))
    yield ox.Quad(m, _n(vocab.TWIN_REVISION), ox.Literal(0))
    for s in model.sites:
        yield ox.Quad(_n(iri_of[s.guid]), _n(vocab.RDF_TYPE), _n(vocab.BOT_SITE))
        yield from names(iri_of[s.guid], s.guid, s.name)
    for b in model.buildings:
        yield ox.Quad(_n(iri_of[b.guid]), _n(vocab.RDF_TYPE), _n(vocab.BOT_BUILDING))
        yield from names(iri_of[b.guid], b.guid, b.name)
        if b.site_guid in iri_of:
            yield ox.Quad(_n(iri_of[b.site_guid]), _n(vocab.BOT_HAS_BUILDING), _n(iri_of[b.guid]))
    used: set[str] = set()
    extents = storey_extents(model)
    for st in sorted(model.storeys, key=lambda s: (s.elevation_m, s.name)):
        node = _n(iri_of[st.guid])
        yield ox.Quad(node, _n(vocab.RDF_TYPE), _n(vocab.BOT_STOREY))
        yield from names(iri_of[st.guid], st.guid, st.name)
        yield ox.Quad(node, _n(vocab.TWIN_ELEVATION), ox.Literal(float(st.elevation_m)))
        yield ox.Quad(node, _n(vocab.TWIN_STOREY_KEY), ox.Literal(vocab.storey_key(st.name, used)))
        if st.guid in extents:
            yield ox.Quad(node, _n(vocab.TWIN_EXTENT), ox.Literal(format_extent(extents[st.guid])))
        if st.building_guid in iri_of:
            yield ox.Quad(_n(iri_of[st.building_guid]), _n(vocab.BOT_HAS_STOREY), node)
    for sp in model.spaces:
        yield ox.Quad(_n(iri_of[sp.guid]), _n(vocab.RDF_TYPE), _n(vocab.BOT_SPACE))
        yield from names(iri_of[sp.guid], sp.guid, sp.name)
        if sp.storey_guid in iri_of:
            yield ox.Quad(_n(iri_of[sp.storey_guid]), _n(vocab.BOT_HAS_SPACE), _n(iri_of[sp.guid]))
        if sp.geometry is not None:
            yield from geometry(iri_of[sp.guid], sp.geometry)
    for el in model.elements:
        node = _n(iri_of[el.guid])
        yield ox.Quad(node, _n(vocab.RDF_TYPE), _n(vocab.BOT_ELEMENT))
        if (semantic := vocab.semantic_class(el.ifc_class)) is not None:
            yield ox.Quad(node, _n(vocab.RDF_TYPE), _n(semantic))
        yield ox.Quad(node, _n(vocab.TWIN_IFC_CLASS), ox.Literal(el.ifc_class))
        for t in el.ifc_types or (el.ifc_class,):
            yield ox.Quad(node, _n(vocab.TWIN_IFC_TYPE), ox.Literal(t))
        yield from names(iri_of[el.guid], el.guid, el.name)
        for mat in el.materials:
            yield ox.Quad(node, _n(vocab.TWIN_MATERIAL), ox.Literal(mat))
        for mat in el.facing_materials:
            yield ox.Quad(node, _n(vocab.TWIN_FACING_MATERIAL), ox.Literal(mat))
        yield ox.Quad(node, _n(vocab.TWIN_IS_STATIC), ox.Literal(el.is_static))
        if el.geometry is not None:
            yield from geometry(iri_of[el.guid], el.geometry)
            if el.mesh_kernel:
                yield ox.Quad(node, _n(vocab.TWIN_MESH_KERNEL), ox.Literal(el.mesh_kernel))
        if el.guid in model.mesh_failures:
            yield ox.Quad(node, _n(vocab.TWIN_MESH_FAILED), ox.Literal(True))
        if el.guid in model.kernel_fallbacks:
            yield ox.Quad(node, _n(vocab.TWIN_KERNEL_FALLBACK), ox.Literal(True))
    for rel, pred in (
        (model.adjacent, vocab.BOT_ADJACENT_ELEMENT),
        (model.contained, vocab.BOT_CONTAINS_ELEMENT),
        (model.decomposed, vocab.BOT_HAS_SUB_ELEMENT),
    ):
        for r in rel:
            if r.subject in iri_of and r.object in iri_of:
                yield ox.Quad(_n(iri_of[r.subject]), _n(pred), _n(iri_of[r.object]))


def _awkward_lab() -> BuildingModel:
    """The two-storey box lab with hard text, shared meshes, failures, fallbacks and a meshed space."""
    lab = box_lab(storeys=2)
    names = [
        'Wall "A" \\ west',
        "line\nbreak\rand\ttab",
        "Wärme — 断熱 😀\u2028",
        "back\\u0041slash \x00\x01\x7f",
        "",
    ]
    shared = box_mesh(0.5, 0.5, 0.5)
    elements = []
    for i, el in enumerate(lab.elements):
        changes: dict[str, object] = {"mesh_kernel": ("manifold", "opencascade", "")[i % 3]}
        if i < len(names):
            changes["name"] = names[i]
            changes["materials"] = (names[i] or "Brick", "Fiberglass Batt")
        if i % 4 == 1 and el.geometry is not None:  # instances of one representation share a Mesh
            changes["geometry"] = Geometry(shared, el.geometry.placement)
        if i == 7:
            changes["geometry"] = None
        elements.append(dataclasses.replace(el, **changes))  # type: ignore[arg-type]
    storeys = tuple(
        dataclasses.replace(st, elevation_m=e) for st, e in zip(lab.storeys, (-2.5e-7, 3.1), strict=True)
    )
    space = Space(
        "3" + "9" * 21, 'Room "B"', storeys[1].guid, Geometry(box_mesh(2, 3, 2.5), box_placement(5, 6, 1))
    )
    return dataclasses.replace(
        lab,
        source_name='lab "v2".ifc',
        source_lines=123456,
        storeys=(*storeys, Storey("2" + "8" * 21, "Roof\\Dach", 1e20, None)),
        spaces=(*lab.spaces, space),
        elements=tuple(elements),
        adjacent=lab.adjacent
        | {Relation(space.guid, elements[0].guid), Relation("unknown", elements[1].guid)},
        mesh_failures=(elements[7].guid,),
        kernel_fallbacks=(elements[2].guid, elements[5].guid),
    )


def _nquads(store: ox.Store) -> list[bytes]:
    buf = io.BytesIO()
    store.dump(buf, format=ox.RdfFormat.N_QUADS)
    return sorted(buf.getvalue().splitlines())


@pytest.mark.parametrize("min_part", [5_000, 1], ids=["one-load", "parallel-loads"])
def test_the_imported_graph_equals_the_reference_writers_term_for_term(
    min_part: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(twin.graph.import_model, "_MIN_PART", min_part)  # 1: the structure loads in halves
    model = _awkward_lab()
    expected = ox.Store()
    expected.extend(_reference_quads(model, base_iri=BASE, site='lab "x"'))
    with EmbeddedStore.open(None) as store:
        summary = import_model(store, model, base_iri=BASE, site='lab "x"')
        got = _nquads(store._store)
    assert summary.triples == len(expected)
    assert got == _nquads(expected)


def test_an_iri_that_cannot_be_written_is_a_model_error_and_the_store_is_untouched() -> None:
    lab = box_lab()
    bad = dataclasses.replace(lab, elements=(dataclasses.replace(lab.elements[0], ifc_class="IfcWall <x>"),))
    with EmbeddedStore.open(None) as store:
        with pytest.raises(ModelError, match="cannot be written as RDF"):
            import_model(store, bad, base_iri=BASE, site="lab")
        assert store.is_empty()


def test_world_bounds_use_only_the_vertices_some_face_uses() -> None:
    rng = np.random.default_rng(7)
    for _ in range(20):
        vertices = rng.normal(size=(50, 3)) * 10
        faces = rng.integers(0, 50, size=(rng.integers(1, 30), 3)).astype(np.int32)
        placement = box_placement(*rng.normal(size=3), yaw=float(rng.uniform(0, 6.3)))
        geometry = Geometry(Mesh(vertices, faces, closed=False), placement)
        world = vertices[np.unique(faces)] @ placement[:3, :3].T + placement[:3, 3]
        expected = np.concatenate([world.min(axis=0)[:2], world.max(axis=0)[:2]])
        got = _bounds(geometry)
        assert np.allclose(got, expected, rtol=0.0, atol=1e-9)  # rounded step by step, not as one product


class _QuadsOnly:
    """A GraphStore that takes quads only (like a remote store): no N-Triples text loading."""

    def __init__(self, inner: EmbeddedStore) -> None:
        self._inner = inner

    def __getattr__(self, name: str) -> object:
        if name == "bulk_load_ntriples":
            raise AttributeError(name)
        return getattr(self._inner, name)

    def __len__(self) -> int:
        return len(self._inner)


def test_a_store_that_takes_only_quads_gets_the_same_graph() -> None:
    model = _awkward_lab()
    with EmbeddedStore.open(None) as text, EmbeddedStore.open(None) as quads:
        import_model(text, model, base_iri=BASE, site="lab")
        assert not isinstance(_QuadsOnly(quads), TextLoader)
        import_model(_QuadsOnly(quads), model, base_iri=BASE, site="lab")  # type: ignore[arg-type]
        assert _nquads(quads._store) == _nquads(text._store)


def _with_bad_placement(model: BuildingModel) -> BuildingModel:
    el = model.elements[-1]
    assert el.geometry is not None
    bad = Geometry(el.geometry.mesh, np.full((4, 4), np.nan))
    return dataclasses.replace(model, elements=(*model.elements[:-1], dataclasses.replace(el, geometry=bad)))


def test_a_geometry_that_cannot_be_written_leaves_an_empty_store_empty_and_replace_keeps_the_old_graph(
    tmp_path: Path,
) -> None:
    bad = _with_bad_placement(box_lab())
    with EmbeddedStore.open(tmp_path / "store") as store:
        with pytest.raises(ModelError, match="placement"):
            import_model(store, bad, base_iri=BASE, site="lab")
        assert store.is_empty()
        import_model(store, box_lab(), base_iri=BASE, site="lab")
        before = _nquads(store._store)
        with pytest.raises(ModelError, match="placement"):
            import_model(store, bad, base_iri=BASE, site="lab", replace=True)
        assert _nquads(store._store) == before


@pytest.mark.parametrize("part_triangles", [400_000, 1], ids=["one-part", "a-part-per-mesh"])
def test_geometry_written_as_it_comes_gives_the_reference_graph(
    part_triangles: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The structure first, then each geometry on its own (in parts loaded in the background), then the
    rest: the graph is the reference writer's, term for term."""
    monkeypatch.setattr(twin.graph.import_model, "_PART_TRIANGLES", part_triangles)
    model = _awkward_lab()
    structure = dataclasses.replace(
        model,
        elements=tuple(dataclasses.replace(e, geometry=None) for e in model.elements),
        spaces=tuple(dataclasses.replace(s, geometry=None) for s in model.spaces),
        mesh_failures=(),
        kernel_fallbacks=(),
    )
    expected = ox.Store()
    expected.extend(_reference_quads(model, base_iri=BASE, site="lab"))
    with EmbeddedStore.open(None) as store:
        with ModelImport(store, base_iri=BASE, site="lab") as job:
            job.write_structure(structure)
            for e in reversed(model.elements[::2]):  # some, in any order; the rest come with finish()
                if e.geometry is not None:
                    job.add_geometry(e.guid, e.geometry, e.mesh_kernel)
            for s in model.spaces:
                if s.geometry is not None:
                    job.add_geometry(s.guid, s.geometry, "")
            summary = job.finish(model)
        assert summary.triples == len(expected)
        assert _nquads(store._store) == _nquads(expected)


def _import_in_steps(
    store: EmbeddedStore,
    model: BuildingModel,
    streamed: list[tuple[str, Geometry]],
    *,
    replace: bool = False,
    fail: str = "",
) -> None:
    """Structure, then ``streamed`` geometry, then finish (or raise RuntimeError(fail) before it)."""
    with ModelImport(store, base_iri=BASE, site="lab", replace=replace) as job:
        job.write_structure(model)
        for guid, geometry in streamed:
            job.add_geometry(guid, geometry, "manifold")
        if fail:
            raise RuntimeError(fail)
        job.finish(model)


def test_finishing_with_another_geometry_than_the_one_written_is_an_error_and_empties_the_store() -> None:
    model = box_lab()
    first = model.elements[0]
    assert first.geometry is not None
    other = Geometry(first.geometry.mesh, box_placement(1, 2, 0))
    with EmbeddedStore.open(None) as store:
        with pytest.raises(ModelError, match="not the one written before"):
            _import_in_steps(store, model, [(first.guid, other)])
        assert store.is_empty()


def test_geometry_for_a_guid_outside_the_structure_is_an_error_naming_it() -> None:
    model = box_lab()
    first = model.elements[0]
    assert first.geometry is not None
    with EmbeddedStore.open(None) as store:
        with pytest.raises(ModelError, match="'3nope"):
            _import_in_steps(store, model, [("3nope", first.geometry)])
        assert store.is_empty()


def test_replacing_writes_nothing_before_finish_and_keeps_the_old_graph_on_an_error() -> None:
    model = box_lab()
    first = model.elements[0]
    assert first.geometry is not None
    with EmbeddedStore.open(None) as store:
        import_model(store, model, base_iri=BASE, site="lab")
        before = _nquads(store._store)
        with pytest.raises(RuntimeError, match="meshing failed"):
            _import_in_steps(
                store, model, [(first.guid, first.geometry)], replace=True, fail="meshing failed"
            )
        assert _nquads(store._store) == before


def test_the_first_iri_that_cannot_be_written_is_named_whatever_class_comes_first() -> None:
    lab = box_lab()
    first, second, *rest = lab.elements
    bad = dataclasses.replace(
        lab,
        elements=(
            first,
            dataclasses.replace(second, ifc_class="IfcWall <x>"),
            *(dataclasses.replace(e, ifc_class="IfcDoor {y}") for e in rest[:1]),
            *rest[1:],
        ),
    )
    iri = f"{BASE}wall <x>_{vocab.expand_guid(second.guid)}"
    with pytest.raises(ModelError, match=f"in IRI '{iri}'"):
        checked_iris(bad, BASE)
    assert checked_iris(lab, BASE) == {g: f"<{i}>" for g, i in mint_iris(lab, BASE).items()}


def test_the_copies_of_a_mesh_literal_are_text_once_then_objects_loaded_a_few_at_a_time() -> None:
    """The first geometry node of a mesh carries its literal as text, its other instances the same
    literal object; those quads come in lists of at most ``max_bytes`` of literal text (one literal
    larger than that alone), every one of them once."""
    literals = MeshLiterals()
    small, large = box_mesh(1.0, 1.0, 1.0), box_mesh(2.0, 1.0, 1.0)
    part = ModelTriples(literals, meshes_as_text=True)
    nodes = [f"https://example.org/e{i}" for i in range(7)]
    for node, mesh in zip(nodes, [small, small, large, small, large, large, small], strict=True):
        part.geometry(node, Geometry(mesh), encode_placement(np.eye(4)))
    text = "".join(part.lines)
    assert text.count(encode_mesh(small)) == 1 and text.count(encode_mesh(large)) == 1
    later = ModelTriples(literals, meshes_as_text=True)  # a later part: text already written
    later.geometry("https://example.org/e7", Geometry(small), encode_placement(np.eye(4)))
    assert encode_mesh(small) not in "".join(later.lines) and len(later.meshes) == 1
    size = len(encode_mesh(small))
    chunks = list(part.mesh_quads(max_bytes=2 * size))
    quads = [q for chunk in chunks for q in chunk]
    firsts = {nodes[0], nodes[2]}  # the first node of each mesh has the text
    assert sorted(q.subject.value for q in quads) == sorted(
        vocab.geometry_iri(n) for n in nodes if n not in firsts
    )
    assert {q.object.value for q in quads} == {encode_mesh(small), encode_mesh(large)}
    assert all(sum(len(q.object.value) for q in chunk) <= 2 * size or len(chunk) == 1 for chunk in chunks)
    assert len(chunks) >= 2
