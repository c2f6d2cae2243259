"""A synthetic Neuron-size building, written as IFC4 with ``ifcopenshell.api`` (benchmarks only).

The paper's large model (the Neuron building, TU Eindhoven) has 11,500 elements and 10,822 meshes. It
is not public, so this generator writes an office building of the same size: a long slab of
``storeys`` floors, each a double-loaded corridor between two rows of rooms, with a stair core and a
service core at each end. Deterministic from ``--seed`` (the same seed, storeys and scale give the same
file byte for byte, in either unit, up to the unit; GlobalIds do not depend on the unit).

One storey, in the storey's frame (metres; interior faces at y 0 and y 16.8)::

       x=0      7.2                                               L-7.2     L
  16.8 +--------+------+------+------+--- ... ---+------+------+--------+     façade: curtain wall
       |service | room | room | room |           | room | room |service |     (plates + mullions) or
   9.6 +---D----+--D---+---D--+--D---+--- ... ---+---D--+---D--+----D---+     a brick wall + window
       |                      corridor (one IfcSpace)                   |
   7.2 +---D----+--D---+---D--+--D---+--- ... ---+---D--+---D--+----D---+     D: a door in an opening
       | stair  | room | room | room |           | room | room | stair  |
     0 +--------+------+------+------+--- ... ---+------+------+--------+
     gable wall (clipped)                                        gable wall (clipped)

- rooms (3.6 m x 7.2 m), offices (2 desks, 2 chairs, 2 cabinets, a shelf) or meeting rooms (a table,
  6 chairs, a glass wall to the corridor); each is an ``IfcSpace`` with ``IfcRelSpaceBoundary`` to its
  walls, door and façade; the corridor and the cores are spaces too;
- partitions: plasterboard walls, some glass walls, some glass panes (``IfcPlate``), some clipped at
  their top corner by a sloped plane (``IfcBooleanClippingResult``, like a duct chase); the gable walls
  are clipped too;
- doors fill ``IfcOpeningElement``s that void their walls (``IfcRelVoidsElement``,
  ``IfcRelFillsElement``), windows likewise in the brick façade walls;
- columns, beams, a floor slab (with stairwell openings above the ground floor), a roof slab, stairs
  (``IfcStair`` aggregating two stepped flights, a landing and railings), ceilings, lights, radiators,
  sanitary terminals;
- chairs, cabinets, lights, radiators and toilets are occurrences of types (``IfcFurnitureType`` etc.)
  whose body is a mapped representation; desks, tables and shelves have their own geometry.

Usage::

    python benchmarks/neuron_gen.py OUT.ifc [--seed 1] [--storeys 6] [--unit m|mm] [--scale 1.0]

``--scale`` scales the number of rooms per storey (1.0: 42 per side, about 12,000 elements over 6
storeys; 0.05: 2 per side, for tests). From Python: ``generate(path, Options(storeys=1, scale=0.05))``.
"""

from __future__ import annotations

import argparse
import math
import random
import sys
import time
import uuid
from collections import Counter, defaultdict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final, Literal

import ifcopenshell
import ifcopenshell.api.aggregate
import ifcopenshell.api.context
import ifcopenshell.api.feature
import ifcopenshell.api.geometry
import ifcopenshell.api.material
import ifcopenshell.api.project
import ifcopenshell.api.root
import ifcopenshell.api.spatial
import ifcopenshell.api.type
import ifcopenshell.api.unit
import ifcopenshell.guid

Unit = Literal["m", "mm"]
METRES_PER_UNIT: Final[dict[str, float]] = {"m": 1.0, "mm": 0.001}

ROOM_W: Final = 3.6
ROOM_D: Final = 7.2
CORRIDOR_W: Final = 2.4
CORE_W: Final = 7.2
DEPTH: Final = 2 * ROOM_D + CORRIDOR_W  # 16.8: interior depth, façade to façade
STOREY_H: Final = 3.6
SLAB_T: Final = 0.3
WALL_H: Final = STOREY_H - SLAB_T  # walls stand on the slab and stop under the next one
CEILING_Z: Final = 2.9
PARTITION_T: Final = 0.1
CORRIDOR_T: Final = 0.15
FACADE_T: Final = 0.3
DOOR_W: Final = 1.0
DOOR_H: Final = 2.1
ROOMS_PER_SIDE: Final = 42
BUILDING_ORIGIN: Final = (50.0, 20.0, 0.0)
TIMESTAMP: Final = "2026-11-23T00:00:00"
_NAMESPACE: Final = uuid.uuid5(uuid.NAMESPACE_URL, "https://w3id.org/building-twin/benchmarks/neuron")

_XYZ = tuple[float, float, float]
_Entity = ifcopenshell.entity_instance


@dataclass(frozen=True, slots=True)
class Options:
    """What to generate: ``scale`` multiplies the rooms per storey side (at least 2)."""

    seed: int = 1
    storeys: int = 6
    unit: Unit = "m"
    scale: float = 1.0

    @property
    def rooms_per_side(self) -> int:
        return max(2, round(ROOMS_PER_SIDE * self.scale))


@dataclass(frozen=True, slots=True)
class Summary:
    """What a generation wrote: entity counts per exact class (elements, spaces, relations, ...)."""

    path: Path
    options: Options
    elements: int
    spaces: int
    counts: dict[str, int]
    seconds: float

    def count(self, ifc_class: str) -> int:
        return self.counts.get(ifc_class, 0)


_COUNTED: Final = (
    "IfcSpace",
    "IfcRelSpaceBoundary",
    "IfcRelVoidsElement",
    "IfcRelFillsElement",
    "IfcRelAggregates",
    "IfcBooleanClippingResult",
    "IfcMappedItem",
    "IfcRepresentationMap",
    "IfcBuildingStorey",
)


@dataclass(slots=True)
class _Storey:
    entity: _Entity
    index: int
    elevation: float
    contained: list[_Entity] = field(default_factory=list)
    placements: list[tuple[_Entity, _XYZ, _XYZ]] = field(default_factory=list)


class _Builder:
    """One generation: the file, its unit scale, shared geometry entities and deferred relations."""

    def __init__(self, options: Options) -> None:
        self.o = options
        self.rng = random.Random(options.seed)
        self.s = METRES_PER_UNIT[options.unit]
        self.f = ifcopenshell.api.project.create_file(version="IFC4")
        self.project = self._product("IfcProject", "Neuron-size building")
        self._assign_units()
        model = ifcopenshell.api.context.add_context(self.f, context_type="Model")
        self.body = ifcopenshell.api.context.add_context(
            self.f, context_type="Model", context_identifier="Body", target_view="MODEL_VIEW", parent=model
        )
        self._dirs: dict[tuple[float, ...], _Entity] = {}
        self.materials: dict[str, _Entity] = {}
        self.by_material: dict[str, list[_Entity]] = defaultdict(list)
        self.types: dict[str, _Entity] = {}
        self.occurrences: dict[str, list[_Entity]] = defaultdict(list)
        self.in_space: dict[int, tuple[_Entity, list[_Entity]]] = {}
        self.n_rooms = options.rooms_per_side
        self.length = 2 * CORE_W + self.n_rooms * ROOM_W

    # --- units, ids and primitive geometry (lengths in metres, written in the project unit) ---------

    def _assign_units(self) -> None:
        prefix = "MILLI" if self.o.unit == "mm" else None
        units = [ifcopenshell.api.unit.add_si_unit(self.f, unit_type="LENGTHUNIT", prefix=prefix)]
        units += [ifcopenshell.api.unit.add_si_unit(self.f, unit_type=t) for t in ("AREAUNIT", "VOLUMEUNIT")]
        ifcopenshell.api.unit.assign_unit(self.f, units=units)

    def _l(self, metres: float) -> float:
        return round(metres / self.s, 9)

    def _pt(self, x: float, y: float, z: float) -> _Entity:
        return self.f.createIfcCartesianPoint((self._l(x), self._l(y), self._l(z)))

    def _pt2(self, x: float, y: float) -> _Entity:
        return self.f.createIfcCartesianPoint((self._l(x), self._l(y)))

    def _dir(self, d: tuple[float, ...]) -> _Entity:
        if d not in self._dirs:
            self._dirs[d] = self.f.createIfcDirection(d)
        return self._dirs[d]

    def _axis(self, origin: _XYZ, x: _XYZ = (1.0, 0.0, 0.0), z: _XYZ = (0.0, 0.0, 1.0)) -> _Entity:
        return self.f.createIfcAxis2Placement3D(self._pt(*origin), self._dir(z), self._dir(x))

    def _prism(
        self, sx: float, sy: float, sz: float, at: _XYZ = (0.0, 0.0, 0.0), centred_y: bool = False
    ) -> _Entity:
        """A box from ``at`` (its low corner; or centred in y on ``at`` with ``centred_y``) of size
        ``sx, sy, sz`` in the product's frame: a rectangle profile extruded up."""
        cy = 0.0 if centred_y else sy / 2
        position = self.f.createIfcAxis2Placement2D(self._pt2(sx / 2, cy), self._dir((1.0, 0.0)))
        profile = self.f.createIfcRectangleProfileDef("AREA", None, position, self._l(sx), self._l(sy))
        return self.f.createIfcExtrudedAreaSolid(
            profile, self._axis(at), self._dir((0.0, 0.0, 1.0)), self._l(sz)
        )

    def _polygon_prism(
        self, points: Sequence[tuple[float, float]], depth: float, position: _Entity
    ) -> _Entity:
        pts = [self._pt2(x, y) for x, y in points]
        curve = self.f.createIfcPolyline([*pts, pts[0]])
        profile = self.f.createIfcArbitraryClosedProfileDef("AREA", None, curve)
        return self.f.createIfcExtrudedAreaSolid(
            profile, position, self._dir((0.0, 0.0, 1.0)), self._l(depth)
        )

    def _shape(self, items: Sequence[_Entity], kind: str = "SweptSolid") -> _Entity:
        rep = self.f.createIfcShapeRepresentation(self.body, "Body", kind, list(items))
        return self.f.createIfcProductDefinitionShape(None, None, [rep])

    def _product(self, ifc_class: str, name: str, predefined_type: str | None = None) -> _Entity:
        return ifcopenshell.api.root.create_entity(
            self.f, ifc_class=ifc_class, name=name, predefined_type=predefined_type
        )

    def _material(self, product: _Entity, name: str) -> None:
        if name not in self.materials:
            self.materials[name] = ifcopenshell.api.material.add_material(
                self.f, name=name, category=name.lower()
            )
        self.by_material[name].append(product)

    # --- elements --------------------------------------------------------------------------------------

    def element(
        self,
        st: _Storey,
        ifc_class: str,
        name: str,
        origin: _XYZ,
        items: Sequence[_Entity] = (),
        *,
        material: str | None = None,
        predefined_type: str | None = None,
        x_axis: _XYZ = (1.0, 0.0, 0.0),
        kind: str = "SweptSolid",
        space: _Entity | None = None,
        contained: bool = True,
    ) -> _Entity:
        """A product at ``origin`` (storey frame) with body ``items`` (its frame); placed when the storey
        is finished, after its relations (the API re-places what is already placed)."""
        product = self._product(ifc_class, name, predefined_type)
        if items:
            product.Representation = self._shape(items, kind)
        if material is not None:
            self._material(product, material)
        if space is not None:
            self.in_space.setdefault(space.id(), (space, []))[1].append(product)
        elif contained:
            st.contained.append(product)
        st.placements.append((product, origin, x_axis))
        return product

    def box(
        self,
        st: _Storey,
        ifc_class: str,
        name: str,
        lo: _XYZ,
        hi: _XYZ,
        *,
        material: str | None = None,
        predefined_type: str | None = None,
        space: _Entity | None = None,
        contained: bool = True,
    ) -> _Entity:
        """An axis-aligned box element from corner ``lo`` to ``hi`` (storey frame)."""
        size = (hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2])
        return self.element(
            st,
            ifc_class,
            name,
            lo,
            [self._prism(*size)],
            material=material,
            predefined_type=predefined_type,
            space=space,
            contained=contained,
        )

    def wall(
        self,
        st: _Storey,
        name: str,
        start: tuple[float, float],
        end: tuple[float, float],
        thickness: float,
        *,
        material: str,
        predefined_type: str = "PARTITIONING",
        ifc_class: str = "IfcWall",
        clip: float = 0.0,
    ) -> _Entity:
        """A full-height wall centred on the axis-aligned line ``start``-``end``; ``clip`` > 0 cuts its
        top corner at ``end`` by a 45-degree plane (``IfcBooleanClippingResult``) of that size."""
        length = math.dist(start, end)
        x_axis = ((end[0] - start[0]) / length, (end[1] - start[1]) / length, 0.0)
        solid = self._prism(length, thickness, WALL_H, centred_y=True)
        kind = "SweptSolid"
        if clip > 0:
            r = math.sqrt(0.5)
            plane = self.f.createIfcPlane(
                self._axis((length - clip, 0.0, WALL_H), x=(r, 0.0, -r), z=(r, 0.0, r))
            )
            half = self.f.createIfcHalfSpaceSolid(plane, False)
            solid = self.f.createIfcBooleanClippingResult("DIFFERENCE", solid, half)
            kind = "Clipping"
        return self.element(
            st,
            ifc_class,
            name,
            (start[0], start[1], 0.0),
            [solid],
            material=material,
            predefined_type=predefined_type,
            x_axis=x_axis,
            kind=kind,
        )

    def filled_opening(
        self,
        st: _Storey,
        host: _Entity,
        name: str,
        *,
        start: tuple[float, float],
        x_axis: tuple[float, float],
        along: float,
        thickness: float,
        width: float,
        sill: float,
        height: float,
        filling: str,
    ) -> _Entity:
        """An opening ``along`` metres into a wall running from ``start`` in direction ``x_axis``,
        voiding it, and a door or window (``filling``) in it, in the middle of the wall's thickness."""
        ox, oy = start[0] + x_axis[0] * along, start[1] + x_axis[1] * along
        axis3 = (x_axis[0], x_axis[1], 0.0)
        opening = self.element(
            st,
            "IfcOpeningElement",
            f"{name} opening",
            (ox, oy, sill),
            [self._prism(width, thickness + 0.2, height, centred_y=True)],
            predefined_type="OPENING",
            x_axis=axis3,
            contained=False,
        )
        ifcopenshell.api.feature.add_feature(self.f, feature=opening, element=host)
        is_door = filling == "IfcDoor"
        leaf = 0.05 if is_door else 0.08
        fill = self.element(
            st,
            filling,
            name,
            (ox, oy, sill),
            [self._prism(width, leaf, height, centred_y=True)],
            material="Wood" if is_door else "Glass",
            predefined_type="DOOR" if is_door else "WINDOW",
            x_axis=axis3,
        )
        fill.OverallWidth = self._l(width)
        fill.OverallHeight = self._l(height)
        ifcopenshell.api.feature.add_filling(self.f, opening=opening, element=fill)
        return fill

    def typed(
        self,
        st: _Storey,
        type_name: str,
        name: str,
        origin: _XYZ,
        *,
        yaw: float = 0.0,
        space: _Entity | None = None,
    ) -> _Entity:
        """An occurrence of one of the shared types (its body is mapped from the type's)."""
        ifc_type, ifc_class, predefined, material, _ = _TYPES[type_name]
        if type_name not in self.types:
            t = self._product(ifc_type, type_name, predefined)
            rep = self._shape(_TYPES[type_name][4](self)).Representations[0]
            ifcopenshell.api.geometry.assign_representation(self.f, product=t, representation=rep)
            self._material(t, material)
            self.types[type_name] = t
        product = self.element(
            st,
            ifc_class,
            name,
            origin,
            predefined_type=predefined,
            x_axis=(math.cos(yaw), math.sin(yaw), 0.0),
            space=space,
        )
        self.occurrences[type_name].append(product)
        return product

    def space(self, st: _Storey, name: str, lo: tuple[float, float], hi: tuple[float, float]) -> _Entity:
        sp = self._product("IfcSpace", name, "INTERNAL")
        sp.Representation = self._shape([self._prism(hi[0] - lo[0], hi[1] - lo[1], WALL_H)])
        ifcopenshell.api.aggregate.assign_object(self.f, products=[sp], relating_object=st.entity)
        st.placements.append((sp, (lo[0], lo[1], 0.0), (1.0, 0.0, 0.0)))
        return sp

    def bounds(self, space: _Entity, elements: Sequence[_Entity], external: Sequence[_Entity] = ()) -> None:
        for e in (*elements, *external):
            self.f.createIfcRelSpaceBoundary(
                ifcopenshell.guid.new(),
                None,
                None,
                None,
                space,
                e,
                None,
                "PHYSICAL",
                "EXTERNAL" if e in external else "INTERNAL",
            )

    # --- the building -----------------------------------------------------------------------------------

    def build(self, progress: Callable[[str], None]) -> None:
        site = self._product("IfcSite", "Campus")
        ifcopenshell.api.aggregate.assign_object(self.f, products=[site], relating_object=self.project)
        building = self._product("IfcBuilding", "Neuron-size building")
        ifcopenshell.api.aggregate.assign_object(self.f, products=[building], relating_object=site)
        site.ObjectPlacement = self.f.createIfcLocalPlacement(None, self._axis((0.0, 0.0, 0.0)))
        building.ObjectPlacement = self.f.createIfcLocalPlacement(
            site.ObjectPlacement, self._axis(BUILDING_ORIGIN)
        )
        t0 = time.perf_counter()
        for i in range(self.o.storeys):
            entity = self._product("IfcBuildingStorey", f"Level {i}")
            entity.Elevation = self._l(i * STOREY_H)
            ifcopenshell.api.aggregate.assign_object(self.f, products=[entity], relating_object=building)
            entity.ObjectPlacement = self.f.createIfcLocalPlacement(
                building.ObjectPlacement, self._axis((0.0, 0.0, i * STOREY_H))
            )
            st = _Storey(entity, i, i * STOREY_H)
            self._storey(st)
            self._finish(st)
            n = len(self.f.by_type("IfcElement"))
            progress(
                f"storey {i + 1}/{self.o.storeys}: {n:,} elements so far, {time.perf_counter() - t0:.1f} s"
            )
        for type_name, products in self.occurrences.items():
            for product in products:  # one at a time: the API iterates a set, in no fixed order
                ifcopenshell.api.type.assign_type(
                    self.f, related_objects=[product], relating_type=self.types[type_name]
                )
        for name, products in self.by_material.items():
            ifcopenshell.api.material.assign_material(
                self.f, products=products, type="IfcMaterial", material=self.materials[name]
            )
        self._stable_ids()

    def _finish(self, st: _Storey) -> None:
        """The storey's containment (API, before placing), then every placement, relative to the storey."""
        ifcopenshell.api.spatial.assign_container(self.f, products=st.contained, relating_structure=st.entity)
        for space, products in self.in_space.values():
            ifcopenshell.api.spatial.assign_container(self.f, products=products, relating_structure=space)
        self.in_space.clear()
        rel_to = st.entity.ObjectPlacement
        for product, origin, x_axis in st.placements:
            product.ObjectPlacement = self.f.createIfcLocalPlacement(rel_to, self._axis(origin, x=x_axis))

    def _stable_ids(self) -> None:
        """GlobalIds from the seed and the creation order (the API mints random ones), and the
        relationships' and unit assignment's lists in creation order (the API builds some through
        sets)."""
        for rel in self.f.by_type("IfcRelationship"):
            for i, value in enumerate(rel):
                if isinstance(value, tuple) and value and isinstance(value[0], ifcopenshell.entity_instance):
                    rel[i] = sorted(value, key=lambda e: e.id())
        for units in self.f.by_type("IfcUnitAssignment"):  # the API assigns the units through a set too
            units.Units = sorted(units.Units, key=lambda e: e.id())
        for i, root in enumerate(sorted(self.f.by_type("IfcRoot"), key=lambda e: e.id())):
            root.GlobalId = ifcopenshell.guid.compress(uuid.uuid5(_NAMESPACE, f"{self.o.seed}/{i}").hex)

    def _storey(self, st: _Storey) -> None:
        top = st.index == self.o.storeys - 1
        length, n = self.length, self.n_rooms
        # Floor slab (the whole footprint, outer wall faces included), its top at the storey's floor.
        slab = self.box(
            st,
            "IfcSlab",
            f"L{st.index} floor slab",
            (-FACADE_T, -FACADE_T, -SLAB_T),
            (length + FACADE_T, DEPTH + FACADE_T, 0.0),
            material="Concrete",
            predefined_type="FLOOR",
        )
        if st.index > 0:  # stairwells from the storey below
            for k, x0 in enumerate(self._stair_xs()):
                hole = self.element(
                    st,
                    "IfcOpeningElement",
                    f"L{st.index} stairwell {k}",
                    (x0 + 0.8, 0.8, -SLAB_T - 0.1),
                    [self._prism(4.8, 2.8, SLAB_T + 0.2)],
                    predefined_type="OPENING",
                    contained=False,
                )
                ifcopenshell.api.feature.add_feature(self.f, feature=hole, element=slab)
        if top:
            self.box(
                st,
                "IfcSlab",
                "Roof slab",
                (-FACADE_T, -FACADE_T, WALL_H),
                (length + FACADE_T, DEPTH + FACADE_T, STOREY_H),
                material="Concrete",
                predefined_type="ROOF",
            )
        # Gable walls at both ends, their top outer corner clipped.
        self.wall(
            st,
            f"L{st.index} gable west",
            (-FACADE_T / 2, DEPTH + FACADE_T),
            (-FACADE_T / 2, -FACADE_T),
            FACADE_T,
            material="Brick",
            predefined_type="SOLIDWALL",
            clip=0.8,
        )
        self.wall(
            st,
            f"L{st.index} gable east",
            (length + FACADE_T / 2, -FACADE_T),
            (length + FACADE_T / 2, DEPTH + FACADE_T),
            FACADE_T,
            material="Brick",
            predefined_type="SOLIDWALL",
            clip=0.8,
        )
        self._structure(st)
        corridor = self.space(st, f"L{st.index} corridor", (0.0, ROOM_D), (length, ROOM_D + CORRIDOR_W))
        corridor_bounds: list[_Entity] = []
        xs = [0.0, CORE_W, *(CORE_W + ROOM_W * (i + 1) for i in range(n)), length]
        for side in ("S", "N"):
            partitions = [self._partition(st, side, i, x) for i, x in enumerate(xs[1:-1])]
            for r in range(len(xs) - 1):
                kind = "stair" if side == "S" else "service"
                if 0 < r < len(xs) - 2:
                    kind = "meeting" if self.rng.random() < 0.2 else "office"
                left = partitions[r - 1] if r > 0 else None
                right = partitions[r] if r < len(partitions) else None
                bounding = [p for p in (left, right) if p]
                corridor_bounds += self._room(st, side, r, (xs[r], xs[r + 1]), kind=kind, partitions=bounding)
        self.bounds(corridor, corridor_bounds)
        self.box(
            st,
            "IfcCovering",
            f"L{st.index} corridor ceiling",
            (0.0, ROOM_D, CEILING_Z),
            (length, ROOM_D + CORRIDOR_W, CEILING_Z + 0.02),
            material="Mineral fibre",
            predefined_type="CEILING",
            space=corridor,
        )
        for k in range(int(length // 7.2)):
            self.typed(
                st,
                "Light",
                f"L{st.index} corridor light {k}",
                (3.0 + 7.2 * k, ROOM_D + 1.05, CEILING_Z - 0.05),
                space=corridor,
            )

    def _stair_xs(self) -> tuple[float, float]:
        return (0.0, self.length - CORE_W)

    def _structure(self, st: _Storey) -> None:
        """Columns on a 7.2 m grid on the four long lines, beams across under the next slab."""
        lines_y = (0.0, ROOM_D, ROOM_D + CORRIDOR_W, DEPTH)
        xs = [CORE_W + 7.2 * k for k in range(int((self.length - 2 * CORE_W) // 7.2) + 1)]
        for k, x in enumerate(xs):
            for j, y in enumerate(lines_y):
                y0 = min(max(y - 0.2, 0.0), DEPTH - 0.4)
                self.box(
                    st,
                    "IfcColumn",
                    f"L{st.index} column {k}-{j}",
                    (x - 0.2, y0, 0.0),
                    (x + 0.2, y0 + 0.4, WALL_H),
                    material="Concrete",
                    predefined_type="COLUMN",
                )
            for j in range(3):
                self.box(
                    st,
                    "IfcBeam",
                    f"L{st.index} beam {k}-{j}",
                    (x - 0.15, lines_y[j], WALL_H - 0.35),
                    (x + 0.15, lines_y[j + 1], WALL_H),
                    material="Concrete",
                    predefined_type="BEAM",
                )

    def _partition(self, st: _Storey, side: str, i: int, x: float) -> _Entity:
        """The wall between two rooms at ``x``: plasterboard, glass, a glass pane, or clipped."""
        y0, y1 = (0.0, ROOM_D) if side == "S" else (ROOM_D + CORRIDOR_W, DEPTH)
        name = f"L{st.index} partition {side}{i}"
        roll = self.rng.random()
        if roll < 0.1:  # a glass pane partition (IfcPlate)
            return self.box(
                st,
                "IfcPlate",
                name,
                (x - 0.01, y0, 0.0),
                (x + 0.01, y1, WALL_H),
                material="Glass",
                predefined_type="SHEET",
            )
        if roll < 0.25:
            return self.wall(st, name, (x, y0), (x, y1), 0.05, material="Glass")
        clip = 0.6 if roll > 0.95 else 0.0
        if side == "N":  # the clipped corner is at the corridor end
            return self.wall(st, name, (x, y1), (x, y0), PARTITION_T, material="Plasterboard", clip=clip)
        return self.wall(st, name, (x, y0), (x, y1), PARTITION_T, material="Plasterboard", clip=clip)

    def _room(
        self,
        st: _Storey,
        side: str,
        r: int,
        span: tuple[float, float],
        *,
        kind: str,
        partitions: list[_Entity],
    ) -> list[_Entity]:
        """One room between x ``span``; returns what also bounds the corridor (its wall and door)."""
        x0, x1 = span
        south = side == "S"
        y0, y1 = (0.0, ROOM_D) if south else (ROOM_D + CORRIDOR_W, DEPTH)
        tag = f"L{st.index} {side}{r}"
        space = self.space(st, f"{tag} {kind}", (x0, y0), (x1, y1))
        width = x1 - x0
        # Corridor wall, a door in it (glass for meeting rooms).
        cy = y1 if south else y0
        glass = kind == "meeting"
        t = 0.05 if glass else CORRIDOR_T
        cwall = self.wall(
            st, f"{tag} corridor wall", (x0, cy), (x1, cy), t, material="Glass" if glass else "Plasterboard"
        )
        at = self.rng.uniform(0.4, width - DOOR_W - 0.4)
        door = self.filled_opening(
            st,
            cwall,
            f"{tag} door",
            start=(x0, cy),
            x_axis=(1.0, 0.0),
            along=at,
            thickness=t,
            width=DOOR_W,
            sill=0.0,
            height=DOOR_H,
            filling="IfcDoor",
        )
        # Façade: a curtain wall (plates and members) or a brick wall with a window.
        fy = -FACADE_T / 2 if south else DEPTH + FACADE_T / 2
        facade: list[_Entity] = []
        if kind in ("office", "meeting") and self.rng.random() < 0.7:
            facade.append(self._curtain_wall(st, tag, span, y=0.0 if south else DEPTH, south=south))
        else:
            fwall = self.wall(
                st,
                f"{tag} facade wall",
                (x0, fy),
                (x1, fy),
                FACADE_T,
                material="Brick",
                predefined_type="SOLIDWALL",
            )
            facade.append(fwall)
            if kind != "stair":
                facade.append(
                    self.filled_opening(
                        st,
                        fwall,
                        f"{tag} window",
                        start=(x0, fy),
                        x_axis=(1.0, 0.0),
                        along=0.6,
                        thickness=FACADE_T,
                        width=width - 1.2,
                        sill=0.9,
                        height=1.5,
                        filling="IfcWindow",
                    )
                )
        self.bounds(space, [*partitions, cwall, door], facade)

        # Contents, in the room's frame: u along x from x0, v from the façade inwards.
        def at_uv(u: float, v: float, z: float) -> _XYZ:
            return (x0 + u, v if south else DEPTH - v, z)

        def uv_box(
            cls: str,
            name: str,
            u: tuple[float, float],
            v: tuple[float, float],
            z: tuple[float, float],
            *,
            material: str,
            ptype: str | None = None,
        ) -> _Entity:
            a, b = at_uv(u[0], v[0], z[0]), at_uv(u[1], v[1], z[1])
            lo = (min(a[0], b[0]), min(a[1], b[1]), a[2])
            hi = (max(a[0], b[0]), max(a[1], b[1]), b[2])
            return self.box(st, cls, name, lo, hi, material=material, predefined_type=ptype, space=space)

        facing = 0.0 if south else math.pi
        if kind in ("office", "meeting"):
            uv_box(
                "IfcCovering",
                f"{tag} ceiling",
                (0.05, width - 0.05),
                (0.0, ROOM_D - 0.1),
                (CEILING_Z, CEILING_Z + 0.02),
                material="Mineral fibre",
                ptype="CEILING",
            )
            for k in range(2):
                self.typed(
                    st,
                    "Light",
                    f"{tag} light {k}",
                    at_uv(width / 2 - 0.6, 2.0 + 3.0 * k, CEILING_Z - 0.05),
                    space=space,
                )
            self.typed(st, "Radiator", f"{tag} radiator", at_uv(width / 2 - 0.5, 0.15, 0.15), space=space)
        if kind == "office":
            for k in range(2):
                u0 = 0.15 + k * (width / 2)
                self._desk(
                    st,
                    f"{tag} desk {k}",
                    at_uv(u0, 1.0, 0.0),
                    width=self.rng.uniform(1.2, width / 2 - 0.3),
                    south=south,
                    space=space,
                )
                yaw = facing + math.pi / 2 + self.rng.uniform(-0.6, 0.6)
                self.typed(st, "Chair", f"{tag} chair {k}", at_uv(u0 + 0.7, 2.3, 0.0), yaw=yaw, space=space)
            for k in range(2):
                u = 0.1 + 0.85 * k + (0.0 if south else 0.8)  # its origin is a corner: turned, the other one
                self.typed(
                    st, "Cabinet", f"{tag} cabinet {k}", at_uv(u, ROOM_D - 0.6, 0.0), yaw=facing, space=space
                )
            h = round(self.rng.uniform(1.8, 2.2), 2)
            uv_box(
                "IfcFurniture",
                f"{tag} shelf",
                (width - 0.45, width - 0.1),
                (3.0, 4.8),
                (0.0, h),
                material="Wood",
                ptype="SHELF",
            )
        elif kind == "meeting":
            tl = round(self.rng.uniform(1.8, 2.4), 2)
            u0, v0 = width / 2 - 0.5, 3.6 - tl / 2
            self._desk(
                st,
                f"{tag} table",
                at_uv(u0, v0, 0.0),
                width=1.0,
                south=south,
                space=space,
                depth=tl,
                ptype="TABLE",
            )
            for k in range(6):
                left = k % 2 == 0
                v = v0 + 0.3 + (k // 2) * (tl - 0.6) / 2
                u = u0 - 0.5 if left else u0 + 1.5
                yaw = (0.0 if left else math.pi) + self.rng.uniform(-0.3, 0.3)
                self.typed(st, "Chair", f"{tag} chair {k}", at_uv(u, v, 0.0), yaw=yaw, space=space)
        elif kind == "service":
            for k in range(3):
                self.typed(
                    st,
                    "Toilet",
                    f"{tag} toilet {k}",
                    at_uv(0.6 + 2.0 * k, ROOM_D - 0.9, 0.0),
                    yaw=facing,
                    space=space,
                )
        elif kind == "stair" and st.index < self.o.storeys - 1:
            self._stair(st, tag, x0, space)
        return [cwall, door]

    def _desk(
        self,
        st: _Storey,
        name: str,
        corner: _XYZ,
        *,
        width: float,
        south: bool,
        space: _Entity,
        depth: float = 0.8,
        ptype: str = "DESK",
    ) -> None:
        """A desk or table of its own geometry: a top on two panel legs (three solids, one mesh)."""
        y0 = corner[1] if south else corner[1] - depth
        items = [
            self._prism(width, depth, 0.03, (0.0, 0.0, 0.72)),
            self._prism(0.03, depth, 0.72, (0.02, 0.0, 0.0)),
            self._prism(0.03, depth, 0.72, (width - 0.05, 0.0, 0.0)),
        ]
        self.element(
            st,
            "IfcFurniture",
            name,
            (corner[0], y0, 0.0),
            items,
            material="Wood",
            predefined_type=ptype,
            space=space,
        )

    def _stair(self, st: _Storey, tag: str, x0: float, space: _Entity) -> None:
        """A dog-leg stair to the next storey: two stepped flights, a landing, two railings."""
        stair = self.element(
            st, "IfcStair", f"{tag} stair", (x0, 0.0, 0.0), predefined_type="HALF_TURN_STAIR"
        )
        risers, tread, riser, width = 10, 0.28, STOREY_H / 20, 1.2
        profile = [(0.0, 0.0)]
        for i in range(risers):
            profile += [(i * tread, (i + 1) * riser), ((i + 1) * tread, (i + 1) * riser)]
        profile += [(risers * tread, (risers - 1) * riser), (tread, 0.0)]
        run = risers * tread
        parts = []
        # Flight 1 climbs +x at y 1.0..2.2; its profile is in the xz plane, extruded towards -y.
        up = self._axis((0.0, 0.0, 0.0), x=(1.0, 0.0, 0.0), z=(0.0, -1.0, 0.0))
        parts.append(
            self.element(
                st,
                "IfcStairFlight",
                f"{tag} flight 1",
                (x0 + 1.0, 2.2, 0.0),
                [self._polygon_prism(profile, width, up)],
                material="Concrete",
                predefined_type="STRAIGHT",
                contained=False,
            )
        )
        # Flight 2 climbs -x at y 2.2..3.4 from the landing; extruded towards +y.
        back = self._axis((0.0, 0.0, 0.0), x=(-1.0, 0.0, 0.0), z=(0.0, 1.0, 0.0))
        parts.append(
            self.element(
                st,
                "IfcStairFlight",
                f"{tag} flight 2",
                (x0 + 1.0 + run, 2.2, STOREY_H / 2),
                [self._polygon_prism(profile, width, back)],
                material="Concrete",
                predefined_type="STRAIGHT",
                contained=False,
            )
        )
        landing_lo = (x0 + 1.0 + run, 1.0, STOREY_H / 2 - 0.2)
        parts.append(
            self.element(
                st,
                "IfcSlab",
                f"{tag} landing",
                landing_lo,
                [self._prism(1.5, 2.4, 0.2)],
                material="Concrete",
                predefined_type="LANDING",
                contained=False,
            )
        )
        parts.append(
            self.element(
                st,
                "IfcRailing",
                f"{tag} railing 1",
                (x0 + 1.0, 2.18, 0.0),
                [self._prism(run, 0.04, 1.0 + STOREY_H / 2)],
                material="Steel",
                predefined_type="BALUSTRADE",
                contained=False,
            )
        )
        parts.append(
            self.element(
                st,
                "IfcRailing",
                f"{tag} railing 2",
                (x0 + 0.8, 3.45, 0.0),
                [self._prism(run + 0.2, 0.04, 1.0)],
                material="Steel",
                predefined_type="HANDRAIL",
                contained=False,
            )
        )
        ifcopenshell.api.aggregate.assign_object(self.f, products=parts, relating_object=stair)
        self.bounds(space, [stair])

    def _curtain_wall(
        self, st: _Storey, tag: str, span: tuple[float, float], *, y: float, south: bool
    ) -> _Entity:
        """A curtain wall on the façade line ``y``, outside the room: two glass plates between
        aluminium mullions, a transom at the bottom and the top (its body is its parts')."""
        x0, x1 = span
        cw = self.element(st, "IfcCurtainWall", f"{tag} curtain wall", (x0, y, 0.0))
        w = x1 - x0
        ya, yb = (y - 0.15, y) if south else (y, y + 0.15)
        parts = []
        for k in range(2):
            u = x0 + k * w / 2
            parts.append(
                self.box(
                    st,
                    "IfcMember",
                    f"{tag} mullion {k}",
                    (u, ya, 0.1),
                    (u + 0.05, yb, WALL_H - 0.1),
                    material="Aluminium",
                    predefined_type="MULLION",
                    contained=False,
                )
            )
            parts.append(
                self.box(
                    st,
                    "IfcPlate",
                    f"{tag} pane {k}",
                    (u + 0.05, (ya + yb) / 2 - 0.01, 0.1),
                    (u + w / 2, (ya + yb) / 2 + 0.01, WALL_H - 0.1),
                    material="Glass",
                    predefined_type="CURTAIN_PANEL",
                    contained=False,
                )
            )
        for k, z in enumerate((0.0, WALL_H - 0.1)):
            parts.append(
                self.box(
                    st,
                    "IfcMember",
                    f"{tag} transom {k}",
                    (x0, ya, z),
                    (x1, yb, z + 0.1),
                    material="Aluminium",
                    predefined_type="MULLION",
                    contained=False,
                )
            )
        ifcopenshell.api.aggregate.assign_object(self.f, products=parts, relating_object=cw)
        return cw


def _chair(b: _Builder) -> list[_Entity]:
    return [
        b._prism(0.1, 0.1, 0.42, (-0.05, -0.05, 0.0)),
        b._prism(0.5, 0.5, 0.05, (-0.25, -0.25, 0.42)),
        b._prism(0.05, 0.5, 0.5, (-0.3, -0.25, 0.47)),
    ]


_TYPES: Final[dict[str, tuple[str, str, str, str, Callable[[_Builder], list[_Entity]]]]] = {
    # name: (type class, occurrence class, predefined type, material, body in the type's frame)
    "Chair": ("IfcFurnitureType", "IfcFurniture", "CHAIR", "Fabric", _chair),
    "Cabinet": (
        "IfcFurnitureType",
        "IfcFurniture",
        "FILECABINET",
        "Steel",
        lambda b: [b._prism(0.8, 0.45, 1.2)],
    ),
    "Light": (
        "IfcLightFixtureType",
        "IfcLightFixture",
        "DIRECTIONSOURCE",
        "Aluminium",
        lambda b: [b._prism(1.2, 0.3, 0.05)],
    ),
    "Radiator": (
        "IfcSpaceHeaterType",
        "IfcSpaceHeater",
        "CONVECTOR",
        "Steel",
        lambda b: [b._prism(1.0, 0.1, 0.6)],
    ),
    "Toilet": (
        "IfcSanitaryTerminalType",
        "IfcSanitaryTerminal",
        "TOILETPAN",
        "Ceramic",
        lambda b: [b._prism(0.4, 0.6, 0.4, (-0.2, -0.3, 0.0))],
    ),
}


def generate(
    path: str | Path, options: Options = Options(), progress: Callable[[str], None] | None = None
) -> Summary:
    """Generate the building and write it to ``path`` (IFC4, STEP); return what it holds.

    Example::

        summary = generate(tmp_path / "n.ifc", Options(storeys=1, scale=0.05))
        summary.count("IfcDoor")
    """
    if options.storeys < 1:
        msg = f"storeys must be at least 1, got {options.storeys}."
        raise ValueError(msg)
    if options.unit not in METRES_PER_UNIT:
        msg = f"unit must be one of {sorted(METRES_PER_UNIT)}, got {options.unit!r}."
        raise ValueError(msg)
    t0 = time.perf_counter()
    say = progress or (lambda _msg: None)
    builder = _Builder(options)
    builder.build(say)
    f = builder.f
    f.header.file_name.time_stamp = TIMESTAMP
    f.header.file_name.name = Path(path).name
    f.write(str(path))
    counts = Counter(e.is_a() for e in f.by_type("IfcElement"))  # type: ignore[no-untyped-call]
    for cls in _COUNTED:
        counts[cls] = len(f.by_type(cls, include_subtypes=False))
    summary = Summary(
        path=Path(path),
        options=options,
        elements=len(f.by_type("IfcElement")),
        spaces=counts["IfcSpace"],
        counts=dict(counts),
        seconds=time.perf_counter() - t0,
    )
    say(f"wrote {path}: {summary.elements:,} elements, {summary.spaces:,} spaces in {summary.seconds:.1f} s")
    return summary


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("out", type=Path, help="the .ifc file to write")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--storeys", type=int, default=6)
    p.add_argument("--unit", choices=sorted(METRES_PER_UNIT), default="m")
    p.add_argument("--scale", type=float, default=1.0, help="rooms per storey side, relative to 42")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    args = p.parse_args(argv)
    options = Options(seed=args.seed, storeys=args.storeys, unit=args.unit, scale=args.scale)
    args.out.parent.mkdir(parents=True, exist_ok=True)

    def say(msg: str) -> None:
        if not args.quiet:
            print(msg, file=sys.stderr, flush=True)

    summary = generate(args.out, options, say)
    top = ", ".join(f"{c} {n:,}" for c, n in sorted(summary.counts.items(), key=lambda kv: -kv[1]))
    say(top)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
