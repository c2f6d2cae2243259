"""Is a product's body a solid or a surface? Decided from the representation, not from its mesh.

A kernel's mesh of a solid is not always watertight (OpenCASCADE triangulates a B-rep face by face
and leaves T-junctions; faceted B-reps exported with split edges do the same), so the mesh alone
cannot say whether an element has an inside. The IFC file can: a body is solid when every item of
its ``Body`` representation (looking through mapped items) is a solid model — an extrusion or other
swept solid (``SweptSolid``, ``AdvancedSweptSolid``), a B-rep (``Brep``, ``AdvancedBrep``), a CSG
primitive or boolean result (``CSG``, ``Clipping``) — or a tessellation the file declares closed.
Surface models, open shells, curves and anything unknown are not solids; their meshes keep their
outline in the maps unless the mesh itself closes around a volume (a surface model whose faces
enclose a lift's car: :func:`adapters.ifc.kernel_child.make_mesh`), which is then filled like a solid.

Item classes are trusted over ``IfcShapeRepresentation.RepresentationType``, which exporters often
leave out or get wrong.

Example::

    kind = BodyKind()
    solid = kind.is_solid(wall)              # True for an extruded wall, False for a SurfaceModel
"""

from __future__ import annotations

from typing import Any

from adapters.ifc.attributes import Attributes, Representations

_SOLID_ITEMS = (
    "IfcSolidModel",  # swept area / disk solids, B-reps (faceted, advanced), CSG solids
    "IfcBooleanResult",  # and IfcBooleanClippingResult
    "IfcCsgPrimitive3D",
    "IfcHalfSpaceSolid",
)
_MAX_DEPTH = 8


class BodyKind:
    """Decides solid or surface per product, remembering the answer per shared (mapped) representation."""

    def __init__(
        self, representations: Representations | None = None, attributes: Attributes | None = None
    ) -> None:
        self._mapped: dict[int, bool] = {}
        self._kinds: dict[str, str] = {}  # item class -> "mapped", "tessellated", "solid" or ""
        self._shape: dict[str, bool] = {}  # representation class -> is an IfcShapeRepresentation
        self._attributes = attributes or Attributes()
        self._representations = representations or Representations(self._attributes)

    def _kind(self, item: Any) -> str:
        name = item.is_a()
        kind = self._kinds.get(name)
        if kind is None:
            if item.is_a("IfcMappedItem"):
                kind = "mapped"
            elif item.is_a("IfcTessellatedFaceSet"):
                kind = "tessellated"
            else:
                kind = "solid" if any(item.is_a(c) for c in _SOLID_ITEMS) else ""
            self._kinds[name] = kind
        return kind

    def _item_is_solid(self, item: Any, depth: int) -> bool:
        kind = self._kind(item)
        if kind == "mapped":
            if depth >= _MAX_DEPTH:
                return False
            get = self._attributes.get
            source = get(get(item, "MappingSource"), "MappedRepresentation")
            known = self._mapped.get(source.id())
            if known is None:
                known = self._mapped[source.id()] = self._items_are_solid(
                    self._representations.items(source), depth + 1
                )
            return known
        if kind == "tessellated":
            return bool(self._attributes.get_or_none(item, "Closed") or False)
        return kind == "solid"

    def _items_are_solid(self, items: Any, depth: int) -> bool:
        items = tuple(items or ())
        return bool(items) and all(self._item_is_solid(i, depth) for i in items)

    def is_solid(self, product: Any) -> bool:
        """True when ``product``'s body (its ``Body`` representations, or all of them when none is
        named so) is made of solids only."""
        get = self._attributes.get
        every = self._representations.of(product)
        if every is None:
            return False
        representations = [r for r in every if self._is_shape(r)]
        body = [r for r in representations if get(r, "RepresentationIdentifier") == "Body"] or representations
        return bool(body) and all(self._items_are_solid(self._representations.items(r), 0) for r in body)

    def _is_shape(self, representation: Any) -> bool:
        name = representation.is_a()
        known = self._shape.get(name)
        if known is None:
            known = self._shape[name] = bool(representation.is_a("IfcShapeRepresentation"))
        return known
