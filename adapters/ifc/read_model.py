"""Read an IFC file into a :class:`twin.records.BuildingModel`: structure, elements, relations, meshes.

Lengths come out in metres whatever the file's unit: the geometry iterator converts meshes and
placements, and storey elevations are scaled by the file's length unit.

Example::

    model = read_model(Path("lab.ifc"), static_types=("IfcWall", "IfcSlab"))
"""

from __future__ import annotations

import logging
import math
import uuid
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from types import TracebackType
from typing import Any, Self

import ifcopenshell
import ifcopenshell.guid
import ifcopenshell.util.element
import ifcopenshell.util.placement
import ifcopenshell.util.unit

from adapters.ifc.attributes import Attributes
from adapters.ifc.errors import ENTITY_ERRORS, IfcFileError
from adapters.ifc.geometry import DEFAULT_KERNELS, Progress, start_meshing
from adapters.ifc.materials import Materials, Names
from adapters.ifc.open_file import check_cycles, open_ifc_checked
from twin.gc_pause import paused_gc
from twin.records import Building, BuildingModel, Element, Geometry, Relation, Site, Space, Storey

log = logging.getLogger(__name__)

BUILDING_WIDE_STOREY = "Whole building"
"""Name of the storey made for a building that has none (its key is ``whole-building``)."""


def _each(rels: Iterable[Any], many: str, one: str, attributes: Attributes) -> Iterator[tuple[Any, Any]]:
    """``(rel.<one>, x)`` for every ``x`` in ``rel.<many>`` of every relation; ``<one>`` is read once a
    relation, after ``<many>`` and only when that holds something."""
    get = attributes.get
    for rel in rels:
        related = get(rel, many) or ()
        if related:
            relating = get(rel, one)
            for x in related:
                yield relating, x


def _hierarchy(f: Any, attributes: Attributes) -> dict[int, Any]:
    """Map entity id -> the entity it belongs to: spatial container, aggregate, host, or opening filled."""
    get = attributes.get
    up: dict[int, Any] = {}
    for kind, many, one in (
        ("IfcRelContainedInSpatialStructure", "RelatedElements", "RelatingStructure"),
        ("IfcRelAggregates", "RelatedObjects", "RelatingObject"),
        ("IfcRelNests", "RelatedObjects", "RelatingObject"),
    ):
        for parent, e in _each(f.by_type(kind), many, one, attributes):
            up.setdefault(e.id(), parent)
    for rel in f.by_type("IfcRelVoidsElement"):
        opening = get(rel, "RelatedOpeningElement")
        if opening is not None:  # None: a reference the parser could not resolve
            up.setdefault(opening.id(), get(rel, "RelatingBuildingElement"))
    for rel in f.by_type("IfcRelFillsElement"):
        filling = get(rel, "RelatedBuildingElement")
        if filling is not None:
            up.setdefault(filling.id(), get(rel, "RelatingOpeningElement"))
    return up


def _ancestor(entity: Any, up: dict[int, Any], kind: str) -> Any | None:
    """The nearest ancestor (through :func:`_hierarchy`) that is an ``kind``, or None."""
    seen: set[int] = set()
    node = up.get(entity.id())
    while node is not None and node.id() not in seen:
        if node.is_a(kind):
            return node
        seen.add(node.id())
        node = up.get(node.id())
    return None


def _building_wide_storeys(path: Path, buildings: Sequence[Any], scale: float) -> tuple[Storey, ...]:
    """One storey per building for a model without IfcBuildingStorey, at the building's elevation.

    Its GlobalId is derived from the building's, so re-imports give the same IRI. Elements contained
    in the building stay ``bot:containsElement`` of the building; the storey's map extent is then the
    whole model's.
    """
    made = []
    for b in buildings:
        guid = ifcopenshell.guid.compress(uuid.uuid5(uuid.NAMESPACE_URL, f"storey-of:{b.GlobalId}").hex)
        made.append(Storey(guid, BUILDING_WIDE_STOREY, _elevation_m(b, scale), str(b.GlobalId)))
    if made:
        log.warning(
            "%s has no IfcBuildingStorey: one building-wide storey %r per building holds its elements",
            path,
            BUILDING_WIDE_STOREY,
        )
    return tuple(made)


def _elevation_m(storey: Any, scale: float) -> float:
    """The storey's elevation from its placement (or its Elevation attribute), in metres; 0 with a
    warning naming the storey when neither can be read (a placement of the wrong type, a text)."""
    try:
        if storey.ObjectPlacement is not None:
            matrix = ifcopenshell.util.placement.get_local_placement(storey.ObjectPlacement)
            elevation = float(matrix[2, 3]) * scale
        else:
            elevation = float(getattr(storey, "Elevation", None) or 0.0) * scale
    except (AssertionError, AttributeError, TypeError, ValueError, RuntimeError) as err:
        elevation, why = math.nan, f"{type(err).__name__}: {err}"
    else:
        why = "it is not a finite number"
    if not math.isfinite(elevation):
        log.warning(
            "%s %s %r: its elevation cannot be read (%s); using 0 m",
            storey.is_a(),
            storey.GlobalId,
            storey.Name,
            why,
        )
        return 0.0
    return elevation


def _supertypes(schema: Any, ifc_class: str, cache: dict[str, tuple[str, ...]]) -> tuple[str, ...]:
    """``ifc_class`` and its supertypes up to IfcRoot, most specific first."""
    chain = cache.get(ifc_class)
    if chain is None:
        names = []
        decl = schema.declaration_by_name(ifc_class)
        while decl is not None:
            names.append(str(decl.name()))
            decl = decl.supertype()
        chain = cache[ifc_class] = tuple(names)
    return chain


def _pairs(
    rels: Iterable[tuple[Any, Any]], left: set[int], right: set[int], guid_of: dict[int, Any]
) -> frozenset[Relation]:
    """The GlobalId pairs (``guid_of`` by id) of the ``rels`` from ``left`` to ``right`` (ids)."""
    return frozenset(
        Relation(guid_of[a.id()], guid_of[b.id()])
        for a, b in rels
        if a is not None and b is not None and a.id() in left and b.id() in right
    )


def _warn_unmeshed(f: Any, ids: list[int]) -> None:
    """One warning naming every element and space that has a body no kernel could mesh."""
    if not ids:
        return
    names = [f"{f.by_id(i).is_a()} {f.by_id(i).GlobalId} {f.by_id(i).Name or ''}".strip() for i in ids]
    log.warning(
        "%d product(s) have a body that no geometry kernel could mesh; they are in the graph without "
        "geometry: %s",
        len(names),
        "; ".join(names),
    )


def _relations(
    f: Any,
    elements: list[Any],
    *,
    spaces: list[Any],
    zones: list[Any],
    attributes: Attributes,
    guid_of: dict[int, Any],
) -> tuple[frozenset[Relation], frozenset[Relation], frozenset[Relation]]:
    """(adjacent, contained, decomposed) GlobalId pairs; see :class:`twin.records.BuildingModel`.
    ``guid_of`` holds the GlobalId of every element, space and zone by id."""
    get = attributes.get
    element_ids = {e.id() for e in elements}
    space_ids = {s.id() for s in spaces}
    structure_ids = space_ids | {z.id() for z in zones}
    adjacent = _pairs(
        (
            (get(r, "RelatingSpace"), get(r, "RelatedBuildingElement"))
            for r in f.by_type("IfcRelSpaceBoundary")
        ),
        space_ids,
        element_ids,
        guid_of,
    )
    contained = _pairs(
        _each(
            f.by_type("IfcRelContainedInSpatialStructure"), "RelatedElements", "RelatingStructure", attributes
        ),
        structure_ids,
        element_ids,
        guid_of,
    )
    parts = [
        *_each(f.by_type("IfcRelAggregates"), "RelatedObjects", "RelatingObject", attributes),
        *_each(f.by_type("IfcRelNests"), "RelatedObjects", "RelatingObject", attributes),
        *(
            (get(r, "RelatingBuildingElement"), get(r, "RelatedOpeningElement"))
            for r in f.by_type("IfcRelVoidsElement")
        ),
        *(
            (get(r, "RelatingOpeningElement"), get(r, "RelatedBuildingElement"))
            for r in f.by_type("IfcRelFillsElement")
        ),
    ]
    decomposed = _pairs(parts, element_ids, element_ids, guid_of)
    return adjacent, contained, decomposed


@contextmanager
def _as_file_error(path: Path) -> Iterator[None]:
    """Re-raise what a malformed entity makes fail as IfcFileError (the traceback at debug level)."""
    try:
        yield
    except (*ENTITY_ERRORS, RecursionError, OverflowError) as err:
        log.debug("reading %s failed", path, exc_info=True)
        text = str(err).strip().splitlines()[0] if str(err).strip() else ""
        msg = f"{path} cannot be read as IFC: {type(err).__name__}" + (f": {text}" if text else "")
        raise IfcFileError(msg) from err


def with_geometry(record: Element, geometry: Geometry | None, kernel: str) -> Element:
    """``replace(record, geometry=geometry, mesh_kernel=kernel)``, a few times faster (12,000 elements)."""
    if geometry is record.geometry and kernel == record.mesh_kernel:
        return record
    return Element(
        record.guid,
        record.ifc_class,
        record.name,
        record.materials,
        record.is_static,
        geometry,
        record.ifc_types,
        kernel,
        record.facing_materials,
        record.predefined_type,
        record.operation_type,
    )


_KIND_CLASSES = frozenset({"IfcDoor", "IfcTransportElement", "IfcSlab"})
"""Classes whose predefined type is read (doors also their operation type): what route graphs and
maps tell apart (a lift from an escalator, a floor from a roof, a sliding door from a swing door)."""
_UNDEFINED = frozenset({"", "NOTDEFINED", "USERDEFINED"})


def _kinds(e: Any, chain: tuple[str, ...]) -> tuple[str, str]:
    """``(predefined type, operation type)`` of a door, lift or slab: the element's own, else its type
    object's (``IfcDoorType``, ``IfcDoorStyle`` in IFC2X3, ...); "" where neither says. IFC2X3 keeps a
    transport element's kind in ``OperationType``; an unreadable value counts as unknown."""
    try:
        kind_type = ifcopenshell.util.element.get_type(e)
    except ENTITY_ERRORS:
        kind_type = None

    def first(name: str) -> str:
        for source in (e, kind_type):
            if source is None:
                continue
            try:
                value = getattr(source, name, None)
            except ENTITY_ERRORS:
                value = None
            if isinstance(value, str) and value not in _UNDEFINED:
                return value
        return ""

    predefined = first("PredefinedType")
    if not predefined and "IfcTransportElement" in chain:
        predefined = first("OperationType")  # IFC2X3: IfcTransportElementTypeEnum
    operation = first("OperationType") if "IfcDoor" in chain else ""
    return predefined, operation


def _entity_name(e: Any) -> str:
    return f"{e.is_a()} {e.GlobalId} {e.Name or ''}".strip()


def _safe_material_names(e: Any, materials: Materials) -> tuple[Names, Names]:
    """The names of ``e``'s materials, none (with a warning) if they cannot be found; a material
    whose name cannot be read makes the file unreadable, as it always did."""
    try:
        key, every, facing = materials.sets(e)
    except ENTITY_ERRORS as err:
        log.warning(
            "%s: its materials cannot be read (%s: %s); imported without",
            _entity_name(e),
            type(err).__name__,
            err,
        )
        return (), ()
    return materials.names(key, every, facing)


class ModelReading:
    """An IFC file being read: its structure first, while forked children mesh; then the whole model.

    Made by :func:`start_reading`; use it as a context manager (leaving it kills the meshing children).
    """

    def __init__(
        self,
        path: Path,
        *,
        static_types: Sequence[str],
        kernels: Sequence[str],
        threads: int,
        progress: Progress | None,
        routing: bool,
    ) -> None:
        self._path = path
        f, self._lines, unplaceable = open_ifc_checked(path, cycles=False)  # checked while meshing
        self._f = f
        with _as_file_error(path):
            scale = float(ifcopenshell.util.unit.calculate_unit_scale(f))
            if not (math.isfinite(scale) and scale > 0):
                msg = f"{path} has a length unit of {scale!r} m; it must be a positive number"
                raise IfcFileError(msg)
            self._scale = scale
            self._sites = f.by_type("IfcSite")
            self._buildings = f.by_type("IfcBuilding")
            self._storeys = f.by_type("IfcBuildingStorey")
            self._spaces = f.by_type("IfcSpace")
            self._elements = f.by_type("IfcElement")
            if not self._spaces:
                log.warning(
                    "%s has no IfcSpace: importing elements, storeys and meshes without space adjacency "
                    "(no bot:adjacentElement); skills with unknown_outside cannot be mapped",
                    path,
                )
            self._attributes = Attributes()
            self._static_types = tuple(static_types)
            # Mesh in the background (forked children do the work, and route what they mesh) while
            # this thread checks the file for reference cycles and reads the structure.
            self._job = start_meshing(
                f,
                [*self._elements, *self._spaces],
                kernels=kernels,
                threads=threads,
                progress=progress,
                route=routing,
                skip=unplaceable,
            )
        try:
            check_cycles(f, path)  # a kernel on a cycle loops forever: the children are then killed
        except BaseException:
            self._job.cancel()
            raise
        self._structure: BuildingModel | None = None
        self._model: BuildingModel | None = None

    def _file(self, what: str) -> Any:
        """The open file; IfcFileError when the reading was left before ``what`` ("its model was read")."""
        if self._f is None:
            msg = f"{self._path}: the reading was left before {what}"
            raise IfcFileError(msg)
        return self._f

    def structure(self) -> BuildingModel:
        """The model without geometry: every element's and space's ``geometry`` is None, and no mesh
        failures or kernel fallbacks yet. Read once; the meshing goes on meanwhile."""
        if self._structure is not None:
            return self._structure
        f, path = self._file("its structure was read"), self._path
        with _as_file_error(path):
            up = _hierarchy(f, self._attributes)

            def guid_of(node: Any | None) -> str | None:
                return str(node.GlobalId) if node is not None else None

            attributes = self._attributes
            schema = ifcopenshell.ifcopenshell_wrapper.schema_by_name(f.schema)
            type_cache: dict[str, tuple[str, ...]] = {}
            statics = self._static_types
            infos = []
            materials = Materials(f, attributes)
            static_of: dict[tuple[str, ...], bool] = {}
            for e in self._elements:
                chain = _supertypes(schema, e.is_a(), type_cache)
                every, facing = _safe_material_names(e, materials)
                static = static_of.get(chain)
                if static is None:  # one answer per class
                    static = static_of[chain] = any(t in chain for t in statics)
                kinds = _kinds(e, chain) if _KIND_CLASSES.intersection(chain) else ("", "")
                infos.append((e, attributes.get(e, "Name"), chain, every, facing, static, *kinds))
            zones = [*self._storeys, *self._buildings, *self._sites]
            guids = {e.id(): attributes.get(e, "GlobalId") for e in (*self._elements, *self._spaces, *zones)}
            adjacent, contained, decomposed = _relations(
                f, self._elements, spaces=self._spaces, zones=zones, attributes=attributes, guid_of=guids
            )
            storey_records = tuple(
                Storey(
                    str(s.GlobalId),
                    str(s.Name or ""),
                    _elevation_m(s, self._scale),
                    guid_of(_ancestor(s, up, "IfcBuilding")),
                )
                for s in self._storeys
            ) or _building_wide_storeys(path, self._buildings, self._scale)
            self._structure = BuildingModel(
                source_name=Path(path).name,
                schema=str(f.schema),
                source_lines=self._lines,
                sites=tuple(Site(str(s.GlobalId), str(s.Name or "")) for s in self._sites),
                buildings=tuple(
                    Building(str(b.GlobalId), str(b.Name or ""), guid_of(_ancestor(b, up, "IfcSite")))
                    for b in self._buildings
                ),
                storeys=storey_records,
                spaces=tuple(
                    Space(
                        str(s.GlobalId),
                        str(s.Name or ""),
                        guid_of(_ancestor(s, up, "IfcBuildingStorey")),
                        None,
                    )
                    for s in self._spaces
                ),
                elements=tuple(
                    Element(
                        guid=str(guids[e.id()]),
                        ifc_class=chain[0],
                        name=str(name or ""),
                        materials=every,
                        is_static=is_static,
                        geometry=None,
                        ifc_types=chain,
                        facing_materials=facing,
                        predefined_type=predefined,
                        operation_type=operation,
                    )
                    for e, name, chain, every, facing, is_static, predefined, operation in infos
                ),
                adjacent=adjacent,
                contained=contained,
                decomposed=decomposed,
            )
        return self._structure

    def geometries(self) -> Iterator[tuple[str, Geometry, str]]:
        """``(GlobalId, geometry, kernel)`` of each element (kernel "" for a space) as soon as it is
        meshed, until the meshing ends: the same geometry :meth:`model` gives it. Read it once."""
        self._file("its geometries were read")
        structure = self.structure()
        guid_of = {e.id(): (r.guid, True) for e, r in zip(self._elements, structure.elements, strict=True)}
        guid_of.update((s.id(), (r.guid, False)) for s, r in zip(self._spaces, structure.spaces, strict=True))
        result = self._job.partial()
        for pid in self._job.arrivals():
            guid, is_element = guid_of[pid]
            yield guid, result.geometry[pid], result.kernel_of[pid] if is_element else ""

    def model(self) -> BuildingModel:
        """The whole model: :meth:`structure` with every mesh (waits for the meshing). Read it before
        leaving the reading (then it is kept)."""
        if self._model is not None:
            return self._model
        f = self._file("its model was read")
        structure = self.structure()
        with _as_file_error(self._path):
            meshed = self._job.result()
            geometry = meshed.geometry
            kernel_fallbacks = tuple(
                f.by_id(pid).GlobalId for pid in sorted(meshed.fallbacks) if f.by_id(pid).is_a("IfcElement")
            )
            failures = tuple(
                f.by_id(pid).GlobalId for pid in meshed.unmeshed if f.by_id(pid).is_a("IfcElement")
            )
            _warn_unmeshed(f, meshed.unmeshed)
            kernel_of = meshed.kernel_of
            elements = tuple(
                with_geometry(record, geometry.get(e.id()), kernel_of.get(e.id(), ""))
                for record, e in zip(structure.elements, self._elements, strict=True)
            )
            spaces = tuple(
                replace(record, geometry=geometry.get(s.id()))
                for record, s in zip(structure.spaces, self._spaces, strict=True)
            )
        self._model = replace(
            structure,
            elements=elements,
            spaces=spaces,
            mesh_failures=failures,
            kernel_fallbacks=kernel_fallbacks,
        )
        return self._model

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        """Kill the meshing children that still run and let go of the file: a large model's entities
        (0.04-0.08 s to free on Janesville) are freed now, while the store may still be loading, not
        whenever the caller lets go of the reading. Only the records read before stay."""
        self._job.release()  # cancels what still runs
        self._f = None
        self._sites = self._buildings = self._storeys = self._spaces = self._elements = []


def start_reading(
    path: Path,
    *,
    static_types: Sequence[str] = (),
    kernels: Sequence[str] = DEFAULT_KERNELS,
    threads: int = 2,
    progress: Progress | None = None,
    routing: bool = True,
) -> ModelReading:
    """Open ``path`` and start meshing it in the background; see :class:`ModelReading`. Raise
    :class:`~adapters.ifc.errors.IfcFileError` on a bad file.

    ``routing=False`` gives every body to the first kernel, even those it gets wrong
    (:mod:`adapters.ifc.kernel_choice`): only to measure what the routing fixes (``benchmarks/kernels.py``).
    """
    return ModelReading(
        path, static_types=static_types, kernels=kernels, threads=threads, progress=progress, routing=routing
    )


def read_model(
    path: Path,
    *,
    static_types: Sequence[str] = (),
    kernels: Sequence[str] = DEFAULT_KERNELS,
    threads: int = 2,
    progress: Progress | None = None,
    routing: bool = True,
) -> BuildingModel:
    """Read ``path`` into records. Raise :class:`~adapters.ifc.errors.IfcFileError` on a bad file.

    ``routing=False``: see :func:`start_reading`.
    """
    with (
        paused_gc(),  # the import makes few cycles; collecting costs ~0.2 s on 12,000 elements
        start_reading(
            path,
            static_types=static_types,
            kernels=kernels,
            threads=threads,
            progress=progress,
            routing=routing,
        ) as reading,
    ):
        return reading.model()
