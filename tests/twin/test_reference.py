"""The map reference itself (references/slab_maps.py): what it fills and what it calls a solid."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
import trimesh

from references.slab_maps import is_solid, slab_geometry

CUBE = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)])  # 4x + 2y + z


def _cube_faces() -> np.ndarray:
    box = trimesh.creation.box(bounds=[[0, 0, 0], [1, 1, 1]])
    index = (box.vertices @ [4, 2, 1]).round().astype(int)
    return index[box.faces]


def test_a_hollow_tube_is_filled_as_a_ring_not_a_square() -> None:
    tube = trimesh.creation.extrude_polygon(
        shapely.box(0, 0, 2, 2).difference(shapely.box(0.5, 0.5, 1.5, 1.5)), 1.0
    )
    section = slab_geometry(tube.vertices, tube.faces, True, 0.4, 0.6)
    assert section.area == pytest.approx(3.0)


def test_two_overlapping_shells_of_one_element_stay_filled_where_they_overlap() -> None:
    a = trimesh.creation.box(bounds=[[0, 0, 0], [2, 1, 1]])
    b = trimesh.creation.box(bounds=[[1, 0, 0], [3, 1, 1]])
    both = trimesh.util.concatenate([a, b])
    assert slab_geometry(both.vertices, both.faces, True, 0.4, 0.6).area == pytest.approx(3.0)


def test_a_cube_is_a_solid_and_stays_one_with_a_t_junction_but_not_with_a_missing_face() -> None:
    faces = _cube_faces()
    assert is_solid(CUBE, faces)
    assert not is_solid(CUBE, faces[1:])
    # split the front face (y = 0) at the middle of its top edge, leave the top face as it is
    lo, hi, top0, top1 = 0, 4, 1, 5  # (0, 0, 0), (1, 0, 0), (0, 0, 1), (1, 0, 1)
    front = [i for i, f in enumerate(faces) if (CUBE[f][:, 1] == 0).all()]
    vertices = np.vstack([CUBE, [[0.5, 0.0, 1.0]]])
    mid = len(CUBE)
    split = np.array([[lo, hi, mid], [hi, top1, mid], [mid, top0, lo]])
    t_junction = np.vstack([np.delete(faces, front, axis=0), split])
    assert not trimesh.Trimesh(vertices, t_junction, process=False).is_watertight
    assert is_solid(vertices, t_junction)
