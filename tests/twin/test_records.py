"""Records: a mesh marked solid is the same mesh (the same arrays) with ``solid`` set, still frozen."""

from __future__ import annotations

import dataclasses

import pytest

from twin.shapes import box_mesh


def test_a_mesh_marked_solid_shares_its_arrays_and_is_still_frozen() -> None:
    mesh = box_mesh(1.0, 2.0, 3.0)
    solid = mesh.marked_solid()
    assert solid.solid and not mesh.solid
    assert solid.vertices is mesh.vertices and solid.faces is mesh.faces and solid.closed == mesh.closed
    expected = dataclasses.replace(mesh, solid=True)
    assert [
        getattr(solid, f.name) is getattr(expected, f.name)
        or getattr(solid, f.name) == getattr(expected, f.name)
        for f in dataclasses.fields(mesh)
    ] == [True] * 4
    with pytest.raises(dataclasses.FrozenInstanceError):
        solid.solid = False  # type: ignore[misc]
