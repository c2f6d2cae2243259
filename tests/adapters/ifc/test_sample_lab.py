"""The generated sample lab: the file read back (structure, relationships, placements, materials,
meshed geometry) against the layout that ``write_lab`` reports."""

from __future__ import annotations

import uuid
from pathlib import Path
from typing import Literal

import ifcopenshell
import ifcopenshell.geom
import ifcopenshell.guid
import ifcopenshell.util.element
import ifcopenshell.util.placement
import ifcopenshell.util.shape
import ifcopenshell.util.unit
import numpy as np
import pytest

from adapters.ifc.sample_lab import LengthUnit, build_lab, write_lab
from twin.samples.lab_layout import LabLayout, ifc_global_id
from twin.samples.lab_plan import (
    ARCH,
    BUILDING_OFFSET,
    DOOR,
    DOOR_HOST,
    DOOR_OPENING,
    GLASS_WALL,
    SLAB_THICKNESS,
    TABLE,
    Box,
)

TOLERANCE_M = 1e-6
LIDAR_HEIGHT_M = 0.1
ROBOT_HEIGHT_M = 0.5
KERNELS = ("manifold", "opencascade")
MANIFOLD_DILATION_M3 = 2e-4
"""IfcOpenShell's manifold kernel grows subtraction operands by 10 x its precision (1e-5 project units)
along their vertex normals, so it cuts a little more than the opening: allow that much volume."""

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


def world_triangles(model: ifcopenshell.file, guid: str, library: str) -> np.ndarray:
    """The meshed triangles (n x 3 x 3, world metres) of one product, its openings cut out."""
    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)
    shape = ifcopenshell.geom.create_shape(settings, model.by_guid(guid), geometry_library=library)
    vertices = np.asarray(ifcopenshell.util.shape.get_vertices(shape.geometry), dtype=float).reshape(-1, 3)
    faces = np.asarray(ifcopenshell.util.shape.get_faces(shape.geometry), dtype=int).reshape(-1, 3)
    return vertices[faces]


def volume(triangles: np.ndarray) -> float:
    """Volume enclosed by a closed, outward-oriented triangle mesh (divergence theorem)."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def box_volume(box: Box) -> float:
    return (box.xmax - box.xmin) * (box.ymax - box.ymin) * (box.zmax - box.zmin)


def material_name(element: ifcopenshell.entity_instance) -> str | None:
    material = ifcopenshell.util.element.get_material(element)
    return None if material is None else str(material.Name)


def contained(model: ifcopenshell.file, storey_guid: str) -> list[ifcopenshell.entity_instance]:
    """The elements the file contains directly in a storey (not through its spaces)."""
    storey = model.by_guid(storey_guid)
    return [e for rel in storey.ContainsElements for e in rel.RelatedElements]


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


def test_the_files_space_boundaries_give_the_arch_the_glass_wall_and_the_door_their_rooms(lab_files):
    model, _ = open_lab(lab_files, "foot", 2)

    def bounding(space_name: str) -> dict[str, tuple[str, str | None, str]]:
        (space,) = [s for s in model.by_type("IfcSpace") if s.Name == space_name]
        return {
            r.RelatedBuildingElement.Name: (
                r.RelatedBuildingElement.is_a(),
                material_name(r.RelatedBuildingElement),
                r.PhysicalOrVirtualBoundary,
            )
            for r in space.BoundedBy
        }

    assert bounding("Corridor")[ARCH] == ("IfcWall", "Steel", "PHYSICAL")
    assert bounding("Room B")[GLASS_WALL] == ("IfcWall", "Glass", "PHYSICAL")
    assert bounding("Room A")[DOOR] == ("IfcDoor", "Wood", "PHYSICAL")
    assert DOOR_OPENING not in bounding("Room A")  # the void is no boundary, its filling is


def test_glass_wall_is_the_only_element_made_of_glass(lab_files):
    model, layout = open_lab(lab_files, "metre", 2)
    materials = {e.GlobalId: material_name(e) for e in model.by_type("IfcElement")}
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


def test_the_files_spatial_containment_equals_the_layout(lab_files):
    model, layout = open_lab(lab_files, "metre", 2)
    names = {s.global_id: s.name for s in (*layout.storeys, *layout.spaces)}
    for element in model.by_type("IfcElement"):
        planned = layout.element(element.Name)
        assert element.GlobalId == planned.global_id
        (rel,) = element.ContainedInStructure or (None,)
        if element.is_a("IfcOpeningElement"):  # no spatial container: it belongs to what it voids
            assert rel is None
            assert element.VoidsElements[0].RelatingBuildingElement.Name == planned.container
        else:
            assert rel is not None, element.Name
            assert names[rel.RelatingStructure.GlobalId] == planned.container, element.Name
        storey = ifcopenshell.util.element.get_container(element)  # through the space or the host
        if storey.is_a("IfcSpace"):
            storey = ifcopenshell.util.element.get_aggregate(storey)
        assert storey.Name == planned.storey, element.Name


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
    slab = model.by_guid(layout.element("Ground floor slab").global_id)
    assert slab.ObjectPlacement.PlacementRelTo == storey.ObjectPlacement
    host = model.by_guid(layout.element(DOOR_HOST).global_id)
    opening = model.by_guid(layout.door_opening.global_id)
    assert opening.ObjectPlacement.PlacementRelTo == host.ObjectPlacement  # moves with its wall
    door = model.by_guid(layout.door.global_id)
    assert door.ObjectPlacement.PlacementRelTo == opening.ObjectPlacement  # moves with its opening


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
        assert layout == layout_again == layout_foot


def test_the_layouts_global_ids_are_ifcopenshells_compression_of_the_same_uuid():
    for key in ("IfcWall/Arch", "", "IfcRelAggregates|RelatingObject=x", "é" * 50):
        uid = uuid.uuid5(uuid.uuid5(uuid.NAMESPACE_URL, "https://w3id.org/building-twin/sample-lab"), key)
        assert ifc_global_id(key) == ifcopenshell.guid.compress(uid.hex)


@pytest.mark.parametrize("library", KERNELS)
@pytest.mark.parametrize("unit", UNITS)
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
    boxes = world_boxes(model, "manifold")
    arch = boxes[layout.arch.global_id]
    assert LIDAR_HEIGHT_M < arch.zmin < ROBOT_HEIGHT_M
    corridor = boxes[layout.space("Corridor").global_id]
    assert (arch.ymin, arch.ymax) == pytest.approx((corridor.ymin, corridor.ymax))  # spans its width
    assert corridor.xmin < arch.xmin < arch.xmax < corridor.xmax


@pytest.mark.parametrize("unit", UNITS)
def test_table_stands_on_the_floor_slab_inside_its_room(lab_files, unit):
    model, layout = open_lab(lab_files, unit, 1)
    boxes = world_boxes(model, "manifold")
    table = model.by_guid(layout.table.global_id)
    room = ifcopenshell.util.element.get_container(table)
    (slab,) = [e for e in contained(model, layout.storey("Ground floor").global_id) if e.is_a("IfcSlab")]
    t, r, s = boxes[table.GlobalId], boxes[room.GlobalId], boxes[slab.GlobalId]
    assert t.zmin == pytest.approx(r.zmin, abs=TOLERANCE_M)
    assert t.zmin == pytest.approx(s.zmax, abs=TOLERANCE_M)
    assert r.xmin < t.xmin < t.xmax < r.xmax
    assert r.ymin < t.ymin < t.ymax < r.ymax


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
    model, layout = open_lab(lab_files, "foot", 2)
    scale = ifcopenshell.util.unit.calculate_unit_scale(model)
    boxes = world_boxes(model, "manifold")
    first = model.by_guid(layout.storey("First floor").global_id)
    elevation = ifcopenshell.util.placement.get_local_placement(first.ObjectPlacement)[2, 3] * scale
    ground = contained(model, layout.storey("Ground floor").global_id)
    upper = contained(model, first.GlobalId)
    assert sorted(e.is_a() for e in upper) == ["IfcSlab", *["IfcWall"] * 5]
    assert ARCH not in {e.Name for e in upper}
    for element in upper:
        box = boxes[element.GlobalId]
        if element.is_a("IfcSlab"):  # the floor: below the elevation
            assert box.zmax == pytest.approx(elevation, abs=TOLERANCE_M)
        else:
            assert box.zmin == pytest.approx(elevation, abs=TOLERANCE_M)

    def overlaps(a: Box, b: Box) -> bool:
        return a.xmin < b.xmax and b.xmin < a.xmax and a.ymin < b.ymax and b.ymin < a.ymax

    ground_walls = [boxes[g.GlobalId] for g in ground if g.is_a("IfcWall")]
    alone = [
        e.Name
        for e in upper
        if e.is_a("IfcWall") and not any(overlaps(boxes[e.GlobalId], g) for g in ground_walls)
    ]
    assert alone == ["Wall L1 interior"]


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


# --- the floor slabs and the door ----------------------------------------------------------------


GROUND_FOOTPRINT_M2 = 4.4 * 4.4 + 3.6 * 1.6 + 4.3 * 4.4  # Room A, corridor, Room B to the wall faces
FIRST_FOOTPRINT_M2 = 12.4 * 4.4


@pytest.mark.parametrize("library", KERNELS)
@pytest.mark.parametrize("unit", UNITS)
def test_each_storey_stands_on_a_concrete_floor_slab_whose_top_is_its_elevation(lab_files, unit, library):
    model, layout = open_lab(lab_files, unit, 2)
    scale = ifcopenshell.util.unit.calculate_unit_scale(model)
    boxes = world_boxes(model, library)
    for planned, area in zip(layout.storeys, (GROUND_FOOTPRINT_M2, FIRST_FOOTPRINT_M2), strict=True):
        storey = model.by_guid(planned.global_id)
        elevation = ifcopenshell.util.placement.get_local_placement(storey.ObjectPlacement)[2, 3] * scale
        elements = contained(model, storey.GlobalId)
        (slab,) = [e for e in elements if e.is_a("IfcSlab")]
        assert (slab.Name, slab.PredefinedType, material_name(slab)) == (
            f"{planned.name} slab",
            "FLOOR",
            "Concrete",
        )
        assert slab.GlobalId == layout.element(slab.Name).global_id
        box = boxes[slab.GlobalId]
        assert box.zmax == pytest.approx(elevation, abs=TOLERANCE_M)  # under every map's heights
        assert box.zmax - box.zmin == pytest.approx(SLAB_THICKNESS, abs=TOLERANCE_M)
        # It spans the storey to the walls' outer faces, and no further (the ground floor's is H-shaped).
        walls = [boxes[e.GlobalId] for e in elements if e.is_a("IfcWall")]
        extent = (
            min(w.xmin for w in walls),
            min(w.ymin for w in walls),
            max(w.xmax for w in walls),
            max(w.ymax for w in walls),
        )
        assert np.allclose((box.xmin, box.ymin, box.xmax, box.ymax), extent, atol=TOLERANCE_M)
        solid = volume(world_triangles(model, slab.GlobalId, library))
        assert solid == pytest.approx(area * SLAB_THICKNESS, abs=1e-6)


def test_the_opening_voids_wall_a_south_and_the_door_fills_it(lab_files):
    for unit in UNITS:
        model, layout = open_lab(lab_files, unit, 1)
        scale = ifcopenshell.util.unit.calculate_unit_scale(model)
        opening = model.by_guid(layout.door_opening.global_id)
        door = model.by_guid(layout.door.global_id)
        assert (opening.Name, opening.PredefinedType, material_name(opening)) == (
            DOOR_OPENING,
            "OPENING",
            None,
        )
        (voids,) = model.by_type("IfcRelVoidsElement")
        assert voids.RelatedOpeningElement == opening
        assert (voids.RelatingBuildingElement.Name, voids.RelatingBuildingElement.GlobalId) == (
            DOOR_HOST,
            layout.element(DOOR_HOST).global_id,
        )
        (fills,) = model.by_type("IfcRelFillsElement")
        assert (fills.RelatingOpeningElement, fills.RelatedBuildingElement) == (opening, door)
        assert (door.Name, door.PredefinedType, material_name(door)) == (DOOR, "DOOR", "Wood")
        assert (door.OverallWidth * scale, door.OverallHeight * scale) == pytest.approx(
            (0.9, 2.1), abs=TOLERANCE_M
        )
        assert (
            ifcopenshell.util.element.get_container(door).GlobalId == layout.storey("Ground floor").global_id
        )


@pytest.mark.parametrize("library", KERNELS)
@pytest.mark.parametrize("unit", UNITS)
def test_the_kernel_cuts_the_opening_out_of_the_wall(lab_files, unit, library):
    model, layout = open_lab(lab_files, unit, 1)
    boxes = world_boxes(model, library)
    wall, opening = boxes[layout.element(DOOR_HOST).global_id], boxes[layout.door_opening.global_id]
    # The opening goes through the wall's thickness, so whatever of the wall remains at the door's
    # x and z shows up as triangles there.
    assert (opening.ymin, opening.ymax) == pytest.approx((wall.ymin, wall.ymax), abs=TOLERANCE_M)
    triangles = world_triangles(model, layout.element(DOOR_HOST).global_id, library)
    centroids = triangles.mean(axis=1)
    eps = 1e-6
    in_the_doorway = (
        (opening.xmin + eps < centroids[:, 0])
        & (centroids[:, 0] < opening.xmax - eps)
        & (opening.zmin + eps < centroids[:, 2])
        & (centroids[:, 2] < opening.zmax - eps)
    )
    assert not in_the_doorway.any(), f"{library} left {in_the_doorway.sum()} wall triangles in the doorway"
    expected = sum(box_volume(piece) for piece in layout.solid(DOOR_HOST))  # the layout's cut wall
    assert expected == pytest.approx(box_volume(wall) - box_volume(opening), abs=1e-9)
    cut = volume(triangles)
    assert expected - MANIFOLD_DILATION_M3 <= cut <= expected + 1e-9
    if library == "opencascade":
        assert cut == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize("library", KERNELS)
def test_the_door_leaf_stands_in_its_opening_inside_the_wall(lab_files, library):
    model, layout = open_lab(lab_files, "foot", 1)
    boxes = world_boxes(model, library)
    door, opening = boxes[layout.door.global_id], boxes[layout.door_opening.global_id]
    assert_box_close(door, layout.door.box, DOOR)
    size = (door.xmax - door.xmin, door.ymax - door.ymin, door.zmax - door.zmin)
    assert size == pytest.approx((0.9, 0.05, 2.1), abs=TOLERANCE_M)
    assert (door.xmin, door.xmax, door.zmin, door.zmax) == pytest.approx(
        (opening.xmin, opening.xmax, opening.zmin, opening.zmax), abs=TOLERANCE_M
    )
    assert opening.ymin < door.ymin < door.ymax < opening.ymax  # within the wall's thickness


def test_slabs_door_and_opening_are_the_same_in_metre_and_foot_files(lab_files):
    new = {
        ("IfcSlab", "Ground floor slab"),
        ("IfcSlab", "First floor slab"),
        ("IfcDoor", DOOR),
        ("IfcOpeningElement", DOOR_OPENING),
    }
    found = {}
    for unit in UNITS:
        model, _ = open_lab(lab_files, unit, 2)
        boxes = world_boxes(model, "manifold")
        by_name = {(e.is_a(), e.Name): e.GlobalId for e in model.by_type("IfcElement")}
        found[unit] = {key: (by_name[key], boxes[by_name[key]]) for key in new}
    for key in new:
        (metre_id, metre_box), (foot_id, foot_box) = found["metre"][key], found["foot"][key]
        assert metre_id == foot_id, key
        assert_box_close(foot_box, metre_box, f"{key[1]} (foot against metre)")


def test_write_plans_writes_a_building_of_other_plans_with_its_walls_where_the_plan_puts_them(
    tmp_path: Path,
) -> None:
    from adapters.ifc.sample_lab import write_plans
    from twin.samples.lab_plan import ElementPlan, StoreyPlan

    walls = tuple(
        ElementPlan(f"Wall {i}", Box(6.0 * i, 0.0, 0.0, 6.0 * i + 0.2, 4.0, 2.7), "Concrete")
        for i in range(3)
    )
    path = tmp_path / "rooms.ifc"
    write_plans(path, (StoreyPlan("Ground floor", 0.0, walls, ()),))
    model = ifcopenshell.open(str(path))
    storeys = model.by_type("IfcBuildingStorey")
    assert [s.Name for s in storeys] == ["Ground floor"]
    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)
    found = {}
    for wall in model.by_type("IfcWall"):
        verts = np.array(ifcopenshell.geom.create_shape(settings, wall).geometry.verts).reshape(-1, 3)
        found[wall.Name] = (verts.min(axis=0), verts.max(axis=0))
    assert sorted(found) == ["Wall 0", "Wall 1", "Wall 2"]
    for i in range(3):
        lo, hi = found[f"Wall {i}"]
        expected_lo = np.array([6.0 * i, 0.0, 0.0]) + BUILDING_OFFSET
        expected_hi = np.array([6.0 * i + 0.2, 4.0, 2.7]) + BUILDING_OFFSET
        assert np.allclose(lo, expected_lo, atol=TOLERANCE_M)
        assert np.allclose(hi, expected_hi, atol=TOLERANCE_M)
