"""The paper's lab as core records built from boxes: no IFC, no ifcopenshell (the core's own tests).

Same layout as ``adapters.ifc.sample_lab`` (world frame: the building at x 10.., y 5..), ground floor only
unless ``storeys=2``: rooms A and B joined by a corridor, an arch across the corridor, a glass wall on
room B's east side, Door A in the gap of Wall A south (x 1.55..2.45, a header above 2.1 m), and a
table in room A.
"""

from __future__ import annotations

from dataclasses import dataclass

from twin.records import Building, BuildingModel, Element, Geometry, Relation, Site, Space, Storey
from twin.shapes import box_mesh, box_placement

OX, OY = 10.0, 5.0
BASE = "https://example.org/test#"

_WALL_TYPES = ("IfcWall", "IfcBuildingElement", "IfcBuiltElement", "IfcElement", "IfcProduct")
_TYPES = {
    "IfcWall": _WALL_TYPES,
    "IfcDoor": ("IfcDoor", "IfcBuildingElement", "IfcBuiltElement", "IfcElement", "IfcProduct"),
    "IfcOpeningElement": (
        "IfcOpeningElement", "IfcFeatureElementSubtraction", "IfcFeatureElement", "IfcElement", "IfcProduct"
    ),
    "IfcFurniture": ("IfcFurniture", "IfcFurnishingElement", "IfcElement", "IfcProduct"),
    "IfcBeam": ("IfcBeam", "IfcBuildingElement", "IfcBuiltElement", "IfcElement", "IfcProduct"),
    "IfcSlab": ("IfcSlab", "IfcBuildingElement", "IfcBuiltElement", "IfcElement", "IfcProduct"),
}  # fmt: skip
STATIC = ("IfcWall", "IfcDoor", "IfcOpeningElement", "IfcBeam", "IfcSlab")


@dataclass(frozen=True, slots=True)
class BoxSpec:
    name: str
    guid: str
    ifc_class: str
    material: str
    box: tuple[float, float, float, float, float, float]  # storey frame: xmin ymin zmin xmax ymax zmax


def _guid(n: int) -> str:
    return "0" + f"{n:021d}"


# Ground floor, storey frame (add OX, OY for world).
GROUND: tuple[BoxSpec, ...] = (
    BoxSpec("Wall A west", _guid(1), "IfcWall", "Brick", (-0.2, -0.2, 0.0, 0.0, 4.2, 2.7)),
    BoxSpec("Wall A north", _guid(2), "IfcWall", "Brick", (-0.2, 4.0, 0.0, 4.2, 4.2, 2.7)),
    BoxSpec("Wall A south", _guid(3), "IfcWall", "Brick", (-0.2, -0.2, 0.0, 1.55, 0.0, 2.7)),
    BoxSpec("Wall A south right", _guid(17), "IfcWall", "Brick", (2.45, -0.2, 0.0, 4.2, 0.0, 2.7)),
    BoxSpec("Wall A south header", _guid(18), "IfcWall", "Brick", (1.55, -0.2, 2.1, 2.45, 0.0, 2.7)),
    BoxSpec("Wall A east low", _guid(4), "IfcWall", "Brick", (4.0, -0.2, 0.0, 4.2, 1.4, 2.7)),
    BoxSpec("Wall A east high", _guid(5), "IfcWall", "Brick", (4.0, 2.6, 0.0, 4.2, 4.2, 2.7)),
    BoxSpec("Corridor north", _guid(6), "IfcWall", "Brick", (4.2, 2.6, 0.0, 7.8, 2.8, 2.7)),
    BoxSpec("Corridor south", _guid(7), "IfcWall", "Brick", (4.2, 1.2, 0.0, 7.8, 1.4, 2.7)),
    BoxSpec("Wall B west low", _guid(8), "IfcWall", "Brick", (7.8, -0.2, 0.0, 8.0, 1.4, 2.7)),
    BoxSpec("Wall B west high", _guid(9), "IfcWall", "Brick", (7.8, 2.6, 0.0, 8.0, 4.2, 2.7)),
    BoxSpec("Wall B north", _guid(10), "IfcWall", "Brick", (7.8, 4.0, 0.0, 12.1, 4.2, 2.7)),
    BoxSpec("Wall B south", _guid(11), "IfcWall", "Brick", (7.8, -0.2, 0.0, 12.1, 0.0, 2.7)),
    BoxSpec("Glass wall", _guid(12), "IfcWall", "Glass", (12.0, 0.0, 0.0, 12.1, 4.0, 2.7)),
    BoxSpec("Arch", _guid(13), "IfcBeam", "Steel", (5.9, 1.4, 0.3, 6.1, 2.6, 1.0)),
    BoxSpec("Door A", _guid(14), "IfcDoor", "Wood", (1.55, -0.125, 0.0, 2.45, -0.075, 2.1)),
    BoxSpec("Table", _guid(15), "IfcFurniture", "Wood", (1.4, 2.6, 0.0, 2.6, 3.4, 0.75)),
    BoxSpec("Floor", _guid(16), "IfcSlab", "Concrete", (-0.2, -0.2, -0.2, 12.1, 4.2, 0.0)),
)
FIRST: tuple[BoxSpec, ...] = (
    BoxSpec("Hall west", _guid(21), "IfcWall", "Brick", (-0.2, -0.2, 0.0, 0.0, 4.2, 2.7)),
    BoxSpec("Hall east", _guid(22), "IfcWall", "Brick", (12.0, -0.2, 0.0, 12.2, 4.2, 2.7)),
    BoxSpec("Hall inner", _guid(23), "IfcWall", "Brick", (5.9, 0.0, 0.0, 6.1, 1.0, 2.7)),
)
STOREY_HEIGHT = 3.0


def element_iri(spec: BoxSpec) -> str:
    from twin.vocab import entity_iri

    return entity_iri(BASE, spec.ifc_class, spec.guid)


def spec(name: str) -> BoxSpec:
    return next(s for s in (*GROUND, *FIRST) if s.name == name)


def world_box(s: BoxSpec, *, elevation: float = 0.0) -> tuple[float, float, float, float, float, float]:
    x0, y0, z0, x1, y1, z1 = s.box
    return (x0 + OX, y0 + OY, z0 + elevation, x1 + OX, y1 + OY, z1 + elevation)


def _element(s: BoxSpec, elevation: float) -> Element:
    x0, y0, z0, x1, y1, z1 = world_box(s, elevation=elevation)
    geometry = Geometry(
        box_mesh(x1 - x0, y1 - y0, z1 - z0), box_placement((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2)
    )
    return Element(
        guid=s.guid,
        ifc_class=s.ifc_class,
        name=s.name,
        materials=(s.material,),
        facing_materials=(s.material,),
        is_static=s.ifc_class in STATIC,
        geometry=geometry,
        ifc_types=_TYPES[s.ifc_class],
    )


def box_lab(*, storeys: int = 1) -> BuildingModel:
    """The lab as a :class:`BuildingModel` (one or two storeys), ready for ``import_model``."""
    site, building = Site(_guid(900), "Site"), Building(_guid(901), "Lab", _guid(900))
    floors = [(Storey(_guid(902), "Ground floor", 0.0, building.guid), GROUND)]
    if storeys == 2:
        floors.append((Storey(_guid(903), "First floor", STOREY_HEIGHT, building.guid), FIRST))
    elements, contained = [], set()
    for storey, specs in floors:
        for s in specs:
            elements.append(_element(s, storey.elevation_m))
            contained.add(Relation(storey.guid, s.guid))
    corridor = Space(_guid(904), "Corridor", floors[0][0].guid)
    return BuildingModel(
        source_name="box-lab",
        schema="IFC4",
        source_lines=0,
        sites=(site,),
        buildings=(building,),
        storeys=tuple(st for st, _ in floors),
        spaces=(corridor,),
        elements=tuple(elements),
        adjacent=frozenset({Relation(corridor.guid, spec("Corridor north").guid)}),
        contained=frozenset(contained),
        decomposed=frozenset(),
    )
