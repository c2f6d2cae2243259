from __future__ import annotations

import numpy as np

from twin.maps.points import triangle_normals
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


def test_triangle_normals_come_from_the_local_mesh_and_do_not_change_where_the_building_sits() -> None:
    # slivers (a tessellated gutter's: 2 m long, 0.3 mm wide), turned and mirrored, placed near the
    # origin and 10 km away: the world triangles round differently, and so would normals taken from
    # them (a few in a thousand change a bit); those of the local mesh keep every bit
    rng = np.random.default_rng(4)
    n = 2000
    a = rng.uniform(-3, 3, (n, 3))
    along = rng.normal(size=(n, 3))
    along /= np.linalg.norm(along, axis=1)[:, None]
    across = rng.normal(size=(n, 3))
    across -= (across * along).sum(axis=1)[:, None] * along
    across /= np.linalg.norm(across, axis=1)[:, None]
    v = np.concatenate([a, a + 2.0 * along, a + 2.0 * along + 0.0003 * across])
    mesh = Mesh(v, (np.arange(n)[:, None] + n * np.arange(3)).astype(np.int32), False)
    turn = np.eye(4)
    turn[:2, :2] = [[np.cos(0.7), -np.sin(0.7)], [np.sin(0.7), np.cos(0.7)]]
    world_changed = 0
    for linear in (turn, turn @ np.diag([1.0, -1.0, 1.0, 1.0])):  # turned; turned and mirrored
        near, far = linear.copy(), linear.copy()
        near[:3, 3] = (1.1, 0.3, 0.7)
        far[:3, 3] = (10_000.0, 5_000.0, -2.45)
        one, two = MeshSet.build([("a", mesh, near)]), MeshSet.build([("a", mesh, far)])
        assert one.normals is not None and two.normals is not None
        assert np.array_equal(one.normals, two.normals)
        # the world winding's normals (a mirror reverses the local winding), within a step of rounding
        assert np.abs(triangle_normals(one.triangles) - one.normals).max() <= 2**-19
        world_changed += int(
            (triangle_normals(one.triangles) != triangle_normals(two.triangles)).any(axis=1).sum()
        )
    assert world_changed > 0
