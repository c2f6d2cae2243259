"""The materials of an element, and the ones a sensor faces, as IfcMaterial names.

An element's material is what ``ifcopenshell.util.element.get_material(element, should_skip_usage=True)``
finds: its own material association, else its type's (a layer set usage gives its layer set, a profile
set usage its profile set). :class:`Materials` finds the same for every element of a file from one pass
over its ``IfcRelAssociatesMaterial`` and ``IfcRelDefinesByType`` relations, and names each material
(set) once however many elements share it: about 10x faster than asking ``get_material`` element by
element. Where the file leaves a doubt that one pass cannot settle the same way (an element or type
with two material associations or two types, an association without a material, a relation that
cannot be read), that element is asked with ``get_material``, which also raises what it always raised.

Example::

    materials = Materials(f)
    every, facing = materials.names_of(wall)  # ("Brick", "Fiberglass Batt", "Plaster"), ("Brick", "Plaster")
"""

from __future__ import annotations

from typing import Any, Final

import ifcopenshell
import ifcopenshell.util.element

from adapters.ifc.attributes import Attributes

Names = tuple[str, ...]

_ASK: Final = object()
"""The element's material cannot be settled from the one pass: ask ``get_material``."""


def _decompose(mat: Any) -> tuple[list[Any], list[Any]]:
    """(every IfcMaterial of the material (set) ``mat``, the ones a sensor faces)."""
    if mat.is_a("IfcMaterial"):
        return [mat], [mat]
    if mat.is_a("IfcMaterialLayerSet"):
        layers = [layer.Material for layer in mat.MaterialLayers or ()]
        return layers, [layers[0], layers[-1]] if layers else []
    if mat.is_a("IfcMaterialList"):
        found = list(mat.Materials or ())
    elif mat.is_a("IfcMaterialConstituentSet"):
        found = [c.Material for c in mat.MaterialConstituents or ()]
    elif mat.is_a("IfcMaterialProfileSet"):
        found = [p.Material for p in mat.MaterialProfiles or ()]
    elif hasattr(mat, "Material"):  # a single layer, profile or constituent assigned directly
        found = [mat.Material]
    else:
        found = []
    return found, found


def material_sets(element: Any) -> tuple[list[Any], list[Any]]:
    """(every IfcMaterial of ``element``, the ones a sensor faces), own or inherited from its type."""
    mat = ifcopenshell.util.element.get_material(element, should_skip_usage=True)
    if mat is None:
        return [], []
    return _decompose(mat)


def _names(materials: list[Any]) -> Names:
    names: dict[str, None] = {}
    for m in materials:
        if m is not None and m.Name:
            names[str(m.Name)] = None
    return tuple(names)


def material_names(element: Any) -> Names:
    """IfcMaterial names of ``element`` (own or inherited from its type), in order, without duplicates."""
    return _names(material_sets(element)[0])


def facing_material_names(element: Any) -> Names:
    """The names of the materials a sensor sees on ``element``'s faces.

    A single material; every constituent of a constituent set and every member of a material list (a
    window of glass and frame shows both); only the first and the last layer of a layer set (its two
    faces: the insulation inside a wall is not seen); every profile of a profile set.
    """
    return _names(material_sets(element)[1])


class Materials:
    """The material names of the elements of one file, found in one pass over its relations."""

    def __init__(self, f: Any, attributes: Attributes | None = None) -> None:
        self._attributes = attributes or Attributes()
        self._associated: dict[int, list[Any]] = {}  # object id -> RelatingMaterial of each association
        self._typed_by: dict[int, list[Any]] = {}  # object id -> RelatingType of each type relation
        self._sets: dict[int, tuple[list[Any], list[Any]]] = {}  # material (set) id -> its materials
        self._named: dict[int, tuple[Names, Names]] = {}  # material (set) id -> their names
        self._is_type: dict[str, bool] = {}
        self._usage: dict[str, str | None] = {}
        try:
            self._index(f)
        except Exception:  # a relation that cannot be read: every element is asked with get_material
            self._associated, self._typed_by, self._whole_file = {}, {}, False
        else:
            self._whole_file = True

    def _index(self, f: Any) -> None:
        get = self._attributes.get
        for kind, into, target in (
            ("IfcRelAssociatesMaterial", self._associated, "RelatingMaterial"),
            ("IfcRelDefinesByType", self._typed_by, "RelatingType"),
        ):
            for rel in f.by_type(kind):
                value = get(rel, target)
                for obj in get(rel, "RelatedObjects") or ():
                    into.setdefault(obj.id(), []).append(value)

    def _material(self, element: Any) -> Any:
        """What ``get_material(element, should_skip_usage=True)`` returns, or :data:`_ASK`."""
        try:
            return self._settled(element)
        except Exception:  # get_material meets it too, and raises it
            return _ASK

    def _settled(self, element: Any) -> Any:
        own = self._associated.get(element.id(), ())
        if len(own) > 1:
            return _ASK
        if own:
            return self._skip_usage(own[0])
        types = self._typed_by.get(element.id(), ())
        if not types:
            return None
        if len(types) > 1 or type(types[0]) is not ifcopenshell.entity_instance or not self._a_type(types[0]):
            return _ASK
        inherited = self._associated.get(types[0].id(), ())
        if len(inherited) > 1:
            return _ASK
        return self._skip_usage(inherited[0]) if inherited else None

    def _a_type(self, entity: Any) -> bool:
        name = entity.is_a()
        known = self._is_type.get(name)
        if known is None:
            known = self._is_type[name] = bool(entity.is_a("IfcTypeObject"))
        return known

    def _skip_usage(self, mat: Any) -> Any:
        """The set a usage is of (``ForLayerSet``, ``ForProfileSet``), else ``mat``; :data:`_ASK`
        when it is no entity."""
        if type(mat) is not ifcopenshell.entity_instance:
            return _ASK
        name = mat.is_a()
        if name not in self._usage:
            usage = None
            if mat.is_a("IfcMaterialLayerSetUsage"):
                usage = "ForLayerSet"
            elif mat.is_a("IfcMaterialProfileSetUsage"):
                usage = "ForProfileSet"
            self._usage[name] = usage
        attribute = self._usage[name]
        return mat if attribute is None else self._attributes.get(mat, attribute)

    def sets(self, element: Any) -> tuple[int | None, list[Any], list[Any]]:
        """(a key for :meth:`names`, then what :func:`material_sets` gives for ``element``); raises what
        it raises. The key is the id of the material (set) when the one pass found it, else None."""
        mat = self._material(element) if self._whole_file else _ASK
        if mat is None:
            return None, [], []
        if mat is not _ASK and type(mat) is ifcopenshell.entity_instance:
            key = mat.id()
            found = self._sets.get(key)
            if found is None:
                try:
                    found = _decompose(mat)
                except Exception:  # asked again below, which raises it where it always did
                    found = None
                else:
                    self._sets[key] = found
            if found is not None:
                return key, found[0], found[1]
        every, facing = material_sets(element)
        return None, every, facing

    def names(self, key: int | None, every: list[Any], facing: list[Any]) -> tuple[Names, Names]:
        """The names of :meth:`sets`' materials, kept per material (set); raises what naming raises."""
        named = self._named.get(key) if key is not None else None
        if named is None:
            named = (_names(every), _names(facing))
            if key is not None:
                self._named[key] = named
        return named

    def names_of(self, element: Any) -> tuple[Names, Names]:
        """(:func:`material_names`, :func:`facing_material_names`) of ``element``."""
        return self.names(*self.sets(element))
