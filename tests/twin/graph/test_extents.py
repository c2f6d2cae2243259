"""Storey extents: the boxes of all instances at once equal the boxes computed one by one, bit for bit.

The extents are stored as text (``repr`` of each bound), so a bound one unit in the last place off
would change the graph: the batched computation must give the very same floats as the plain one,
including the sign of a zero bound.
"""

from __future__ import annotations

import numpy as np

from twin.graph.extents import _bounds, _instance_bounds, geometry_bounds, storey_extents
from twin.maps.shapes import box_mesh, box_placement
from twin.records import BuildingModel, Element, Geometry, Mesh, Relation, Storey


def _random_geometries(seed: int) -> list[Geometry]:
    rng = np.random.default_rng(seed)
    meshes = []
    for _ in range(12):
        n = int(rng.integers(3, 40))
        vertices = rng.normal(size=(n, 3)) * float(rng.choice([0.01, 1.0, 50.0]))
        faces = rng.integers(0, n, size=(int(rng.integers(1, 20)), 3)).astype(np.int32)  # some unused
        meshes.append(Mesh(vertices, faces, closed=False))
    meshes.append(box_mesh(1.0, 2.0, 3.0))
    # A mesh touching the origin and an unrotated placement: bounds of exactly (signed) zero.
    meshes.append(
        Mesh(
            np.array([[0.0, 0.0, 0.0], [-0.0, 1.0, 0.0], [1.0, -0.0, 0.5]]),
            np.array([[0, 1, 2]], dtype=np.int32),
            closed=False,
        )
    )
    yaws = [0.0, 0.5, float(np.pi / 2), 2.0]
    out = []
    for _ in range(300):
        mesh = meshes[int(rng.integers(len(meshes)))]
        centre = rng.normal(size=3) * 20 if rng.random() < 0.7 else np.zeros(3) * rng.choice([1.0, -1.0])
        placement = box_placement(*centre, yaw=yaws[int(rng.integers(len(yaws)))])
        if rng.random() < 0.2:
            placement[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0]  # any rotation
        if rng.random() < 0.1:
            placement[0, 1] = -0.0
        out.append(Geometry(mesh, placement))
    return out


def test_the_boxes_of_all_instances_at_once_equal_the_boxes_one_by_one_bit_for_bit() -> None:
    for seed in range(5):
        geometries = _random_geometries(seed)
        expected = np.stack([_bounds(g) for g in geometries])
        got = _instance_bounds(geometries)
        assert got.shape == (len(geometries), 4)
        assert got.tobytes() == expected.tobytes()


def test_instances_sharing_a_mesh_each_get_their_own_placed_box() -> None:
    mesh = box_mesh(2.0, 1.0, 1.0)
    geometries = [
        Geometry(mesh, box_placement(10.0, 0.0, 0.0)),
        Geometry(mesh, box_placement(0.0, 5.0, 0.0, yaw=np.pi / 2)),
    ]
    got = _instance_bounds(geometries)
    assert np.allclose(got[0], [9.0, -0.5, 11.0, 0.5])
    assert np.allclose(got[1], [-0.5, 4.0, 0.5, 6.0])


def test_no_instances_give_no_boxes() -> None:
    assert _instance_bounds([]).shape == (0, 4)


def test_boxes_worked_out_in_parts_as_the_meshes_come_give_the_same_extents_bit_for_bit() -> None:
    """An import computes the boxes part by part while it meshes; the storey extents made from them
    are those made from the whole model at the end, and a geometry left out of the parts is computed."""
    geometries = _random_geometries(11)
    storeys = (Storey("S1", "Ground", 0.0, None), Storey("S2", "First", 3.0, None))
    elements = tuple(
        Element(f"E{i}", "IfcWall", f"wall {i}", (), True, geometry=g) for i, g in enumerate(geometries)
    )
    contained = frozenset(Relation("S1" if i % 3 else "S2", e.guid) for i, e in enumerate(elements))
    model = BuildingModel(
        source_name="parts.ifc",
        schema="IFC4",
        source_lines=0,
        sites=(),
        buildings=(),
        storeys=storeys,
        spaces=(),
        elements=elements,
        adjacent=frozenset(),
        contained=contained,
        decomposed=frozenset(),
    )
    whole = storey_extents(model)
    known: dict[str, np.ndarray] = {}
    items = [(e.guid, e.geometry) for e in elements if e.geometry is not None]
    for lo in range(0, len(items) - 7, 37):  # parts of 37, the last seven left to storey_extents
        known.update(geometry_bounds(items[lo : lo + 37]))
    assert 0 < len(known) < len(items)
    got = storey_extents(model, known)
    assert got == whole and len(got) == 2
    assert all(np.array(got[s]).tobytes() == np.array(whole[s]).tobytes() for s in whole)
    told = dict(known, E0=np.array([-1e6, -1e6, 1e6, 1e6]))  # the boxes given are the ones used
    assert storey_extents(model, told)["S2"] == (-1e6, -1e6, 1e6, 1e6)


def test_a_box_does_not_depend_on_what_else_is_rotated_with_it() -> None:
    """A mesh whose faces use a single vertex, alone or among others of its rotation: the same box bit
    for bit (a one-row matrix product rounded otherwise than the same row in a larger product)."""
    rng = np.random.default_rng(5)
    point = Mesh(rng.normal(size=(1, 3)) * 7.3, np.array([[0, 0, 0]], dtype=np.int32), closed=False)
    placement = box_placement(1.25, -3.5, 0.0, yaw=0.7)
    alone = _instance_bounds([Geometry(point, placement)])
    for seed in range(20):
        others = [Geometry(g.mesh, placement) for g in _random_geometries(seed)[:30]]
        among = _instance_bounds([*others, Geometry(point, placement)])
        assert among[-1].tobytes() == alone[0].tobytes()
