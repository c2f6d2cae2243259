"""The bundled sample building's plan as plain data: the lab of de Vos et al., typed once.

The paper "Generation of skill-specific maps from graph world models for robotic systems" shows its
method on a small lab: two rooms joined by a corridor, with an arch across the corridor that a lidar
at 0.1 m sees under but a 0.5 m tall robot cannot pass, a glass wall that a lidar does not see, and a
table. This module holds that lab's plan, storey by storey in each storey's frame (boxes, classes,
materials, relationships) and nothing else; ``twin.samples.lab_layout`` places it in the world and names its
GlobalIds. ``adapters.ifc.sample_lab`` writes it as an IFC4 file, and the core's tests build the same
lab as records from its boxes (``tests/twin/box_lab.py``).

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

Walls are 0.2 m thick and 2.7 m tall (the glass wall 0.1 m). The arch (an ``IfcWall`` of steel, as
the paper's selection keeps it: the localization map's ``include_types = ["IfcWall"]`` selects it and
only its height keeps it out of a 0.1 m lidar's map) spans the corridor at x 5.9..6.1 from z 0.3 to
1.0 m. The table (an ``IfcFurnishingElement``, 1.2 x 0.8 x 0.75 m) stands in Room A at x 1.4..2.6,
y 2.6..3.4. With two storeys a first floor at elevation 3.0 m holds one hall (x 0..12, y 0..4) with a
short interior wall at x 5.9..6.1, y 0..1.0, where the ground floor has nothing, and no arch.

Each storey stands on a floor slab (``IfcSlab``, predefined type FLOOR, concrete, 0.2 m thick) that
covers its whole footprint, outer wall faces included, with its top at the storey's elevation: so it
lies below every map's heights of its own storey. The ground floor's slab is H-shaped (its
``outline``), the rooms and the corridor; the first floor's is the rectangle x -0.2..12.2,
y -0.2..4.2. A slab's layout box is its bounding box.

Door A (``IfcDoor``, wood, 0.9 m wide, 2.1 m high, 0.05 m thick) stands in the middle of Wall A
south's thickness. It fills "Door A opening", an ``IfcOpeningElement`` through the wall's full
thickness up to 2.1 m that voids the wall; the opening has no material and no spatial container: its
layout ``container`` is the wall it voids.

Example::

    GROUND_FLOOR.elements[0].box              # Box(xmin=-0.2, ymin=-0.2, zmin=0.0, ...): storey frame
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final, NamedTuple

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

PROJECT: Final = "Sample lab"
SITE: Final = "Lab site"
BUILDING: Final = "Lab"


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

    def minus(self, other: Box) -> tuple[Box, ...]:
        """Disjoint boxes that together cover this box less ``other`` (none overlap ``other``)."""
        lo, hi = list(self[:3]), list(self[3:])
        if any(other[a] >= hi[a] or other[a + 3] <= lo[a] for a in range(3)):
            return (self,)
        pieces = []
        for axis in range(3):  # peel off the slabs on either side of the cut, axis by axis
            for start, end in ((lo[axis], other[axis]), (other[axis + 3], hi[axis])):
                if start < end:
                    piece_lo, piece_hi = lo.copy(), hi.copy()
                    piece_lo[axis], piece_hi[axis] = start, end
                    pieces.append(Box._make((*piece_lo, *piece_hi)))
            lo[axis], hi[axis] = max(lo[axis], other[axis]), min(hi[axis], other[axis + 3])
        return tuple(pieces)


XY = tuple[float, float]


# --- the plan, in each storey's frame (metres) ----------------------------------------------------


@dataclass(frozen=True, slots=True)
class ElementPlan:
    """One element as drawn: its box in the storey's frame, class, material and relationships."""

    name: str
    box: Box
    material: str | None
    ifc_class: str = "IfcWall"
    space: str | None = None
    """Contained in this space instead of the storey."""
    predefined_type: str | None = None
    outline: tuple[XY, ...] = ()
    """A footprint other than the box's rectangle (storey frame, counter-clockwise)."""
    voids: str | None = None
    """An opening: the element it cuts (an opening is not spatially contained)."""
    fills: str | None = None
    """A door: the opening it fills."""


@dataclass(frozen=True, slots=True)
class SpacePlan:
    name: str
    box: Box
    bounded_by: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class StoreyPlan:
    name: str
    elevation: float
    elements: tuple[ElementPlan, ...]
    spaces: tuple[SpacePlan, ...]


def _wall(name: str, xy0: XY, xy1: XY, material: str = "Concrete") -> ElementPlan:
    """A full-height wall from floor corner ``xy0`` to ``xy1`` (storey frame, metres)."""
    return ElementPlan(name, Box(*xy0, 0.0, *xy1, WALL_HEIGHT), material)


def _floor_slab(storey: str, outline: tuple[XY, ...]) -> ElementPlan:
    """The storey's floor: ``outline`` (storey frame, counter-clockwise) from z -0.2 up to z 0."""
    xs, ys = [x for x, _ in outline], [y for _, y in outline]
    box = Box(min(xs), min(ys), -SLAB_THICKNESS, max(xs), max(ys), 0.0)
    return ElementPlan(f"{storey} slab", box, "Concrete", "IfcSlab", predefined_type="FLOOR", outline=outline)


_H_SHAPE: Final = (
    (-0.2, -0.2), (4.2, -0.2), (4.2, 1.2), (7.8, 1.2), (7.8, -0.2), (12.1, -0.2),
    (12.1, 4.2), (7.8, 4.2), (7.8, 2.8), (4.2, 2.8), (4.2, 4.2), (-0.2, 4.2),
)  # fmt: skip

GROUND_FLOOR: Final = StoreyPlan(
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
        ElementPlan(ARCH, Box(5.9, 1.4, 0.3, 6.1, 2.6, 1.0), "Steel"),
        ElementPlan(TABLE, Box(1.4, 2.6, 0.0, 2.6, 3.4, 0.75), "Wood", "IfcFurnishingElement", "Room A"),
        _floor_slab("Ground floor", _H_SHAPE),
        ElementPlan(
            DOOR_OPENING,
            Box(1.55, -0.2, 0.0, 2.45, 0.0, 2.1),
            None,
            "IfcOpeningElement",
            predefined_type="OPENING",
            voids=DOOR_HOST,
        ),
        ElementPlan(
            DOOR,
            Box(1.55, -0.125, 0.0, 2.45, -0.075, 2.1),
            "Wood",
            "IfcDoor",
            predefined_type="DOOR",
            fills=DOOR_OPENING,
        ),
    ),
    spaces=(
        SpacePlan(
            "Room A",
            Box(0.0, 0.0, 0.0, 4.0, 4.0, WALL_HEIGHT),
            ("Wall A south", "Wall A west", "Wall A north", "Wall A east 1", "Wall A east 2", DOOR),
        ),
        SpacePlan(
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
        SpacePlan(
            "Room B",
            Box(8.0, 0.0, 0.0, 12.0, 4.0, WALL_HEIGHT),
            ("Wall B south", "Wall B north", "Wall B west 1", "Wall B west 2", GLASS_WALL),
        ),
    ),
)

FIRST_FLOOR: Final = StoreyPlan(
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
        SpacePlan(
            "Hall",
            Box(0.0, 0.0, 0.0, 12.0, 4.0, WALL_HEIGHT),
            ("Wall L1 south", "Wall L1 west", "Wall L1 north", "Wall L1 east", "Wall L1 interior"),
        ),
    ),
)

STOREY_PLANS: Final = (GROUND_FLOOR, FIRST_FLOOR)
