"""The generated sample lab: its structure, its ids, and its meshed geometry against its layout."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import ifcopenshell
import ifcopenshell.geom
import ifcopenshell.util.element
import ifcopenshell.util.placement
import ifcopenshell.util.shape
import ifcopenshell.util.unit
import numpy as np
import pytest

from adapters.sample_lab import (
    ARCH,
    BUILDING_OFFSET,
    GLASS_WALL,
    TABLE,
    Box,
    LabLayout,
    LengthUnit,
    build_lab,
    write_lab,
)

TOLERANCE_M = 1e-6
LIDAR_HEIGHT_M = 0.1
ROBOT_HEIGHT_M = 0.5

UNITS: tuple[LengthUnit, ...] = ("metre", "foot")
STOREYS: tuple[Literal[1, 2], ...] = (1, 2)

Lab = tuple[ifcopenshell.file, LabLayout]


@pytest.fixture(scope="module")
def lab_files(tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[str, int], tuple[Path, LabLayout]]:
    folder = tmp_path_factory.mktemp("lab")
    files = {}
    for unit in UNITS:
        for storeys in STOREYS:
            path = folder / f"lab-{unit}-{storeys}.ifc"
            files[unit, storeys] = (path, write_lab(path, length_unit=unit, storeys=storeys))
    return files


def open_lab(lab_files: dict[tuple[str, int], tuple[Path, LabLayout]], unit: str, storeys: int) -> Lab:
    path, layout = lab_files[unit, storeys]
    return ifcopenshell.open(str(path)), layout


def world_boxes(
    model: ifcopenshell.file, library: str, *, convert_back_units: bool = False
) -> dict[str, Box]:
    """GlobalId -> world axis-aligned box of every meshed shape (metres, unless converted back)."""
    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)
    settings.set("convert-back-units", convert_back_units)
    iterator = ifcopenshell.geom.iterator(settings, model, 1, geometry_library=library)
    assert iterator.initialize(), f"{library} meshed nothing"
    boxes = {}
    while True:
        shape = iterator.get()
        vertices = ifcopenshell.util.shape.get_vertices(shape.geometry)
        boxes[shape.guid] = Box(*vertices.min(axis=0), *vertices.max(axis=0))
        if not iterator.next():
            return boxes


def assert_box_close(got: Box, want: Box, what: str) -> None:
    assert np.allclose(got, want, rtol=0.0, atol=TOLERANCE_M), f"{what}: meshed {got}, layout {want}"


def test_written_file_is_ifc4_with_the_length_unit_assigned_explicitly(lab_files):
    metre, _ = open_lab(lab_files, "metre", 1)
    foot, _ = open_lab(lab_files, "foot", 1)
    assert metre.schema == foot.schema == "IFC4"
    assert ifcopenshell.util.unit.calculate_unit_scale(metre) == 1.0
    assert ifcopenshell.util.unit.calculate_unit_scale(foot) == pytest.approx(0.3048)
    (length,) = [u for u in metre.by_type("IfcProject")[0].UnitsInContext.Units if u.UnitType == "LENGTHUNIT"]
    assert (length.is_a(), length.Prefix, length.Name) == ("IfcSIUnit", None, "METRE")
    (length,) = [u for u in foot.by_type("IfcProject")[0].UnitsInContext.Units if u.UnitType == "LENGTHUNIT"]
    assert (length.is_a(), length.Name.lower()) == ("IfcConversionBasedUnit", "foot")


def test_spatial_structure_runs_project_site_building_storeys(lab_files):
    model, layout = open_lab(lab_files, "metre", 2)
    project = model.by_guid(layout.project_guid)
    (site,) = ifcopenshell.util.element.get_decomposition(project, is_recursive=False)
    assert site.is_a("IfcSite")
    assert site.GlobalId == layout.site_guid
    (building,) = ifcopenshell.util.element.get_decomposition(site, is_recursive=False)
    assert building.is_a("IfcBuilding")
    assert building.GlobalId == layout.building_guid
    storeys = ifcopenshell.util.element.get_decomposition(building, is_recursive=False)
    assert {s.GlobalId for s in storeys} == {s.global_id for s in layout.storeys}


def test_lab_has_three_spaces_with_boundaries(lab_files):
    model, layout = open_lab(lab_files, "metre", 1)
    storey = layout.storey("Ground floor").global_id
    spaces = model.by_type("IfcSpace")
    assert sorted(s.Name for s in spaces) == ["Corridor", "Room A", "Room B"]
    for space in spaces:
        planned = layout.space(space.Name)
        assert space.GlobalId == planned.global_id
        assert ifcopenshell.util.element.get_aggregate(space).GlobalId == storey
        boundaries = [r for r in space.BoundedBy if r.is_a("IfcRelSpaceBoundary")]
        assert boundaries, f"{space.Name} has no space boundaries"
        bounding = {r.RelatedBuildingElement.GlobalId for r in boundaries}
        assert bounding == {layout.element(n).global_id for n in planned.bounded_by}


def test_corridor_is_bounded_by_the_arch_and_room_b_by_the_glass_wall(lab_files):
    _, layout = open_lab(lab_files, "metre", 1)
    assert ARCH in layout.space("Corridor").bounded_by
    assert GLASS_WALL in layout.space("Room B").bounded_by


def test_glass_wall_is_the_only_element_made_of_glass(lab_files):
    model, layout = open_lab(lab_files, "metre", 2)
    materials = {
        e.GlobalId: ifcopenshell.util.element.get_material(e).Name for e in model.by_type("IfcElement")
    }
    assert materials[layout.glass_wall.global_id] == "Glass"
    assert [g for g, name in materials.items() if name == "Glass"] == [layout.glass_wall.global_id]
    assert materials == {e.global_id: e.material for e in layout.elements}


def test_walls_are_extruded_solids(lab_files):
    model, layout = open_lab(lab_files, "metre", 2)
    walls = model.by_type("IfcWall")
    assert {w.GlobalId for w in walls} == {w.global_id for w in layout.walls}
    for wall in walls:
        (body,) = wall.Representation.Representations
        assert [i.is_a() for i in body.Items] == ["IfcExtrudedAreaSolid"]


def test_lab_has_one_furnishing_element_contained_in_its_room(lab_files):
    model, layout = open_lab(lab_files, "metre", 1)
    (table,) = model.by_type("IfcFurnishingElement")
    assert table.is_a() == "IfcFurnishingElement"
    assert (table.GlobalId, table.Name) == (layout.table.global_id, TABLE)
    room = ifcopenshell.util.element.get_container(table)
    assert room.is_a("IfcSpace")
    assert room.GlobalId == layout.space(layout.table.container).global_id
    storey = layout.storey("Ground floor").global_id
    for wall in model.by_type("IfcWall"):
        assert ifcopenshell.util.element.get_container(wall).GlobalId == storey


def test_placements_nest_under_an_offset_building(lab_files):
    model, layout = open_lab(lab_files, "foot", 1)
    scale = ifcopenshell.util.unit.calculate_unit_scale(model)
    building = model.by_guid(layout.building_guid)
    world = ifcopenshell.util.placement.get_local_placement(building.ObjectPlacement)
    assert np.allclose(world[:3, 3] * scale, BUILDING_OFFSET)
    storey = model.by_guid(layout.storey("Ground floor").global_id)
    assert storey.ObjectPlacement.PlacementRelTo == building.ObjectPlacement
    wall = model.by_guid(layout.glass_wall.global_id)
    assert wall.ObjectPlacement.PlacementRelTo == storey.ObjectPlacement
    table = model.by_guid(layout.table.global_id)
    room = model.by_guid(layout.space(layout.table.container).global_id)
    assert table.ObjectPlacement.PlacementRelTo == room.ObjectPlacement


def test_global_ids_are_unique_and_deterministic_across_runs_and_units(lab_files, tmp_path):
    def ids(model: ifcopenshell.file) -> dict[str, tuple[str, str | None]]:
        found = {e.GlobalId: (e.is_a(), getattr(e, "Name", None)) for e in model.by_type("IfcRoot")}
        assert len(found) == len(model.by_type("IfcRoot")), "GlobalIds are not unique"
        return found

    for storeys in STOREYS:
        again = tmp_path / f"again-{storeys}.ifc"
        layout_again = write_lab(again, storeys=storeys)
        metre, layout = open_lab(lab_files, "metre", storeys)
        foot, layout_foot = open_lab(lab_files, "foot", storeys)
        assert ids(metre) == ids(ifcopenshell.open(str(again))) == ids(foot)
        assert layout == layout_again
        assert (layout.storeys, layout.spaces, layout.elements) == (
            layout_foot.storeys,
            layout_foot.spaces,
            layout_foot.elements,
        )


@pytest.mark.parametrize("library", ["manifold", "opencascade"])
@pytest.mark.parametrize("unit", ["metre", "foot"])
def test_meshed_world_boxes_equal_the_layout(lab_files, library, unit):
    model, layout = open_lab(lab_files, unit, 2)
    boxes = world_boxes(model, library)
    for item in (*layout.elements, *layout.spaces):
        assert item.global_id in boxes, f"{library} did not mesh {item.name}"
        assert_box_close(boxes[item.global_id], item.box, f"{item.name} ({library}, {unit})")


def test_foot_file_stores_lengths_in_feet(lab_files):
    model, layout = open_lab(lab_files, "foot", 2)
    scale = ifcopenshell.util.unit.calculate_unit_scale(model)
    boxes = world_boxes(model, "manifold", convert_back_units=True)  # in project units: feet
    for item in (*layout.elements, *layout.spaces):
        in_feet = boxes[item.global_id]
        assert_box_close(Box(*(v * scale for v in in_feet)), item.box, item.name)
        assert not np.allclose(in_feet, item.box)


def test_arch_underside_lies_between_lidar_and_robot_height(lab_files):
    model, layout = open_lab(lab_files, "metre", 1)
    arch = world_boxes(model, "manifold")[layout.arch.global_id]
    assert LIDAR_HEIGHT_M < arch.zmin < ROBOT_HEIGHT_M
    corridor = layout.space("Corridor").box
    assert (arch.ymin, arch.ymax) == pytest.approx((corridor.ymin, corridor.ymax))  # spans its width
    assert corridor.xmin < arch.xmin < arch.xmax < corridor.xmax


def test_table_stands_on_the_floor_inside_its_room(lab_files):
    _, layout = open_lab(lab_files, "metre", 1)
    table, room = layout.table.box, layout.space(layout.table.container).box
    assert table.zmin == room.zmin
    assert room.xmin < table.xmin < table.xmax < room.xmax
    assert room.ymin < table.ymin < table.ymax < room.ymax


@pytest.mark.parametrize("unit", ["metre", "foot"])
def test_two_storeys_have_the_reported_elevations(lab_files, unit):
    model, layout = open_lab(lab_files, unit, 2)
    scale = ifcopenshell.util.unit.calculate_unit_scale(model)
    assert [(s.name, s.elevation_m) for s in layout.storeys] == [("Ground floor", 0.0), ("First floor", 3.0)]
    storeys = model.by_type("IfcBuildingStorey")
    assert len(storeys) == 2
    for planned in layout.storeys:
        storey = model.by_guid(planned.global_id)
        assert storey.Name == planned.name
        assert storey.Elevation * scale == pytest.approx(planned.elevation_m, abs=TOLERANCE_M)
        world = ifcopenshell.util.placement.get_local_placement(storey.ObjectPlacement)
        assert world[2, 3] * scale == pytest.approx(planned.elevation_m, abs=TOLERANCE_M)
    assert len(model.by_type("IfcSpace")) == 4


def test_second_storey_has_a_wall_where_the_first_has_none_and_no_arch(lab_files):
    _, layout = open_lab(lab_files, "metre", 2)
    ground = [e.box for e in layout.elements if e.storey == "Ground floor"]
    upper = [e for e in layout.elements if e.storey == "First floor"]
    assert upper
    assert all(e.ifc_class == "IfcWall" and e.name != ARCH for e in upper)
    for element in upper:
        assert layout.storey("First floor").elevation_m <= element.box.zmin

    def overlaps(a: Box, b: Box) -> bool:
        return a.xmin < b.xmax and b.xmin < a.xmax and a.ymin < b.ymax and b.ymin < a.ymax

    assert any(not any(overlaps(e.box, g) for g in ground) for e in upper)


def test_in_memory_build_matches_the_written_layout(lab_files):
    model, layout = build_lab(length_unit="foot", storeys=2)
    assert layout == lab_files["foot", 2][1]
    assert model.by_guid(layout.arch.global_id).Name == ARCH


def test_build_rejects_unknown_units_and_storey_counts():
    with pytest.raises(ValueError, match="length_unit must be 'metre' or 'foot', got 'inch'"):
        build_lab(length_unit="inch")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="storeys must be 1 or 2, got 3"):
        build_lab(storeys=3)  # type: ignore[arg-type]


def test_layout_lookup_of_an_unknown_name_raises_key_error(lab_files):
    _, layout = open_lab(lab_files, "metre", 1)
    with pytest.raises(KeyError, match="The sample lab has no 'Hall'"):
        layout.space("Hall")
