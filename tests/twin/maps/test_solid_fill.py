"""Solids whose meshes are not watertight are filled where their section is made of closed loops.

The meshes here are what kernels deliver for closed solids: faces triangulated one by one, so a face
split where its neighbour is not leaves T-junctions; bodies of one element touching along a face;
vertex copies a rounding error apart. They are checked against the same solids' watertight meshes
(filled exactly, see ``test_raster.py``), and kept apart from true surfaces and broken meshes, which
keep their outline.
"""

from __future__ import annotations

import base64
from dataclasses import replace
from itertools import pairwise

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.conftest import imported
from tests.twin.box_lab import OX, OY, box_lab
from tests.twin.live_helpers import box_turtle, observe, started
from twin.graph.meshcodec import decode_mesh, encode_mesh
from twin.graph.vocab import entity_iri
from twin.maps.grid import GridFrame, Window
from twin.maps.meshops import closes_around, is_closed, orient_faces, orient_shells, seal_t_junctions
from twin.maps.raster import closed_sections
from twin.maps.render import MapPlan, occupancy
from twin.maps.scene import MeshSet, StoreyInfo
from twin.records import BuildingModel, Element, Geometry, Mesh, Relation
from twin.selection.skills import parse_skill

XYZ = tuple[float, float, float]


def _rotation_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def box_faces(lo: XYZ, hi: XYZ, *, split_y: tuple[float, ...] = (), split_z: tuple[float, ...] = ()) -> list:
    """Outward quads of the box ``lo``-``hi``; the -x face cut into strips at ``split_y``, the -y face
    at ``split_z`` (their neighbours whole: T-junctions)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    ys = [y0, *split_y, y1]
    zs = [z0, *split_z, z1]
    faces = [
        [(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)],
        [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],
        [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)],
        [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)],
    ]
    faces += [[(x0, a, z0), (x0, a, z1), (x0, b, z1), (x0, b, z0)] for a, b in pairwise(ys)]
    faces += [[(x0, y0, a), (x1, y0, a), (x1, y0, b), (x0, y0, b)] for a, b in pairwise(zs)]
    return faces


def mesh_of(quads: list, *, tilt: float = 0.0, jitter: float = 0.0, seed: int = 0) -> Mesh:
    """Quads triangulated one by one (a kernel's face-by-face mesh), tilted about x; with ``jitter``,
    every face gets its own vertex copies moved by up to that many metres."""
    rng = np.random.default_rng(seed)
    points: dict[XYZ, int] = {}
    vertices: list[np.ndarray] = []
    faces = []
    for quad in quads:
        ids = []
        for p in quad:
            if jitter:
                vertices.append(np.array(p) + rng.uniform(-jitter, jitter, 3))
                ids.append(len(vertices) - 1)
            else:
                if p not in points:
                    points[p] = len(vertices)
                    vertices.append(np.array(p, dtype=float))
                ids.append(points[p])
        faces += [[ids[0], ids[1], ids[2]], [ids[0], ids[2], ids[3]]]
    v = np.array(vertices) @ _rotation_x(tilt).T
    return Mesh(v, np.array(faces, dtype=np.int32), closed=False, solid=True)


def as_triangles(*meshes: Mesh) -> tuple[np.ndarray, np.ndarray]:
    tri = np.concatenate([m.vertices[m.faces] for m in meshes])
    owner = np.concatenate([np.full(len(m.faces), i, dtype=np.intp) for i, m in enumerate(meshes)])
    return tri, owner


LIFT = box_faces((0.0, 0.0, 0.0), (1.6, 1.2, 3.0), split_y=(0.35, 0.8), split_z=(1.1,))


def test_a_kernel_s_face_by_face_mesh_of_a_box_is_open_but_its_sections_are_closed_loops() -> None:
    mesh = mesh_of(LIFT, tilt=0.3)
    assert not is_closed(mesh.faces)
    tri, owner = as_triangles(mesh)
    for z in (0.3, 0.75, 1.1, 1.5, 2.9):
        assert closed_sections(tri, owner, 1, z).tolist() == [True], z


def test_vertex_copies_a_rounding_error_apart_still_close_the_section() -> None:
    tri, owner = as_triangles(mesh_of(LIFT, tilt=0.2, jitter=1e-10))
    assert closed_sections(tri, owner, 1, 1.5).tolist() == [True]


def test_bodies_touching_along_a_face_close_the_section() -> None:
    a = mesh_of(box_faces((0.0, 0.0, 0.0), (1.0, 1.0, 3.0), split_z=(2.0,)))
    b = mesh_of(box_faces((1.0, 0.0, 0.0), (2.0, 1.0, 3.0), split_y=(0.5,)))
    tri, owner = as_triangles(a, b)
    assert closed_sections(tri, np.zeros_like(owner), 1, 1.5).tolist() == [True]


def test_a_surface_a_lost_face_or_faces_turned_inside_out_do_not_close_the_section() -> None:
    mesh = mesh_of(LIFT)
    lost = replace(mesh, faces=mesh.faces[2:])  # the bottom face is lost: its section stays closed
    no_wall = replace(mesh, faces=np.delete(mesh.faces, [4, 5], axis=0))  # the +x wall is lost
    flipped = mesh.faces.copy()
    flipped[6:8] = flipped[6:8, ::-1]  # the +y wall turned inside out
    inside_out = replace(mesh, faces=flipped)
    tri, owner = as_triangles(lost, no_wall, inside_out, mesh)
    assert closed_sections(tri, owner, 5, 1.5).tolist() == [True, False, False, True, False]
    assert closed_sections(tri, owner, 5, 3.5).tolist() == [False] * 5  # above it: nothing to fill


def test_a_face_by_face_mesh_closes_around_a_volume_and_a_ring_of_faces_or_a_lost_face_does_not() -> None:
    for tilt in (0.0, 0.3):
        mesh = mesh_of(LIFT, tilt=tilt)
        assert not is_closed(mesh.faces) and closes_around(mesh.vertices, mesh.faces), tilt
    watertight = mesh_of(box_faces((0.0, 0.0, 0.0), (1.0, 1.0, 1.0)))
    assert is_closed(watertight.faces) and closes_around(watertight.vertices, watertight.faces)
    ring = mesh_of(box_faces((0.0, 0.0, 0.0), (2.0, 1.5, 1.1))[2:])  # sides only: a railing round a void
    lost = mesh_of(LIFT[1:])  # the bottom face is lost
    for surface in (ring, lost):
        assert not closes_around(surface.vertices, surface.faces)
    a = mesh_of(box_faces((0.0, 0.0, 0.0), (1.0, 1.0, 3.0), split_z=(2.0,)))
    b = mesh_of(box_faces((1.0, 0.0, 0.0), (2.0, 1.0, 3.0), split_y=(0.5,)))
    both = np.concatenate([a.vertices, b.vertices])
    assert closes_around(both, np.concatenate([a.faces, b.faces + len(a.vertices)]))


def test_a_closed_surface_with_t_junctions_and_a_face_turned_inwards_is_sealed_and_oriented() -> None:
    mesh = mesh_of(LIFT, tilt=0.3)
    faces = mesh.faces.copy()
    faces[6:8] = faces[6:8, ::-1]  # the +y wall turned inwards: a surface model need not orient faces
    sealed = seal_t_junctions(mesh.vertices, faces)
    assert len(sealed) > len(faces)  # the long edges split at their neighbours' vertices
    oriented = orient_shells(sealed)
    assert oriented is not None and is_closed(oriented)
    tri, owner = as_triangles(replace(mesh, faces=oriented))
    assert closed_sections(tri, owner, 1, 1.5).tolist() == [True]
    ring = mesh_of(box_faces((0.0, 0.0, 0.0), (2.0, 1.5, 1.1))[2:])
    assert orient_shells(seal_t_junctions(ring.vertices, ring.faces)) is None, "a ring has no inside"


def test_shells_touching_along_an_edge_are_oriented_each_on_its_own() -> None:
    a = mesh_of(box_faces((0.0, 0.0, 0.0), (1.0, 1.0, 1.0)))
    b = mesh_of(box_faces((1.0, 1.0, 0.0), (2.0, 2.0, 1.0)))  # shares the edge x = y = 1 with a
    points: dict[tuple[float, ...], int] = {}
    vertices, faces = [], []
    for m in (a, b):
        for tri in m.vertices[m.faces]:
            faces.append([points.setdefault(tuple(p), len(points)) for p in tri.tolist()])
    vertices = np.array(list(points), dtype=np.float64)
    both = np.array(faces, dtype=np.int32)
    both[14:16] = both[14:16, ::-1]  # one side of b turned inwards
    assert not is_closed(both) and closes_around(vertices, both)
    assert orient_faces(both) is None, "four faces on the shared edge: not one shell"
    oriented = orient_shells(both)
    assert oriented is not None and is_closed(oriented)


FRAME = GridFrame.around(-0.5, -0.5, 2.5, 2.0, resolution_m=0.05, margin_m=0.0)


def _map(meshes: list[Mesh], window: Window | None = None) -> np.ndarray:
    """The cells the meshes occupy between 0.05 and 1.5 m on ``FRAME`` (or its ``window``)."""
    ms = MeshSet.build([(f"urn:e{i}", m, np.eye(4)) for i, m in enumerate(meshes)])
    skill = parse_skill("nav", {"kind": "navigation", "robot_height_m": 1.5})
    z = (0.05, 1.5)
    storey = StoreyInfo("urn:s", "s", "s", 0.0, (0.0, 0.0, 1.0, 1.0))
    plan = MapPlan(skill, storey, FRAME, z[0], z[1], np.arange(len(meshes)), np.empty(0, np.intp))
    return occupancy(ms, np.arange(len(meshes), dtype=np.intp), plan, window or FRAME.full)


@pytest.mark.parametrize("tilt", [0.0, 0.05])
def test_an_open_solid_fills_like_its_watertight_mesh_and_a_surface_keeps_its_outline(tilt: float) -> None:
    open_solid = mesh_of(LIFT, tilt=tilt)
    watertight = mesh_of(box_faces((0.0, 0.0, 0.0), (1.6, 1.2, 3.0)), tilt=tilt)
    watertight = replace(watertight, closed=True)
    assert is_closed(watertight.faces)
    filled, reference = _map([open_solid]), _map([watertight])
    np.testing.assert_array_equal(filled, reference)
    outline = _map([replace(open_solid, solid=False)])
    w = FRAME.window_for(0.4, 0.3, 1.2, 0.8)  # well inside
    assert filled[w.row0 : w.row1, w.col0 : w.col1].all()
    assert not outline[w.row0 : w.row1, w.col0 : w.col1].any(), "a surface is drawn as its outline only"


def test_a_thin_open_solid_never_vanishes_and_touching_ones_leave_no_gap() -> None:
    thin = mesh_of(box_faces((0.0, 0.0, 0.0), (0.01, 1.2, 3.0), split_y=(0.6,)))  # a 1 cm layer
    left = mesh_of(box_faces((0.2, 0.0, 0.0), (0.6, 1.0, 3.0), split_z=(2.0,)))
    right = mesh_of(box_faces((0.6, 0.0, 0.0), (1.1, 1.0, 3.0), split_y=(0.4,)))
    grid = _map([thin, left, right])
    assert grid[10:34, 10].all(), "the thin layer occupies its column"
    assert grid[10:30, 14:32].all(), "no free cell where the two bodies touch (x 0.2..1.1, y 0..1)"
    assert not grid[10:30, 13].any() and not grid[10:30, 32].any()


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_any_window_of_open_solids_equals_the_full_map(data: st.DataObject) -> None:
    meshes = [mesh_of(LIFT, tilt=0.1), mesh_of(box_faces((1.7, -0.4, 0.0), (2.2, 1.8, 2.0), split_y=(0.1,)))]
    full = _map(meshes)
    h, w = FRAME.height, FRAME.width
    r0, c0 = data.draw(st.integers(0, h - 1)), data.draw(st.integers(0, w - 1))
    r1, c1 = data.draw(st.integers(r0 + 1, h)), data.draw(st.integers(c0 + 1, w))
    window = Window(r0, c0, r1, c1)
    np.testing.assert_array_equal(_map(meshes, window), full[r0:r1, c0:c1])


def test_the_solid_flag_round_trips_through_the_mesh_literal_and_older_literals_stay_surfaces() -> None:
    mesh = mesh_of(LIFT)
    again = decode_mesh(encode_mesh(mesh))
    assert again.solid and not again.closed
    plain = replace(mesh, solid=False)
    text = encode_mesh(plain)
    assert b"solid" not in base64.b64decode(text), "a literal without the flag is as before"
    assert not decode_mesh(text).solid


def _lab_with_lift() -> tuple[BuildingModel, str]:
    """The box lab with a lift in room B whose mesh is a solid's face-by-face (open) mesh."""
    model = box_lab()
    storey = model.storeys[0]
    mesh = mesh_of(LIFT)
    placement = np.eye(4)
    placement[:3, 3] = (OX + 9.0, OY + 1.5, 0.0)
    lift = Element(
        guid="0" + "9" * 21,
        ifc_class="IfcTransportElement",
        name="Lift",
        materials=("Steel",),
        facing_materials=("Steel",),
        is_static=True,
        geometry=Geometry(mesh, placement),
        ifc_types=("IfcTransportElement", "IfcElement", "IfcProduct"),
    )
    model = replace(
        model,
        elements=(*model.elements, lift),
        contained=model.contained | {Relation(storey.guid, lift.guid)},
    )
    return model, entity_iri("https://example.org/test#", "IfcTransportElement", lift.guid)


def test_the_imported_lift_is_filled_in_the_live_maps_and_its_graph_node_says_solid() -> None:
    model, iri = _lab_with_lift()
    store = imported(model)
    assert store.ask(f"ASK {{ <{iri}> omg:hasGeometry/twin:solid true }}"), "twin:solid on the geometry node"
    service, _ = started(store)
    m = service.live_maps.skill_maps[("ground-floor", "navigation")]
    f = m.plan.frame
    w = f.window_for(OX + 9.2, OY + 1.7, OX + 10.4, OY + 2.5)
    assert (m.data[w.row0 : w.row1, w.col0 : w.col1] == 100).all(), "the inside of the lift is occupied"


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    moves=st.lists(
        st.tuples(st.floats(8.0, 11.5), st.floats(0.5, 3.5), st.floats(0.05, 1.5), st.booleans()),
        min_size=1,
        max_size=5,
    )
)
def test_incremental_maps_around_an_open_solid_equal_a_full_rebuild(moves: list) -> None:
    model, _ = _lab_with_lift()
    store = imported(model)
    service, _ = started(store)
    for i, (x, y, size, remove) in enumerate(moves):
        name = f"urn:robot:crate-{i % 2}"
        payload = f"<{name}> <https://w3id.org/building-twin#removed> true .".encode() if remove else None
        observe(service, "robot1", payload or box_turtle(name, x, y, sx=size, sy=size))
    for key, m in service.live_maps.skill_maps.items():
        np.testing.assert_array_equal(
            m.data, service.live_maps.rebuild(m), err_msg=f"{key} vs its own rebuild"
        )
