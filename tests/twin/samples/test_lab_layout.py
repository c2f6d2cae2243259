"""The sample lab's layout (``twin.samples.lab_layout``): one plan for the IFC file and the core's box lab."""

from __future__ import annotations

import numpy as np
import pytest

from tests.twin.box_lab import LAB, box_lab
from twin.samples.lab_layout import lab_layout
from twin.samples.lab_plan import DOOR_HOST, Box


def volume(box: Box) -> float:
    return (box.xmax - box.xmin) * (box.ymax - box.ymin) * (box.zmax - box.zmin)


def overlap(a: Box, b: Box) -> bool:
    return all(max(a[i], b[i]) < min(a[i + 3], b[i + 3]) for i in range(3))


def test_a_wall_less_its_door_opening_is_three_disjoint_boxes_around_the_doorway() -> None:
    wall, opening = LAB.element(DOOR_HOST).box, LAB.door_opening.box
    pieces = LAB.solid(DOOR_HOST)
    assert len(pieces) == 3
    assert not any(overlap(p, opening) for p in pieces)
    assert not any(overlap(p, q) for i, p in enumerate(pieces) for q in pieces[i + 1 :])
    assert sum(map(volume, pieces)) == pytest.approx(volume(wall) - volume(opening), abs=1e-12)


def test_a_box_less_a_box_it_does_not_overlap_is_itself() -> None:
    box = Box(0.0, 0.0, 0.0, 1.0, 1.0, 1.0)
    assert box.minus(Box(1.0, 0.0, 0.0, 2.0, 1.0, 1.0)) == (box,)
    assert box.minus(Box(-1.0, -1.0, -1.0, 2.0, 2.0, 2.0)) == ()


def test_every_name_the_layout_relates_is_one_of_its_entities() -> None:
    names = [e.name for e in LAB.elements]
    assert len(set(names)) == len(names)
    structures = {s.name for s in (*LAB.storeys, *LAB.spaces)}
    assert all(e.container in structures or e.container in names for e in LAB.elements)
    assert all(n in names for s in LAB.spaces for n in s.bounded_by)
    assert all(e.fills in names for e in LAB.elements if e.fills is not None)


def test_the_arch_is_a_steel_wall_between_lidar_and_robot_height() -> None:
    arch = LAB.arch
    assert (arch.ifc_class, arch.material) == ("IfcWall", "Steel")
    assert 0.1 < arch.box.zmin < 0.5


def test_the_box_labs_elements_are_the_layouts_with_the_same_ids_classes_and_world_boxes() -> None:
    model = box_lab(storeys=2)
    assert [(e.guid, e.ifc_class, e.name) for e in model.elements] == [
        (e.global_id, e.ifc_class, e.name) for e in lab_layout(storeys=2).elements
    ]
    for element in model.elements:
        assert element.geometry is not None
        world = element.geometry.world_vertices()
        bounds = (*world.min(axis=0), *world.max(axis=0))
        np.testing.assert_allclose(bounds, LAB.element(element.name).box, atol=1e-9)
