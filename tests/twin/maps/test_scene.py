from __future__ import annotations

import numpy as np

from twin.maps.scene import MeshSet, SlabBox
from twin.records import Mesh

BOX_V = np.array([[x, y, z] for x in (0.0, 1) for y in (0.0, 1) for z in (0.0, 1)])
BOX_F = np.array(
    [
        [0, 1, 3],
        [0, 3, 2],
        [4, 6, 7],
        [4, 7, 5],
        [0, 4, 5],
        [0, 5, 1],
        [2, 3, 7],
        [2, 7, 6],
        [0, 2, 6],
        [0, 6, 4],
        [1, 5, 7],
        [1, 7, 3],
    ],
    dtype=np.int32,
)


def _placed(dx: float) -> np.ndarray:
    m = np.eye(4)
    m[0, 3] = dx
    return m


def test_bounds_are_world_boxes_of_the_placed_meshes() -> None:
    ms = MeshSet.build([("a", Mesh(BOX_V, BOX_F, True), _placed(100.0))])
    np.testing.assert_array_equal(ms.bounds[0], [100, 0, 0, 101, 1, 1])


def test_an_empty_mesh_has_no_bounds_and_never_overlaps() -> None:
    empty = Mesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32), False)
    ms = MeshSet.build([("a", Mesh(BOX_V, BOX_F, True), _placed(100.0)), ("b", empty, np.eye(4))])
    assert np.isnan(ms.bounds[1]).all()
    ids = np.arange(2, dtype=np.intp)
    near = ms.overlapping(ids, SlabBox(-1e9, -1e9, 1e9, 1e9, z_lo=-1e9, z_hi=1e9))
    assert near.tolist() == [0]


def test_triangles_of_returns_each_elements_triangles_with_their_owner() -> None:
    ms = MeshSet.build(
        [("a", Mesh(BOX_V, BOX_F, True), _placed(0.0)), ("b", Mesh(BOX_V, BOX_F[:2], False), _placed(5.0))]
    )
    tris, owner = ms.triangles_of(np.array([1, 0], dtype=np.intp))
    assert tris.shape == (14, 3, 3)
    assert owner.tolist() == [0, 0] + [1] * 12
    assert tris[0, :, 0].min() == 5.0
