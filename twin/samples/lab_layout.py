"""The bundled sample lab placed in the world: every storey, space and element with its GlobalId and
world box (metres), computed from the plan in ``twin.samples.lab_plan`` without any IFC library.

``adapters.ifc.sample_lab`` writes exactly this layout as IFC (and returns it, so tests check the file
against it); the core's tests build the same lab as records from its boxes. GlobalIds are derived
from the entity's class and name (uuid5), so the file, its foot variant and the core's records agree.

Example::

    layout = lab_layout(storeys=2)
    layout.arch.box.zmin                      # 0.3 (metres, world frame)
    layout.space("Corridor").bounded_by
    layout.solid("Wall A south")              # the wall's box less the door's opening: three boxes
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass
from typing import Final, Literal, TypeVar

from twin.samples.lab_plan import (
    ARCH,
    BUILDING,
    BUILDING_OFFSET,
    DOOR,
    DOOR_OPENING,
    GLASS_WALL,
    PROJECT,
    SITE,
    STOREY_PLANS,
    TABLE,
    Box,
    StoreyPlan,
)

_GUID_NAMESPACE: Final = uuid.uuid5(uuid.NAMESPACE_URL, "https://w3id.org/building-twin/sample-lab")
_IFC_BASE64: Final = "0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz_$"


def ifc_global_id(key: str) -> str:
    """The lab's deterministic IFC GlobalId for ``key``: uuid5 of it, in IFC's 22-character base 64."""
    n = uuid.uuid5(_GUID_NAMESPACE, key).int
    return "".join(_IFC_BASE64[(n >> (6 * i)) & 63] for i in reversed(range(22)))


def entity_global_id(ifc_class: str, name: str) -> str:
    """The GlobalId of the lab's entity of class ``ifc_class`` named ``name``."""
    return ifc_global_id(f"{ifc_class}/{name}")


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
    fills: str | None = None
    """A door: the name of the opening it fills."""


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
    """What the lab holds, in metres in world coordinates, for tests to check files and maps against."""

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

    def solid(self, name: str) -> tuple[Box, ...]:
        """Disjoint world boxes that make up element ``name`` once the openings that void it are cut."""
        pieces: tuple[Box, ...] = (self.element(name).box,)
        for opening in self.elements:
            if opening.ifc_class == "IfcOpeningElement" and opening.container == name:
                pieces = tuple(p for piece in pieces for p in piece.minus(opening.box))
        return pieces

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


def storey_plans(storeys: Literal[1, 2]) -> tuple[StoreyPlan, ...]:
    """The plans of the lab's lowest ``storeys`` storeys (1: the ground floor; 2: and the first floor)."""
    if storeys not in (1, 2):
        msg = f"storeys must be 1 or 2, got {storeys!r}."
        raise ValueError(msg)
    return STOREY_PLANS[:storeys]


def lab_layout(*, storeys: Literal[1, 2] = 1) -> LabLayout:
    """The lab with ``storeys`` storeys, in metres in world coordinates."""
    lab_storeys, spaces, elements = [], [], []
    for plan in storey_plans(storeys):
        dx, dy, dz = BUILDING_OFFSET[0], BUILDING_OFFSET[1], BUILDING_OFFSET[2] + plan.elevation
        lab_storeys.append(
            LabStorey(plan.name, entity_global_id("IfcBuildingStorey", plan.name), plan.elevation)
        )
        spaces += [
            LabSpace(
                sp.name,
                entity_global_id("IfcSpace", sp.name),
                plan.name,
                sp.box.moved(dx, dy, dz),
                sp.bounded_by,
            )
            for sp in plan.spaces
        ]
        elements += [
            LabElement(
                name=el.name,
                global_id=entity_global_id(el.ifc_class, el.name),
                ifc_class=el.ifc_class,
                material=el.material,
                storey=plan.name,
                container=el.voids or el.space or plan.name,
                box=el.box.moved(dx, dy, dz),
                fills=el.fills,
            )
            for el in plan.elements
        ]
    return LabLayout(
        project_guid=entity_global_id("IfcProject", PROJECT),
        site_guid=entity_global_id("IfcSite", SITE),
        building_guid=entity_global_id("IfcBuilding", BUILDING),
        building_offset=BUILDING_OFFSET,
        storeys=tuple(lab_storeys),
        spaces=tuple(spaces),
        elements=tuple(elements),
    )
