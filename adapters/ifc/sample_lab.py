"""The bundled sample building: the lab of de Vos et al., generated in code with ``ifcopenshell.api``.

The paper "Generation of skill-specific maps from graph world models for robotic systems" shows its
method on a small lab: two rooms joined by a corridor, with an arch across the corridor that a lidar
at 0.1 m sees under but a 0.5 m tall robot cannot pass, a glass wall that a lidar does not see, and a
table. This module writes that lab as an IFC4 file so the demo and the tests need no downloaded model;
it adds a floor slab under each storey and a door, so that files carry the openings and fillings real
models have.

The ground floor, in the storey's frame (metres, interior faces of the walls; the building is placed
at ``BUILDING_OFFSET``, so add (10, 5, 0) for world coordinates)::

          x=0        4                 8        12
      y=4 +----------+                 +--------+
          |  Room A  |                 | Room B G
    y=2.6 |  [Table] +-----------------+        G     G: the glass wall, x 12..12.1
          |             Corridor   A            G     A: the arch, x 5.9..6.1, z 0.3..1.0
    y=1.4 |          +-----------------+        G
          |          |                 |        G
      y=0 +---DDD----+                 +--------+     D: Door A, x 1.55..2.45, in Wall A south

Walls are 0.2 m thick and 2.7 m tall (the glass wall 0.1 m). The arch spans the corridor at x 5.9..6.1
from z 0.3 to 1.0 m. The table (1.2 x 0.8 x 0.75 m) stands in Room A at x 1.4..2.6, y 2.6..3.4. With
``storeys=2`` a first floor at elevation 3.0 m holds one hall (x 0..12, y 0..4) with a short interior
wall at x 5.9..6.1, y 0..1.0, where the ground floor has nothing, and no arch.

Each storey stands on a floor slab (``IfcSlab``, predefined type FLOOR, concrete, 0.2 m thick) that
covers its whole footprint, outer wall faces included, with its top at the storey's elevation: so it
lies below every map's heights of its own storey. The ground floor's slab is H-shaped, the outline of
the rooms and the corridor (x -0.2..12.1, y -0.2..4.2, without x 4.2..7.8 outside y 1.2..2.8); the
first floor's is the rectangle x -0.2..12.2, y -0.2..4.2, its underside (2.8 m) above the ground
floor's walls (2.7 m). A slab's layout box is its bounding box.

Door A (``IfcDoor``, wood, 0.9 m wide, 2.1 m high, 0.05 m thick) stands in the middle of Wall A
south's thickness at x 1.55..2.45, y -0.125..-0.075. It fills "Door A opening", an
``IfcOpeningElement`` (x 1.55..2.45, y -0.2..0, z 0..2.1: the wall's full thickness) that voids the
wall (``IfcRelVoidsElement``; the door ``IfcRelFillsElement``), so the geometry kernel cuts the wall.
The opening has no material and no spatial container: its layout ``container`` is the wall it voids.
The door bounds Room A (``IfcRelSpaceBoundary``).

Every GlobalId is derived from a fixed name (uuid5), so two generations, and the metre and foot
variants, carry the same ids. The foot variant writes every length divided by 0.3048: its geometry
in metres is the same as the metre variant's. (Meshed, so is every element's, but for the cut wall
under IfcOpenShell's manifold kernel: it enlarges an opening by 10 times its precision in project
units before subtracting it, so that wall differs by under a millimetre between the two variants;
the opencascade kernel cuts exactly.)

Example::

    from adapters.ifc.sample_lab import write_lab

    layout = write_lab("lab.ifc", length_unit="foot", storeys=2)
    layout.arch.box.zmin          # 0.3 (metres, world frame, whatever the file's unit)
    layout.space("Corridor").bounded_by
"""

from __future__ import annotations

import logging
import time
import uuid
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Final, Literal, NamedTuple, TypeVar

import ifcopenshell
import ifcopenshell.api.aggregate
import ifcopenshell.api.context
import ifcopenshell.api.feature
import ifcopenshell.api.geometry
import ifcopenshell.api.material
import ifcopenshell.api.project
import ifcopenshell.api.root
import ifcopenshell.api.spatial
import ifcopenshell.api.unit
import ifcopenshell.guid
import numpy as np
from ifcopenshell.util.shape_builder import ShapeBuilder

log = logging.getLogger(__name__)

LengthUnit = Literal["metre", "foot"]
FOOT_M: Final = 0.3048
BUILDING_OFFSET: Final = (10.0, 5.0, 0.0)
"""World position (metres) of the building's placement; storeys and elements are placed under it."""
WALL_HEIGHT: Final = 2.7
STOREY_HEIGHT: Final = 3.0

SLAB_THICKNESS: Final = 0.2

ARCH: Final = "Arch"
GLASS_WALL: Final = "Glass wall"
TABLE: Final = "Table"
DOOR: Final = "Door A"
DOOR_OPENING: Final = "Door A opening"
DOOR_HOST: Final = "Wall A south"
"""The wall that the door's opening voids."""

_GUID_NAMESPACE: Final = uuid.uuid5(uuid.NAMESPACE_URL, "https://w3id.org/building-twin/sample-lab")


class Box(NamedTuple):
    """An axis-aligned box in metres."""

    xmin: float
    ymin: float
    zmin: float
    xmax: float
    ymax: float
    zmax: float

    def moved(self, dx: float, dy: float, dz: float) -> Box:
        """This box translated by (dx, dy, dz), rounded to the nanometre to keep numbers readable."""
        lo = (self.xmin + dx, self.ymin + dy, self.zmin + dz)
        hi = (self.xmax + dx, self.ymax + dy, self.zmax + dz)
        return Box(*(round(v, 9) for v in (*lo, *hi)))


@dataclass(frozen=True, slots=True)
class LabElement:
    """An element of the lab: its GlobalId, IFC class, material and world box (metres)."""

    name: str
    global_id: str
    ifc_class: str
    material: str | None
    """Name of its ``IfcMaterial``; None for the door's opening, which has none."""
    storey: str
    container: str
    """Name of the spatial structure that contains it: its storey, or a space (the table); for the
    door's opening, which no spatial structure contains, the element it voids."""
    box: Box


@dataclass(frozen=True, slots=True)
class LabSpace:
    """An ``IfcSpace``: its world box (footprint extruded floor to ceiling) and bounding elements."""

    name: str
    global_id: str
    storey: str
    box: Box
    bounded_by: tuple[str, ...]
    """Names of the elements related to it by ``IfcRelSpaceBoundary``."""


@dataclass(frozen=True, slots=True)
class LabStorey:
    """An ``IfcBuildingStorey``."""

    name: str
    global_id: str
    elevation_m: float
    """World z of the storey's floor."""


@dataclass(frozen=True, slots=True)
class LabLayout:
    """What the generated file holds, in metres in world coordinates, for tests to check maps against."""

    length_unit: LengthUnit
    project_guid: str
    site_guid: str
    building_guid: str
    building_offset: tuple[float, float, float]
    storeys: tuple[LabStorey, ...]
    spaces: tuple[LabSpace, ...]
    elements: tuple[LabElement, ...]

    def element(self, name: str) -> LabElement:
        return _by_name(self.elements, name)

    def space(self, name: str) -> LabSpace:
        return _by_name(self.spaces, name)

    def storey(self, name: str) -> LabStorey:
        return _by_name(self.storeys, name)

    @property
    def arch(self) -> LabElement:
        return self.element(ARCH)

    @property
    def glass_wall(self) -> LabElement:
        return self.element(GLASS_WALL)

    @property
    def table(self) -> LabElement:
        return self.element(TABLE)

    @property
    def door(self) -> LabElement:
        return self.element(DOOR)

    @property
    def door_opening(self) -> LabElement:
        return self.element(DOOR_OPENING)

    @property
    def walls(self) -> tuple[LabElement, ...]:
        """Every ``IfcWall``, including the arch and the glass wall."""
        return tuple(e for e in self.elements if e.ifc_class == "IfcWall")

    @property
    def slabs(self) -> tuple[LabElement, ...]:
        """The floor slab of each storey, in storey order."""
        return tuple(e for e in self.elements if e.ifc_class == "IfcSlab")


_Named = TypeVar("_Named", LabElement, LabSpace, LabStorey)


def _by_name(items: tuple[_Named, ...], name: str) -> _Named:
    for item in items:
        if item.name == name:
            return item
    msg = f"The sample lab has no {name!r}; it has {[i.name for i in items]}."
    raise KeyError(msg)


# --- the plan, in each storey's frame (metres) ----------------------------------------------------


_XY = tuple[float, float]


@dataclass(frozen=True, slots=True)
class _ElementPlan:
    name: str
    box: Box
    material: str | None
    ifc_class: str = "IfcWall"
    space: str | None = None  # contained in this space instead of the storey
    predefined_type: str | None = None
    outline: tuple[_XY, ...] = ()  # a footprint other than the box's rectangle (counter-clockwise)
    voids: str | None = None  # an opening: the element it cuts (not spatially contained)
    fills: str | None = None  # a door: the opening it fills


@dataclass(frozen=True, slots=True)
class _SpacePlan:
    name: str
    box: Box
    bounded_by: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class _StoreyPlan:
    name: str
    elevation: float
    elements: tuple[_ElementPlan, ...]
    spaces: tuple[_SpacePlan, ...]


def _wall(name: str, xy0: _XY, xy1: _XY, material: str = "Concrete") -> _ElementPlan:
    """A full-height wall from floor corner ``xy0`` to ``xy1`` (storey frame, metres)."""
    return _ElementPlan(name, Box(*xy0, 0.0, *xy1, WALL_HEIGHT), material)


def _floor_slab(storey: str, outline: tuple[_XY, ...]) -> _ElementPlan:
    """The storey's floor: ``outline`` (storey frame, counter-clockwise) from z -0.2 up to z 0."""
    xs, ys = [x for x, _ in outline], [y for _, y in outline]
    box = Box(min(xs), min(ys), -SLAB_THICKNESS, max(xs), max(ys), 0.0)
    return _ElementPlan(
        f"{storey} slab", box, "Concrete", "IfcSlab", predefined_type="FLOOR", outline=outline
    )


_GROUND_FLOOR: Final = _StoreyPlan(
    name="Ground floor",
    elevation=0.0,
    elements=(
        _wall("Wall A south", (-0.2, -0.2), (4.2, 0.0)),
        _wall("Wall A west", (-0.2, 0.0), (0.0, 4.0)),
        _wall("Wall A north", (-0.2, 4.0), (4.2, 4.2)),
        _wall("Wall A east 1", (4.0, 0.0), (4.2, 1.4)),
        _wall("Wall A east 2", (4.0, 2.6), (4.2, 4.0)),
        _wall("Wall corridor south", (4.2, 1.2), (7.8, 1.4)),
        _wall("Wall corridor north", (4.2, 2.6), (7.8, 2.8)),
        _wall("Wall B west 1", (7.8, 0.0), (8.0, 1.4)),
        _wall("Wall B west 2", (7.8, 2.6), (8.0, 4.0)),
        _wall("Wall B south", (7.8, -0.2), (12.1, 0.0)),
        _wall("Wall B north", (7.8, 4.0), (12.1, 4.2)),
        _wall(GLASS_WALL, (12.0, 0.0), (12.1, 4.0), material="Glass"),
        _ElementPlan(ARCH, Box(5.9, 1.4, 0.3, 6.1, 2.6, 1.0), "Steel"),
        _ElementPlan(TABLE, Box(1.4, 2.6, 0.0, 2.6, 3.4, 0.75), "Wood", "IfcFurnishingElement", "Room A"),
        _floor_slab(
            "Ground floor",
            (
                (-0.2, -0.2),
                (4.2, -0.2),
                (4.2, 1.2),
                (7.8, 1.2),
                (7.8, -0.2),
                (12.1, -0.2),
                (12.1, 4.2),
                (7.8, 4.2),
                (7.8, 2.8),
                (4.2, 2.8),
                (4.2, 4.2),
                (-0.2, 4.2),
            ),
        ),
        _ElementPlan(
            DOOR_OPENING,
            Box(1.55, -0.2, 0.0, 2.45, 0.0, 2.1),
            None,
            "IfcOpeningElement",
            predefined_type="OPENING",
            voids=DOOR_HOST,
        ),
        _ElementPlan(
            DOOR,
            Box(1.55, -0.125, 0.0, 2.45, -0.075, 2.1),
            "Wood",
            "IfcDoor",
            predefined_type="DOOR",
            fills=DOOR_OPENING,
        ),
    ),
    spaces=(
        _SpacePlan(
            "Room A",
            Box(0.0, 0.0, 0.0, 4.0, 4.0, WALL_HEIGHT),
            ("Wall A south", "Wall A west", "Wall A north", "Wall A east 1", "Wall A east 2", DOOR),
        ),
        _SpacePlan(
            "Corridor",
            Box(4.0, 1.4, 0.0, 8.0, 2.6, WALL_HEIGHT),
            (
                "Wall corridor south",
                "Wall corridor north",
                ARCH,
                "Wall A east 1",
                "Wall A east 2",
                "Wall B west 1",
                "Wall B west 2",
            ),
        ),
        _SpacePlan(
            "Room B",
            Box(8.0, 0.0, 0.0, 12.0, 4.0, WALL_HEIGHT),
            ("Wall B south", "Wall B north", "Wall B west 1", "Wall B west 2", GLASS_WALL),
        ),
    ),
)

_FIRST_FLOOR: Final = _StoreyPlan(
    name="First floor",
    elevation=STOREY_HEIGHT,
    elements=(
        _wall("Wall L1 south", (-0.2, -0.2), (12.2, 0.0)),
        _wall("Wall L1 west", (-0.2, 0.0), (0.0, 4.0)),
        _wall("Wall L1 north", (-0.2, 4.0), (12.2, 4.2)),
        _wall("Wall L1 east", (12.0, 0.0), (12.2, 4.0)),
        _wall("Wall L1 interior", (5.9, 0.0), (6.1, 1.0), material="Brick"),
        _floor_slab("First floor", ((-0.2, -0.2), (12.2, -0.2), (12.2, 4.2), (-0.2, 4.2))),
    ),
    spaces=(
        _SpacePlan(
            "Hall",
            Box(0.0, 0.0, 0.0, 12.0, 4.0, WALL_HEIGHT),
            ("Wall L1 south", "Wall L1 west", "Wall L1 north", "Wall L1 east", "Wall L1 interior"),
        ),
    ),
)

_MATERIAL_CATEGORIES: Final = {m: m.lower() for m in ("Concrete", "Brick", "Glass", "Steel", "Wood")}


# --- public API -----------------------------------------------------------------------------------


def write_lab(
    path: str | Path, *, length_unit: LengthUnit = "metre", storeys: Literal[1, 2] = 1
) -> LabLayout:
    """Generate the sample lab and write it to ``path`` as IFC4 (STEP); return its layout.

    :param path: the ``.ifc`` file to write (its folder must exist).
    :param length_unit: the project length unit: ``"metre"`` or ``"foot"`` (a conversion-based unit, as
        Revit writes). The geometry in metres is the same either way.
    :param storeys: 1 for the ground floor only, 2 to add a first floor with a different layout.
    :return: the layout, in metres in world coordinates.

    Example::

        layout = write_lab(tmp_path / "lab.ifc")
        assert layout.arch.box.zmin == 0.3
    """
    model, layout = build_lab(length_unit=length_unit, storeys=storeys)
    model.write(str(path))
    log.info("Wrote the sample lab (%s, %d storey(s)) to %s.", length_unit, storeys, path)
    return layout


def build_lab(
    *, length_unit: LengthUnit = "metre", storeys: Literal[1, 2] = 1
) -> tuple[ifcopenshell.file, LabLayout]:
    """Generate the sample lab in memory: the IFC4 model and its layout (see ``write_lab``).

    Example::

        model, layout = build_lab(storeys=2)
        model.by_guid(layout.glass_wall.global_id)
    """
    if length_unit not in ("metre", "foot"):
        msg = f"length_unit must be 'metre' or 'foot', got {length_unit!r}."
        raise ValueError(msg)
    if storeys not in (1, 2):
        msg = f"storeys must be 1 or 2, got {storeys!r}."
        raise ValueError(msg)
    started = time.perf_counter()
    builder = _LabBuilder(length_unit)
    layout = builder.build((_GROUND_FLOOR, _FIRST_FLOOR)[:storeys])
    log.debug("Generated the sample lab in %.1f ms.", (time.perf_counter() - started) * 1e3)
    return builder.file, layout


# --- generation -----------------------------------------------------------------------------------


def _guid(key: str) -> str:
    """A deterministic IFC GlobalId (22 characters) for ``key``."""
    return str(ifcopenshell.guid.compress(uuid.uuid5(_GUID_NAMESPACE, key).hex))


class _LabBuilder:
    """One generation: holds the file being built and the project's length scale."""

    def __init__(self, length_unit: LengthUnit) -> None:
        self.length_unit: LengthUnit = length_unit
        self.file = ifcopenshell.api.project.create_file(version="IFC4")
        self.scale = FOOT_M if length_unit == "foot" else 1.0  # metres per project length unit
        self.shapes = ShapeBuilder(self.file)
        self.materials: dict[str, ifcopenshell.entity_instance] = {}
        self.by_material: dict[str, list[ifcopenshell.entity_instance]] = defaultdict(list)
        self.project = self._root("IfcProject", "Sample lab")
        self._assign_units()
        model = ifcopenshell.api.context.add_context(self.file, context_type="Model")
        self.body = ifcopenshell.api.context.add_context(
            self.file, context_type="Model", context_identifier="Body", target_view="MODEL_VIEW", parent=model
        )

    def build(self, plans: tuple[_StoreyPlan, ...]) -> LabLayout:
        project = self.project
        site = self._root("IfcSite", "Lab site")
        ifcopenshell.api.aggregate.assign_object(self.file, products=[site], relating_object=project)
        self._place(site, (0.0, 0.0, 0.0))
        building = self._root("IfcBuilding", "Lab")
        ifcopenshell.api.aggregate.assign_object(self.file, products=[building], relating_object=site)
        self._place(building, BUILDING_OFFSET)

        storeys, spaces, elements = [], [], []
        for plan in plans:
            storey = self._root("IfcBuildingStorey", plan.name)
            storey.Elevation = plan.elevation / self.scale
            ifcopenshell.api.aggregate.assign_object(self.file, products=[storey], relating_object=building)
            self._place(storey, (BUILDING_OFFSET[0], BUILDING_OFFSET[1], BUILDING_OFFSET[2] + plan.elevation))
            storeys.append(LabStorey(plan.name, storey.GlobalId, plan.elevation))
            s, e = self._add_storey_contents(plan, storey)
            spaces += s
            elements += e

        for name, products in self.by_material.items():
            ifcopenshell.api.material.assign_material(
                self.file, products=products, type="IfcMaterial", material=self.materials[name]
            )
        _stabilise_relationship_ids(self.file)
        return LabLayout(
            length_unit=self.length_unit,
            project_guid=project.GlobalId,
            site_guid=site.GlobalId,
            building_guid=building.GlobalId,
            building_offset=BUILDING_OFFSET,
            storeys=tuple(storeys),
            spaces=tuple(spaces),
            elements=tuple(elements),
        )

    def _add_storey_contents(
        self, plan: _StoreyPlan, storey: ifcopenshell.entity_instance
    ) -> tuple[list[LabSpace], list[LabElement]]:
        dx, dy, dz = BUILDING_OFFSET[0], BUILDING_OFFSET[1], BUILDING_OFFSET[2] + plan.elevation
        spaces: dict[str, ifcopenshell.entity_instance] = {}
        lab_spaces = []
        for sp in plan.spaces:
            space = self._root("IfcSpace", sp.name, predefined_type="INTERNAL")
            ifcopenshell.api.aggregate.assign_object(self.file, products=[space], relating_object=storey)
            self._place(space, (sp.box.xmin + dx, sp.box.ymin + dy, sp.box.zmin + dz))
            self._assign_prism_body(space, sp.box)
            spaces[sp.name] = space
            world_box = sp.box.moved(dx, dy, dz)
            lab_spaces.append(LabSpace(sp.name, space.GlobalId, plan.name, world_box, sp.bounded_by))

        products: dict[str, ifcopenshell.entity_instance] = {}
        lab_elements = []
        in_storey = []
        for el in plan.elements:
            product = self._root(el.ifc_class, el.name, el.predefined_type)
            products[el.name] = product
            if el.voids is not None:  # an opening belongs to the element it voids, not to a storey
                ifcopenshell.api.feature.add_feature(self.file, feature=product, element=products[el.voids])
            elif el.space is None:
                in_storey.append(product)
            else:  # contained in its room, so that the file has both kinds of containment
                ifcopenshell.api.spatial.assign_container(
                    self.file, products=[product], relating_structure=spaces[el.space]
                )
            if el.fills is not None:
                ifcopenshell.api.feature.add_filling(self.file, opening=products[el.fills], element=product)
            if el.material is not None:
                self._add_material(el.material)
                self.by_material[el.material].append(product)
            lab_elements.append(
                LabElement(
                    name=el.name,
                    global_id=product.GlobalId,
                    ifc_class=el.ifc_class,
                    material=el.material,
                    storey=plan.name,
                    container=el.voids or el.space or plan.name,
                    box=el.box.moved(dx, dy, dz),
                )
            )
        ifcopenshell.api.spatial.assign_container(self.file, products=in_storey, relating_structure=storey)

        # Placements after containment, voiding and filling, in plan order (a host before what it
        # hosts): edit_object_placement takes a world matrix and writes it relative to the placement
        # of the container, of the voided wall (the opening) or of the filled opening (the door).
        for el in plan.elements:
            product = products[el.name]
            if el.ifc_class == "IfcWall":
                self._place_wall(product, el.box, (dx, dy, dz))
            else:
                self._place(product, (el.box.xmin + dx, el.box.ymin + dy, el.box.zmin + dz))
                self._assign_prism_body(product, el.box, el.outline)
            if el.ifc_class == "IfcDoor":
                product.OverallWidth = (el.box.xmax - el.box.xmin) / self.scale
                product.OverallHeight = (el.box.zmax - el.box.zmin) / self.scale

        for sp in plan.spaces:
            for name in sp.bounded_by:
                external = "INTERNAL" if name == ARCH else "EXTERNAL"
                self.file.create_entity(
                    "IfcRelSpaceBoundary",
                    RelatingSpace=spaces[sp.name],
                    RelatedBuildingElement=products[name],
                    PhysicalOrVirtualBoundary="PHYSICAL",
                    InternalOrExternalBoundary=external,
                )
        return lab_spaces, lab_elements

    def _root(
        self, ifc_class: str, name: str, predefined_type: str | None = None
    ) -> ifcopenshell.entity_instance:
        entity = ifcopenshell.api.root.create_entity(
            self.file, ifc_class=ifc_class, name=name, predefined_type=predefined_type
        )
        entity.GlobalId = _guid(f"{ifc_class}/{name}")
        return entity

    def _assign_units(self) -> None:
        # The API's default is millimetres: assign the length unit explicitly.
        if self.length_unit == "foot":
            units = [
                ifcopenshell.api.unit.add_conversion_based_unit(self.file, name=n)
                for n in ("foot", "square foot", "cubic foot")
            ]
        else:
            units = [
                ifcopenshell.api.unit.add_si_unit(self.file, unit_type=t)
                for t in ("LENGTHUNIT", "AREAUNIT", "VOLUMEUNIT")
            ]
        ifcopenshell.api.unit.assign_unit(self.file, units=units)

    def _add_material(self, name: str) -> None:
        if name not in self.materials:
            self.materials[name] = ifcopenshell.api.material.add_material(
                self.file, name=name, category=_MATERIAL_CATEGORIES[name]
            )

    def _place(
        self,
        product: ifcopenshell.entity_instance,
        origin: tuple[float, float, float],
        *,
        along_y: bool = False,
    ) -> None:
        """Place ``product`` at world ``origin`` (metres); ``along_y`` turns its x axis to world +y."""
        matrix = np.eye(4)
        if along_y:
            matrix[:3, 0] = (0.0, 1.0, 0.0)
            matrix[:3, 1] = (-1.0, 0.0, 0.0)
        matrix[:3, 3] = origin
        # is_si: the API converts metres to the project unit (and relative to the container).
        ifcopenshell.api.geometry.edit_object_placement(self.file, product=product, matrix=matrix, is_si=True)

    def _place_wall(
        self, wall: ifcopenshell.entity_instance, box: Box, offset: tuple[float, float, float]
    ) -> None:
        """Give ``wall`` the body of ``box`` (storey frame): a wall along its longer horizontal side."""
        dx, dy, dz = offset
        size_x, size_y = box.xmax - box.xmin, box.ymax - box.ymin
        along_y = size_y > size_x
        if along_y:  # local x = world +y, local y = world -x: the profile runs from xmax towards -x
            self._place(wall, (box.xmax + dx, box.ymin + dy, box.zmin + dz), along_y=True)
            length, thickness = size_y, size_x
        else:
            self._place(wall, (box.xmin + dx, box.ymin + dy, box.zmin + dz))
            length, thickness = size_x, size_y
        # Lengths in metres: the API converts them to the project unit.
        height = box.zmax - box.zmin
        representation = ifcopenshell.api.geometry.add_wall_representation(
            self.file, context=self.body, length=length, height=height, thickness=thickness
        )
        ifcopenshell.api.geometry.assign_representation(
            self.file, product=wall, representation=representation
        )

    def _assign_prism_body(
        self, product: ifcopenshell.entity_instance, box: Box, outline: tuple[_XY, ...] = ()
    ) -> None:
        """Extrude from the product's origin (``box``'s low corner) ``box``'s rectangle, or ``outline``
        (same frame as ``box``) when given, by ``box``'s height; written in project units."""
        s = self.scale
        if outline:
            points = [((x - box.xmin) / s, (y - box.ymin) / s) for x, y in outline]
            curve = self.shapes.polyline(points, closed=True)
        else:
            curve = self.shapes.rectangle(size=((box.xmax - box.xmin) / s, (box.ymax - box.ymin) / s))
        solid = self.shapes.extrude(self.shapes.profile(curve), magnitude=(box.zmax - box.zmin) / s)
        representation = self.shapes.get_representation(self.body, [solid])
        ifcopenshell.api.geometry.assign_representation(
            self.file, product=product, representation=representation
        )


def _stabilise_relationship_ids(model: ifcopenshell.file) -> None:
    """Give every relationship a GlobalId derived from its class and its singular (relating) ends.

    The API mints random ids for the relationships it creates; each relationship here is identified
    by what it relates from (e.g. the storey that contains, the material that is associated), so the
    ids do not depend on run, length unit or how many elements sit on the other end.
    """
    seen: dict[str, ifcopenshell.entity_instance] = {}
    for rel in model.by_type("IfcRelationship"):
        info = rel.get_info(include_identifier=False, recursive=False)
        parts = [str(info.pop("type"))]
        for attribute, value in info.items():
            if attribute in ("GlobalId", "OwnerHistory") or isinstance(value, tuple):
                continue
            ref = value
            if isinstance(value, ifcopenshell.entity_instance):  # a rooted object, or a material by name
                ref = getattr(value, "GlobalId", None) or getattr(value, "Name", None)
            parts.append(f"{attribute}={ref}")
        key = "|".join(parts)
        if key in seen:
            msg = f"Two relationships of the sample lab share the key {key!r}."
            raise RuntimeError(msg)
        seen[key] = rel
        rel.GlobalId = _guid(key)
