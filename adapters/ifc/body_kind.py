"""Is a product's body a solid or a surface? Decided from the representation, not from its mesh.

A kernel's mesh of a solid is not always watertight (OpenCASCADE triangulates a B-rep face by face
and leaves T-junctions; faceted B-reps exported with split edges do the same), so the mesh alone
cannot say whether an element has an inside. The IFC file can: a body is solid when every item of
its ``Body`` representation (looking through mapped items) is a solid model — an extrusion or other
swept solid (``SweptSolid``, ``AdvancedSweptSolid``), a B-rep (``Brep``, ``AdvancedBrep``), a CSG
primitive or boolean result (``CSG``, ``Clipping``) — or a tessellation the file declares closed.
Surface models, open shells, curves and anything unknown are not: they keep their outline in the maps.

Item classes are trusted over ``IfcShapeRepresentation.RepresentationType``, which exporters often
leave out or get wrong.

Example::

    kind = BodyKind()
    solid = kind.is_solid(wall)              # True for an extruded wall, False for a SurfaceModel
"""

from __future__ import annotations

from typing import Any

_SOLID_ITEMS = (
    "IfcSolidModel",  # swept area / disk solids, B-reps (faceted, advanced), CSG solids
    "IfcBooleanResult",  # and IfcBooleanClippingResult
    "IfcCsgPrimitive3D",
    "IfcHalfSpaceSolid",
)
_MAX_DEPTH = 8


class BodyKind:
    """Decides solid or surface per product, remembering the answer per shared (mapped) representation."""

    def __init__(self) -> None:
        self._mapped: dict[int, bool] = {}

    def _item_is_solid(self, item: Any, depth: int) -> bool:
        if item.is_a("IfcMappedItem"):
            if depth >= _MAX_DEPTH:
                return False
            source = item.MappingSource.MappedRepresentation
            known = self._mapped.get(source.id())
            if known is None:
                known = self._mapped[source.id()] = self._items_are_solid(source.Items, depth + 1)
            return known
        if item.is_a("IfcTessellatedFaceSet"):
            return bool(getattr(item, "Closed", False))
        return any(item.is_a(c) for c in _SOLID_ITEMS)

    def _items_are_solid(self, items: Any, depth: int) -> bool:
        items = tuple(items or ())
        return bool(items) and all(self._item_is_solid(i, depth) for i in items)

    def is_solid(self, product: Any) -> bool:
        """True when ``product``'s body (its ``Body`` representations, or all of them when none is
        named so) is made of solids only."""
        shape = getattr(product, "Representation", None)
        if shape is None:
            return False
        representations = [r for r in shape.Representations or () if r.is_a("IfcShapeRepresentation")]
        body = [r for r in representations if r.RepresentationIdentifier == "Body"] or representations
        return bool(body) and all(self._items_are_solid(r.Items, 0) for r in body)
