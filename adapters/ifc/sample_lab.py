"""The bundled sample building written as IFC4 with ``ifcopenshell.api``: the lab of de Vos et al.

The lab's plan and world layout are plain data in the core (``twin.samples.lab_plan``,
``twin.samples.lab_layout``:
the rooms, the corridor and its arch, the glass wall, the table, Door A in its opening, a floor slab
under each storey); this module writes them as an IFC4 file so the demo and the tests need no
downloaded model, with the openings, fillings, space boundaries, materials and units real models have.
Walls are written with ``add_wall_representation`` along their longer side, everything else as an
extruded prism (a slab's outline when it has one); the door's opening voids its wall
(``IfcRelVoidsElement``) and the door fills it (``IfcRelFillsElement``), so the geometry kernel cuts
the wall; the table is contained in Room A, everything else (but the opening) in its storey.

Every GlobalId is the layout's (derived from a fixed name), relationships' too (from what they
relate), so two generations, and the metre and foot variants, carry the same ids. The foot variant
writes every length divided by 0.3048: its geometry in metres is the same as the metre variant's.
(Meshed, so is every element's, but for the cut wall under IfcOpenShell's manifold kernel: it
enlarges an opening by 10 times its precision in project units before subtracting it, so that wall
differs by under a millimetre between the two variants; the opencascade kernel cuts exactly.)

Example::

    from adapters.ifc.sample_lab import write_lab

    layout = write_lab("lab.ifc", length_unit="foot", storeys=2)
    layout.arch.box.zmin          # 0.3 (metres, world frame, whatever the file's unit)
    layout.space("Corridor").bounded_by
"""

from __future__ import annotations

import logging
import time
from collections import defaultdict
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
import ifcopenshell.api.unit
import numpy as np
from ifcopenshell.util.shape_builder import ShapeBuilder

from twin.samples.lab_layout import LabLayout, entity_global_id, ifc_global_id, lab_layout, storey_plans
from twin.samples.lab_plan import ARCH, BUILDING, BUILDING_OFFSET, PROJECT, SITE, XY, Box, StoreyPlan

log = logging.getLogger(__name__)

LengthUnit = Literal["metre", "foot"]
FOOT_M: Final = 0.3048

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
    plans = storey_plans(storeys)
    started = time.perf_counter()
    builder = _LabBuilder(length_unit)
    builder.build(plans)
    log.debug("Generated the sample lab in %.1f ms.", (time.perf_counter() - started) * 1e3)
    return builder.file, lab_layout(storeys=storeys)


def write_plans(path: str | Path, plans: tuple[StoreyPlan, ...]) -> None:
    """Write storey plans other than the lab's (the same builder: walls, slabs, furniture, spaces) to
    ``path`` as IFC4 in metres, e.g. a benchmark's building of many rooms.

    Example::

        from twin.samples.lab_plan import StoreyPlan

        write_plans("cells.ifc", (StoreyPlan("Ground floor", 0.0, elements, ()),))
    """
    builder = _LabBuilder("metre")
    builder.build(plans)
    builder.file.write(str(path))
    log.info("Wrote %d storey plan(s) to %s.", len(plans), path)


# --- generation -----------------------------------------------------------------------------------


class _LabBuilder:
    """One generation: holds the file being built and the project's length scale."""

    def __init__(self, length_unit: LengthUnit) -> None:
        self.length_unit: LengthUnit = length_unit
        self.file = ifcopenshell.api.project.create_file(version="IFC4")
        self.scale = FOOT_M if length_unit == "foot" else 1.0  # metres per project length unit
        self.shapes = ShapeBuilder(self.file)
        self.materials: dict[str, ifcopenshell.entity_instance] = {}
        self.by_material: dict[str, list[ifcopenshell.entity_instance]] = defaultdict(list)
        self.project = self._root("IfcProject", PROJECT)
        self._assign_units()
        model = ifcopenshell.api.context.add_context(self.file, context_type="Model")
        self.body = ifcopenshell.api.context.add_context(
            self.file, context_type="Model", context_identifier="Body", target_view="MODEL_VIEW", parent=model
        )

    def build(self, plans: tuple[StoreyPlan, ...]) -> None:
        """Write the storeys of ``plans`` (the entities of ``twin.samples.lab_layout.lab_layout``)."""
        site = self._root("IfcSite", SITE)
        ifcopenshell.api.aggregate.assign_object(self.file, products=[site], relating_object=self.project)
        self._place(site, (0.0, 0.0, 0.0))
        building = self._root("IfcBuilding", BUILDING)
        ifcopenshell.api.aggregate.assign_object(self.file, products=[building], relating_object=site)
        self._place(building, BUILDING_OFFSET)

        for plan in plans:
            storey = self._root("IfcBuildingStorey", plan.name)
            storey.Elevation = plan.elevation / self.scale
            ifcopenshell.api.aggregate.assign_object(self.file, products=[storey], relating_object=building)
            self._place(storey, (BUILDING_OFFSET[0], BUILDING_OFFSET[1], BUILDING_OFFSET[2] + plan.elevation))
            self._add_storey_contents(plan, storey)

        for name, products in self.by_material.items():
            ifcopenshell.api.material.assign_material(
                self.file, products=products, type="IfcMaterial", material=self.materials[name]
            )
        _stabilise_relationship_ids(self.file)

    def _add_storey_contents(self, plan: StoreyPlan, storey: ifcopenshell.entity_instance) -> None:
        dx, dy, dz = BUILDING_OFFSET[0], BUILDING_OFFSET[1], BUILDING_OFFSET[2] + plan.elevation
        spaces: dict[str, ifcopenshell.entity_instance] = {}
        for sp in plan.spaces:
            space = self._root("IfcSpace", sp.name, predefined_type="INTERNAL")
            ifcopenshell.api.aggregate.assign_object(self.file, products=[space], relating_object=storey)
            self._place(space, (sp.box.xmin + dx, sp.box.ymin + dy, sp.box.zmin + dz))
            self._assign_prism_body(space, sp.box)
            spaces[sp.name] = space

        products: dict[str, ifcopenshell.entity_instance] = {}
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

    def _root(
        self, ifc_class: str, name: str, predefined_type: str | None = None
    ) -> ifcopenshell.entity_instance:
        entity = ifcopenshell.api.root.create_entity(
            self.file, ifc_class=ifc_class, name=name, predefined_type=predefined_type
        )
        entity.GlobalId = entity_global_id(ifc_class, name)
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
        self, product: ifcopenshell.entity_instance, box: Box, outline: tuple[XY, ...] = ()
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
        rel.GlobalId = ifc_global_id(key)
