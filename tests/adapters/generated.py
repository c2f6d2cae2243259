"""Small IFC models generated with ifcopenshell.api for tests: boxes with materials, in metres.

Example::

    g = Generated("IFC4")
    storey = g.storey("Ground", 0.0)
    wall = g.box("IfcWall", "W1", (0, 0, 0), (4, 0.3, 3), container=storey)
    g.layers(wall, ["Brick", "Fiberglass Batt", "Plaster"])
    g.write(tmp_path / "m.ifc")
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import pairwise
from pathlib import Path
from typing import Any

import ifcopenshell
import ifcopenshell.api.aggregate
import ifcopenshell.api.context
import ifcopenshell.api.geometry
import ifcopenshell.api.material
import ifcopenshell.api.owner
import ifcopenshell.api.owner.settings
import ifcopenshell.api.project
import ifcopenshell.api.root
import ifcopenshell.api.spatial
import ifcopenshell.api.type
import ifcopenshell.api.unit
import numpy as np
from ifcopenshell.util.shape_builder import ShapeBuilder

XYZ = tuple[float, float, float]


def _first(kind: str) -> Callable[[ifcopenshell.file], Any]:
    return lambda ifc: next(iter(ifc.by_type(kind)), None)


def _add_owner(f: ifcopenshell.file) -> None:
    person = ifcopenshell.api.owner.add_person(f)
    organisation = ifcopenshell.api.owner.add_organisation(f)
    ifcopenshell.api.owner.add_person_and_organisation(f, person=person, organisation=organisation)
    ifcopenshell.api.owner.add_application(f)
    # the API asks these hooks for the owner of new entities; look them up in the file being written
    ifcopenshell.api.owner.settings.get_user = _first("IfcPersonAndOrganization")
    ifcopenshell.api.owner.settings.get_application = _first("IfcApplication")


class Generated:
    """A project with one site and one building (``self.building``), lengths in metres."""

    def __init__(self, schema: str = "IFC4") -> None:
        self.file = ifcopenshell.api.project.create_file(version=schema)
        f = self.file
        if schema == "IFC2X3":  # IFC2X3 requires owner histories: a user and an application first
            _add_owner(f)
        project = ifcopenshell.api.root.create_entity(f, ifc_class="IfcProject", name="Generated")
        units = [
            ifcopenshell.api.unit.add_si_unit(f, unit_type=t)
            for t in ("LENGTHUNIT", "AREAUNIT", "VOLUMEUNIT")
        ]
        ifcopenshell.api.unit.assign_unit(f, units=units)
        model = ifcopenshell.api.context.add_context(f, context_type="Model")
        self.body = ifcopenshell.api.context.add_context(
            f, context_type="Model", context_identifier="Body", target_view="MODEL_VIEW", parent=model
        )
        site = ifcopenshell.api.root.create_entity(f, ifc_class="IfcSite", name="Site")
        ifcopenshell.api.aggregate.assign_object(f, products=[site], relating_object=project)
        self.building = ifcopenshell.api.root.create_entity(f, ifc_class="IfcBuilding", name="Hall")
        ifcopenshell.api.aggregate.assign_object(f, products=[self.building], relating_object=site)
        self.shapes = ShapeBuilder(f)
        self._materials: dict[str, Any] = {}

    def storey(self, name: str, elevation_m: float) -> Any:
        storey = ifcopenshell.api.root.create_entity(self.file, ifc_class="IfcBuildingStorey", name=name)
        ifcopenshell.api.aggregate.assign_object(self.file, products=[storey], relating_object=self.building)
        self._place(storey, (0.0, 0.0, elevation_m))
        storey.Elevation = elevation_m
        return storey

    def box(self, ifc_class: str, name: str, origin: XYZ, size: XYZ, *, container: Any) -> Any:
        """An element whose body is an extruded rectangle from ``origin`` (world, m) of ``size`` (m)."""
        element = ifcopenshell.api.root.create_entity(self.file, ifc_class=ifc_class, name=name)
        ifcopenshell.api.spatial.assign_container(self.file, products=[element], relating_structure=container)
        self._place(element, origin)
        curve = self.shapes.rectangle(size=(size[0], size[1]))
        solid = self.shapes.extrude(self.shapes.profile(curve), magnitude=size[2])
        representation = self.shapes.get_representation(self.body, [solid])
        ifcopenshell.api.geometry.assign_representation(
            self.file, product=element, representation=representation
        )
        return element

    def faceted_brep(self, faces: list[list[XYZ]]) -> Any:
        """An ``IfcFacetedBrep`` of polygonal ``faces`` (each a loop of local points, m, counter-clockwise
        seen from outside); equal points are one ``IfcCartesianPoint``."""
        return self.file.createIfcFacetedBrep(self.file.createIfcClosedShell(self._faces(faces)))

    def surface_model(self, faces: list[list[XYZ]]) -> Any:
        """An ``IfcFaceBasedSurfaceModel`` of polygonal ``faces`` (as in :meth:`faceted_brep`) in one
        ``IfcConnectedFaceSet``: a surface, whether or not its faces close around a volume."""
        f = self.file
        return f.createIfcFaceBasedSurfaceModel([f.createIfcConnectedFaceSet(self._faces(faces))])

    def _faces(self, faces: list[list[XYZ]]) -> list[Any]:
        f, points = self.file, {}
        for face in faces:
            for p in face:
                if p not in points:
                    points[p] = f.createIfcCartesianPoint([float(c) for c in p])
        return [
            f.createIfcFace([f.createIfcFaceOuterBound(f.createIfcPolyLoop([points[p] for p in face]), True)])
            for face in faces
        ]

    def brep_element(
        self,
        ifc_class: str,
        name: str,
        origin: XYZ,
        items: list[Any],
        *,
        container: Any,
        mapped: bool = False,
        representation_type: str = "Brep",
    ) -> Any:
        """An element whose body is the B-rep ``items`` (``Brep``, or ``representation_type``: e.g.
        ``SurfaceModel`` for :meth:`surface_model` items), or with ``mapped`` an ``IfcMappedItem`` of a
        representation map holding them (``MappedRepresentation``), placed at ``origin``."""
        f = self.file
        element = ifcopenshell.api.root.create_entity(f, ifc_class=ifc_class, name=name)
        ifcopenshell.api.spatial.assign_container(f, products=[element], relating_structure=container)
        self._place(element, origin)
        body = f.createIfcShapeRepresentation(self.body, "Body", representation_type, items)
        if mapped:
            zero = f.createIfcCartesianPoint([0.0, 0.0, 0.0])
            source = f.createIfcRepresentationMap(f.createIfcAxis2Placement3D(zero), body)
            operator = f.createIfcCartesianTransformationOperator3D(None, None, zero, None, None)
            body = f.createIfcShapeRepresentation(
                self.body, "Body", "MappedRepresentation", [f.createIfcMappedItem(source, operator)]
            )
        ifcopenshell.api.geometry.assign_representation(f, product=element, representation=body)
        return element

    def mapped_copy(self, element: Any, name: str, origin: XYZ, *, container: Any) -> Any:
        """Another product of ``element``'s class, placed at ``origin``, whose body maps the same
        representation map as ``element``'s (made with ``mapped=True``)."""
        f = self.file
        (item,) = element.Representation.Representations[0].Items
        copy = ifcopenshell.api.root.create_entity(f, ifc_class=element.is_a(), name=name)
        ifcopenshell.api.spatial.assign_container(f, products=[copy], relating_structure=container)
        self._place(copy, origin)
        mapped = f.createIfcMappedItem(item.MappingSource, item.MappingTarget)
        body = f.createIfcShapeRepresentation(self.body, "Body", "MappedRepresentation", [mapped])
        ifcopenshell.api.geometry.assign_representation(f, product=copy, representation=body)
        return copy

    def material(self, name: str) -> Any:
        if name not in self._materials:
            self._materials[name] = ifcopenshell.api.material.add_material(self.file, name=name)
        return self._materials[name]

    def single(self, element: Any, name: str) -> None:
        ifcopenshell.api.material.assign_material(
            self.file, products=[element], type="IfcMaterial", material=self.material(name)
        )

    def layer_set(self, names: list[str]) -> Any:
        layer_set = ifcopenshell.api.material.add_material_set(
            self.file, name="Layers", set_type="IfcMaterialLayerSet"
        )
        for n in names:
            layer = ifcopenshell.api.material.add_layer(
                self.file, layer_set=layer_set, material=self.material(n)
            )
            layer.LayerThickness = 0.1
        return layer_set

    def layers(self, element: Any, names: list[str]) -> None:
        """A layer set usage (outer layer first) on ``element``."""
        ifcopenshell.api.material.assign_material(
            self.file, products=[element], type="IfcMaterialLayerSetUsage", material=self.layer_set(names)
        )

    def constituents(self, element: Any, names: list[str]) -> None:
        cset = ifcopenshell.api.material.add_material_set(
            self.file, name="Parts", set_type="IfcMaterialConstituentSet"
        )
        for n in names:
            ifcopenshell.api.material.add_constituent(
                self.file, constituent_set=cset, material=self.material(n)
            )
        ifcopenshell.api.material.assign_material(
            self.file, products=[element], type="IfcMaterialConstituentSet", material=cset
        )

    def material_list(self, element: Any, names: list[str]) -> None:
        mlist = ifcopenshell.api.material.add_material_set(self.file, name="List", set_type="IfcMaterialList")
        for n in names:
            ifcopenshell.api.material.add_list_item(self.file, material_list=mlist, material=self.material(n))
        ifcopenshell.api.material.assign_material(
            self.file, products=[element], type="IfcMaterialList", material=mlist
        )

    def typed_layers(self, element: Any, type_class: str, names: list[str]) -> None:
        """``names`` as a layer set on a type object that ``element`` is typed by (nothing on the element)."""
        element_type = ifcopenshell.api.root.create_entity(
            self.file, ifc_class=type_class, name=f"{type_class} type"
        )
        ifcopenshell.api.material.assign_material(
            self.file, products=[element_type], type="IfcMaterialLayerSet", material=self.layer_set(names)
        )
        ifcopenshell.api.type.assign_type(self.file, related_objects=[element], relating_type=element_type)

    def write(self, path: Path) -> Path:
        self.file.write(str(path))
        return path

    def _place(self, product: Any, origin: XYZ) -> None:
        matrix = np.eye(4)
        matrix[:3, 3] = origin
        ifcopenshell.api.geometry.edit_object_placement(self.file, product=product, matrix=matrix, is_si=True)


def box_faces(lo: XYZ, hi: XYZ, *, split: dict[str, tuple[float, ...]] | None = None) -> list[list[XYZ]]:
    """The six faces of the box ``lo``-``hi`` for :meth:`Generated.faceted_brep`, outward loops.

    ``split`` cuts named faces (``"-x"``, ``"+x"``, ``"-y"``, ``"+y"``, ``"-z"``, ``"+z"``) into strips
    at the given coordinates: the x and z faces at values of y, the y faces at values of z. The
    neighbours are not split, so every cut leaves T-junctions: the mesh of the B-rep is open though
    the solid is closed, as a kernel that triangulates face by face delivers it.
    """
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    cuts = split or {}

    def strips(name: str, a0: float, a1: float) -> list[tuple[float, float]]:
        at = [a0, *sorted(c for c in cuts.get(name, ()) if a0 < c < a1), a1]
        return list(pairwise(at))

    faces: list[list[XYZ]] = []
    for a, b in strips("-z", y0, y1):
        faces.append([(x0, a, z0), (x0, b, z0), (x1, b, z0), (x1, a, z0)])
    for a, b in strips("+z", y0, y1):
        faces.append([(x0, a, z1), (x1, a, z1), (x1, b, z1), (x0, b, z1)])
    for a, b in strips("-x", y0, y1):
        faces.append([(x0, a, z0), (x0, a, z1), (x0, b, z1), (x0, b, z0)])
    for a, b in strips("+x", y0, y1):
        faces.append([(x1, a, z0), (x1, b, z0), (x1, b, z1), (x1, a, z1)])
    for a, b in strips("-y", z0, z1):
        faces.append([(x0, y0, a), (x1, y0, a), (x1, y0, b), (x0, y0, b)])
    for a, b in strips("+y", z0, z1):
        faces.append([(x0, y1, a), (x0, y1, b), (x1, y1, b), (x1, y1, a)])
    return faces
