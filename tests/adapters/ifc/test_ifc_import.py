"""IFC -> graph: the graph must say exactly what the IFC file says (counts, relations, meshes, units)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from pathlib import Path

import ifcopenshell
import ifcopenshell.geom
import ifcopenshell.util.shape
import numpy as np
import pytest

from adapters.ifc import IfcFileError, read_model
from adapters.ifc.kernel_child import make_mesh
from adapters.ifc.sample_lab import write_lab
from tests.conftest import SHARED_MODELS, imported, shared_model
from twin.graph import vocab
from twin.graph.meshcodec import decode_mesh, decode_placement
from twin.graph.rdf import literal_value
from twin.graph.store import GraphStore
from twin.maps.shapes import box_mesh
from twin.records import BuildingModel
from twin.samples.lab_layout import LabLayout

pytestmark = pytest.mark.slow  # a daemon, robots or shared models: left out by make test-fast

MODELS = ["lab", *SHARED_MODELS]


@pytest.fixture(scope="module", params=MODELS)
def case(
    request: pytest.FixtureRequest,
    lab: tuple[Path, LabLayout],
    read_cached: Callable[[Path], BuildingModel],
) -> tuple[ifcopenshell.file, BuildingModel, GraphStore]:
    path = lab[0] if request.param == "lab" else shared_model(request.param)
    model = read_cached(path)
    return ifcopenshell.open(str(path)), model, imported(model)


def _guid_pairs(store: GraphStore, predicate: str, subject_class: str) -> set[tuple[str, str]]:
    rows = store.select(
        f"SELECT ?a ?b WHERE {{ ?s a {subject_class} ; {predicate} ?e . "
        "?s props:globalIdIfcRoot_attribute_simple ?a . ?e props:globalIdIfcRoot_attribute_simple ?b }"
    )
    return {(literal_value(r["a"]) or "", literal_value(r["b"]) or "") for r in rows}


def test_element_counts_per_class_equal_ifcopenshell_counts(case) -> None:
    f, _, store = case
    expected = Counter(e.is_a() for e in f.by_type("IfcElement"))
    rows = store.select(
        "SELECT ?c (COUNT(?e) AS ?n) WHERE { ?e a bot:Element ; twin:ifcClass ?c } GROUP BY ?c"
    )
    got = {literal_value(r["c"]): int(literal_value(r["n"]) or 0) for r in rows}
    assert got == dict(expected)


def test_spaces_and_storeys_counts_equal_ifcopenshell_counts(case) -> None:
    f, _, store = case
    for cls, ifc in (("bot:Space", "IfcSpace"), ("bot:Storey", "IfcBuildingStorey")):
        n = store.select(f"SELECT (COUNT(?s) AS ?n) WHERE {{ ?s a {cls} }}")[0]["n"]
        assert int(literal_value(n) or 0) == len(f.by_type(ifc)), cls


def test_adjacency_pairs_equal_the_files_space_boundaries(case) -> None:
    f, _, store = case
    expected = {
        (r.RelatingSpace.GlobalId, r.RelatedBuildingElement.GlobalId)
        for r in f.by_type("IfcRelSpaceBoundary")
        if r.RelatedBuildingElement is not None
        and r.RelatingSpace is not None
        and r.RelatingSpace.is_a("IfcSpace")
        and r.RelatedBuildingElement.is_a("IfcElement")
    }
    assert _guid_pairs(store, "bot:adjacentElement", "bot:Space") == expected


def test_containment_pairs_equal_the_files_spatial_containment(case) -> None:
    f, _, store = case
    expected = {
        (r.RelatingStructure.GlobalId, e.GlobalId)
        for r in f.by_type("IfcRelContainedInSpatialStructure")
        if any(
            r.RelatingStructure.is_a(t) for t in ("IfcSpace", "IfcBuildingStorey", "IfcBuilding", "IfcSite")
        )
        for e in r.RelatedElements
        if e.is_a("IfcElement")
    }
    got = set().union(
        *(
            _guid_pairs(store, "bot:containsElement", z)
            for z in ("bot:Space", "bot:Storey", "bot:Building", "bot:Site")
        )
    )
    assert got == expected


# Elements no kernel can mesh, per model: Janesville has two walls whose bodies mesh to nothing.
EXPECTED_FAILURES = {
    "revit2012_janesville_restaurant.ifc": {"0CZFXJxMD0IPFB4qXmF_Hx", "3ZfA0qgTb94uLn5wS785Vd"}
}


def test_every_element_with_a_body_has_a_mesh_except_the_known_failures(case) -> None:
    f, model, store = case
    with_body = {e.GlobalId for e in f.by_type("IfcElement") if e.Representation is not None}
    meshed = {e.guid for e in model.elements if e.geometry is not None}
    expected_failures = EXPECTED_FAILURES.get(model.source_name, set())
    assert set(model.mesh_failures) == expected_failures
    assert meshed == with_body - expected_failures
    flagged = store.select(
        "SELECT ?g WHERE { ?e twin:meshFailed true ; props:globalIdIfcRoot_attribute_simple ?g }"
    )
    assert {literal_value(r["g"]) for r in flagged} == expected_failures


def test_instances_of_one_representation_share_one_mesh_literal(case) -> None:
    _, model, store = case
    meshes = {id(e.geometry.mesh) for e in model.elements if e.geometry is not None}
    n = store.select(
        "SELECT (COUNT(DISTINCT ?ply) AS ?n) "
        "WHERE { ?e a bot:Element ; omg:hasGeometry/fog:asPly_v1.0-binaryLE ?ply }"
    )
    literals = int(literal_value(n[0]["n"]) or 0)
    meshed = sum(1 for e in model.elements if e.geometry is not None)
    assert literals <= len(meshes)
    if len(meshes) < meshed:  # instanced representations: fewer literals than meshed elements
        assert literals < meshed


def test_the_spatial_tree_and_decomposition_are_in_the_graph(case) -> None:
    f, _, store = case
    assert store.ask(
        "ASK { ?site a bot:Site ; bot:hasBuilding ?b . ?b a bot:Building ; bot:hasStorey ?s . "
        "?s a bot:Storey }"
    )
    space_pairs = {
        (sp.GlobalId, rel.RelatingObject.GlobalId)
        for sp in f.by_type("IfcSpace")
        for rel in sp.Decomposes or ()
        if rel.RelatingObject.is_a("IfcBuildingStorey")
    }
    got = {
        (literal_value(r["sp"]), literal_value(r["st"]))
        for r in store.select(
            "SELECT ?sp ?st WHERE { ?s bot:hasSpace ?x . ?s props:globalIdIfcRoot_attribute_simple ?st . "
            "?x props:globalIdIfcRoot_attribute_simple ?sp }"
        )
    }
    assert got == space_pairs
    voids = {
        (r.RelatingBuildingElement.GlobalId, r.RelatedOpeningElement.GlobalId)
        for r in f.by_type("IfcRelVoidsElement")
    }
    assert voids <= _guid_pairs(store, "bot:hasSubElement", "bot:Element")


def test_elements_carry_supertypes_and_lbd_classes(case) -> None:
    f, _, store = case
    walls = {e.GlobalId for e in f.by_type("IfcWall")}  # subtypes included
    rows = store.select(
        'SELECT ?g WHERE { ?e twin:ifcType "IfcWall" ; props:globalIdIfcRoot_attribute_simple ?g }'
    )
    assert {literal_value(r["g"]) for r in rows} == walls
    rows = store.select("SELECT ?g WHERE { ?e a beo:Wall ; props:globalIdIfcRoot_attribute_simple ?g }")
    assert {literal_value(r["g"]) for r in rows} == walls
    assert store.ask('ASK { ?e a bot:Element ; twin:ifcType "IfcElement" ; twin:isStatic ?s }')
    assert not store.ask(
        "ASK { ?e omg:hasGeometry ?g . FILTER NOT EXISTS { ?g a omg:Geometry ; fog:asPly_v1.0-binaryLE ?p ; "
        "twin:placement ?m ; twin:closedMesh ?c } }"
    )


def test_a_crashing_kernel_falls_back_without_losing_geometry(read_cached) -> None:
    model = read_cached(shared_model("Duplex_A_20110907.ifc"))  # manifold segfaults on this model
    assert model.kernel_fallbacks
    assert not model.mesh_failures


def _iris(store: GraphStore) -> set[str]:
    rows = store.select("SELECT ?n WHERE { ?n props:globalIdIfcRoot_attribute_simple ?g }")
    return {literal_value(r["n"]) or "" for r in rows}


def test_element_iris_follow_ifctolbd(case) -> None:
    _, model, store = case
    for element in model.elements[:50]:
        expected = (
            f"https://example.org/test#{element.ifc_class.lower()[3:]}_{vocab.expand_guid(element.guid)}"
        )
        assert store.ask(f"ASK {{ <{expected}> a bot:Element }}"), expected


def test_iris_are_stable_across_reimports_and_units(tmp_path: Path) -> None:
    metre, foot = tmp_path / "m.ifc", tmp_path / "ft.ifc"
    write_lab(metre, storeys=2)
    first = _iris(imported(read_model(metre)))
    write_lab(metre, storeys=2)  # generated again, read again
    assert _iris(imported(read_model(metre))) == first
    write_lab(foot, length_unit="foot", storeys=2)
    assert _iris(imported(read_model(foot))) == first
    assert all(iri.count("-") == 4 for iri in first)


def _world_vertices(store: GraphStore, guid: str) -> np.ndarray:
    rows = store.select(
        f'SELECT ?ply ?pl WHERE {{ ?e props:globalIdIfcRoot_attribute_simple "{guid}" ; omg:hasGeometry ?g . '
        "?g fog:asPly_v1.0-binaryLE ?ply ; twin:placement ?pl }"
    )
    mesh = decode_mesh(literal_value(rows[0]["ply"]) or "")
    m = decode_placement(literal_value(rows[0]["pl"]) or "")
    return mesh.vertices @ m[:3, :3].T + m[:3, 3]


def _assert_same_points(a: np.ndarray, b: np.ndarray, tol: float = 1e-6) -> None:
    """Every point of ``a`` is within ``tol`` of a point of ``b`` and vice versa."""
    for p, q in ((a, b), (b, a)):
        d = np.sqrt(((p[:, None, :] - q[None, :, :]) ** 2).sum(axis=2)).min(axis=1)
        assert d.max() <= tol, d.max()


def test_meshes_read_back_equal_ifcopenshell_world_meshes(case) -> None:
    f, model, store = case
    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)
    candidates = [  # meshed by manifold (not routed to OpenCASCADE, not a fallback)
        e
        for e in model.elements
        if e.geometry is not None and e.mesh_kernel == "manifold" and len(e.geometry.mesh.vertices) <= 1500
    ]
    rng = np.random.default_rng(7)
    sample = [
        candidates[i] for i in rng.choice(len(candidates), size=min(12, len(candidates)), replace=False)
    ]
    for element in sample:
        shape = ifcopenshell.geom.create_shape(settings, f.by_guid(element.guid), geometry_library="manifold")
        expected = np.asarray(ifcopenshell.util.shape.get_vertices(shape.geometry), dtype=float).reshape(
            -1, 3
        )
        _assert_same_points(_world_vertices(store, element.guid), expected)


def test_a_solid_whose_vertex_copies_lie_a_hair_apart_is_welded_into_a_closed_mesh() -> None:
    box = box_mesh(1.0, 2.0, 3.0)
    copies = box.vertices[box.faces].reshape(-1, 3)  # every triangle with its own vertices
    copies[::2, 0] += 1e-12  # as OpenCASCADE leaves them around a cut-out opening
    faces = np.arange(len(copies), dtype=np.int32).reshape(-1, 3)
    mesh = make_mesh(copies, faces)
    assert mesh.closed
    assert len(mesh.vertices) == 8
    assert len(mesh.faces) == len(box.faces)


def test_the_outside_wall_with_two_windows_cut_out_of_largebuilding_is_a_closed_solid(read_cached) -> None:
    model = read_cached(shared_model("LargeBuilding.ifc"))
    wall = next(e for e in model.elements if e.guid == "1F6umJ5H50aeL3A1As_wTm")
    assert wall.geometry is not None
    assert wall.geometry.mesh.closed, "its section must be filled in the maps, not only outlined"


def test_a_glass_wall_is_found_by_a_sparql_query_on_material(lab_store: GraphStore, lab) -> None:
    _, layout = lab
    rows = lab_store.select(
        "SELECT ?g WHERE { ?e a beo:Wall ; twin:material ?m ; props:globalIdIfcRoot_attribute_simple ?g . "
        'FILTER(CONTAINS(LCASE(?m), "glass")) }'
    )
    assert {literal_value(r["g"]) for r in rows} == {layout.glass_wall.global_id}


PAPER_SELECTION = """
SELECT ?g WHERE {
  ?e a bot:Element ; twin:ifcClass ?t ; props:globalIdIfcRoot_attribute_simple ?g .
  FILTER(?t NOT IN ("IfcOpeningElement", "IfcFurnishingElement",
                    "IfcBuildingElementProxy", "IfcFlowTerminal"))
  MINUS { ?e twin:material ?m . FILTER(CONTAINS(LCASE(?m), "glass")) }
}"""


def test_the_papers_selection_query_returns_the_walls_except_glass_on_the_sample(lab_store, lab) -> None:
    _, layout = lab
    got = {literal_value(r["g"]) for r in lab_store.select(PAPER_SELECTION)}
    kept = [*layout.walls, *layout.slabs, layout.door]
    expected = {e.global_id for e in kept} - {layout.glass_wall.global_id}
    assert got == expected
    assert layout.table.global_id not in got
    assert layout.arch.global_id in got


def test_storeys_have_elevations_names_and_keys(lab2, read_cached) -> None:
    path, layout = lab2
    store = imported(read_cached(path))
    rows = store.select(
        "SELECT ?name ?elev ?key WHERE { ?b bot:hasStorey ?s . ?s rdfs:label ?name ; twin:elevation ?elev ; "
        "twin:storeyKey ?key }"
    )
    got = {(literal_value(r["name"]), round(float(literal_value(r["elev"]) or 0), 6)) for r in rows}
    assert got == {(s.name, round(s.elevation_m, 6)) for s in layout.storeys}
    assert len({literal_value(r["key"]) for r in rows}) == len(rows)


def test_static_flag_follows_the_configured_types(lab_store: GraphStore, lab) -> None:
    _, layout = lab
    rows = lab_store.select(
        "SELECT ?g ?s WHERE { ?e twin:isStatic ?s ; props:globalIdIfcRoot_attribute_simple ?g }"
    )
    static = {literal_value(r["g"]): literal_value(r["s"]) == "true" for r in rows}
    assert static[layout.table.global_id] is False
    assert all(static[w.global_id] for w in layout.walls)


def test_a_feet_model_and_a_metres_model_give_the_same_coordinates(tmp_path: Path) -> None:
    metre, foot = tmp_path / "m.ifc", tmp_path / "ft.ifc"
    write_lab(metre, storeys=2)
    write_lab(foot, length_unit="foot", storeys=2)
    a, b = read_model(metre), read_model(foot)
    assert {s.guid: round(s.elevation_m, 9) for s in a.storeys} == {
        s.guid: round(s.elevation_m, 9) for s in b.storeys
    }
    geo_b = {e.guid: e.geometry for e in b.elements}
    # manifold grows an opening by a tolerance that depends on the file's unit: walls with openings
    # differ by up to 0.7 mm between the two files; everything else is equal to 1e-6 m
    voided = {
        r.subject
        for r in a.decomposed
        if r.object in {e.guid for e in a.elements if e.ifc_class == "IfcOpeningElement"}
    }
    for e in a.elements:
        ga, gb = e.geometry, geo_b[e.guid]
        assert ga is not None
        assert gb is not None
        va, vb = ga.world_vertices(), gb.world_vertices()
        if e.guid in voided:
            np.testing.assert_allclose(va.min(axis=0), vb.min(axis=0), atol=1e-3)
            np.testing.assert_allclose(va.max(axis=0), vb.max(axis=0), atol=1e-3)
        else:
            np.testing.assert_allclose(va, vb, atol=1e-6)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (None, "No such file"),
        (b"hello world\n", "not an IFC/STEP file"),
        (b"ISO-10303-21;\nHEADER;\nFILE_SCHEMA(('IFC4'));\nENDSEC;\nDATA;\n#1=IFCWALL(", "truncated"),
        (
            b"ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nFILE_NAME('','',(''),(''),'','','');\n"
            b"FILE_SCHEMA(('IFC9'));\nENDSEC;\nDATA;\nENDSEC;\nEND-ISO-10303-21;\n",
            "IFC9|schema",
        ),
        (
            b"ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nFILE_NAME('','',(''),(''),'','','');\n"
            b"FILE_SCHEMA(('IFC4'));\nENDSEC;\nDATA;\nENDSEC;\nEND-ISO-10303-21;\n",
            "empty model",
        ),
    ],
    ids=["missing", "not-step", "truncated", "unsupported-schema", "empty"],
)
def test_bad_files_raise_an_error_naming_the_problem(
    tmp_path: Path, content: bytes | None, message: str
) -> None:
    path = tmp_path / "bad.ifc"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(IfcFileError, match=message):
        read_model(path)


def test_a_model_without_spaces_imports_with_a_warning_and_no_adjacency(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    path = tmp_path / "nospace.ifc"
    write_lab(tmp_path / "lab.ifc")
    f = ifcopenshell.open(str(tmp_path / "lab.ifc"))
    for space in f.by_type("IfcSpace"):
        f.remove(space)
    f.write(str(path))
    with caplog.at_level("WARNING"):
        model = read_model(path)
    assert any("has no IfcSpace" in r.getMessage() for r in caplog.records)
    store = imported(model)
    assert not store.ask("ASK { ?s bot:adjacentElement ?e }")
    assert len(model.elements) == len(f.by_type("IfcElement"))
    assert store.ask("ASK { ?st a bot:Storey ; bot:containsElement ?e . ?e omg:hasGeometry ?g }")


def test_a_bad_or_duplicated_globalid_is_named_and_replace_keeps_the_old_graph(lab_model) -> None:
    from dataclasses import replace

    from twin.errors import ModelError
    from twin.graph.import_model import import_model

    store = imported(lab_model)
    before = len(store)
    bad = replace(lab_model.elements[0], guid="not a guid")
    broken = replace(lab_model, elements=(bad, *lab_model.elements[1:]))
    with pytest.raises(ModelError, match="invalid GlobalId 'not a guid'"):
        import_model(store, broken, base_iri="https://example.org/test#", site="t", replace=True)
    assert len(store) == before
    twice = replace(lab_model, elements=(*lab_model.elements, lab_model.elements[0]))
    with pytest.raises(ModelError, match="used twice"):
        import_model(store, twice, base_iri="https://example.org/test#", site="t", replace=True)
    assert len(store) == before
