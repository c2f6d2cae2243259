"""Typed records at the boundaries of the core.

Adapters turn foreign data (IFC files, wire payloads) into these records: a building model to import
(:class:`BuildingModel`), what robots report about elements (:class:`ElementReport`, parsed by
``twin.live.parse``); the import turns them into triples, the scene reads them back. They import
nothing but numpy. All lengths are metres, in the building's world frame unless a field says ``local``.

Arrays follow trimesh's conventions:

- ``vertices``: ``(n, 3) float64``
- ``faces``: ``(m, 3) int32`` indices into ``vertices``
- ``placement``: ``(4, 4) float64`` homogeneous matrix, world-from-local
"""

from __future__ import annotations

import operator
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from twin.errors import ModelError

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int32]


@dataclass(frozen=True, eq=False, slots=True)
class Mesh:
    """A triangle mesh in an element's local frame.

    Attributes:
        vertices: ``(n, 3) float64`` local coordinates in metres.
        faces: ``(m, 3) int32`` vertex indices, one row a triangle.
        closed: True when every edge is shared by exactly two faces (a watertight solid): such
            meshes are filled when sliced; open meshes contribute their surfaces only.
        solid: True when the body bounds a volume although its mesh may be open: the source model
            says it is a solid (an extrusion, a B-rep, a CSG or boolean result, ...), or it is a
            surface whose faces close around a volume up to T-junctions (a lift's car modelled as a
            surface model: :func:`twin.maps.meshops.closes_around`). Such an open mesh (T-junctions, seams
            a kernel left unstitched) is still filled where its section is made of closed loops.
            False for open surfaces and when unknown (older stores, meshes robots send).
    """

    vertices: FloatArray
    faces: IntArray
    closed: bool
    solid: bool = False

    def __post_init__(self) -> None:
        if self.vertices.dtype != np.float64 or self.faces.dtype != np.int32:
            msg = (
                "Mesh arrays must be float64 vertices and int32 faces, "
                f"got {self.vertices.dtype} and {self.faces.dtype}."
            )
            raise ModelError(msg)
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 3:
            msg = f"Mesh vertices must have shape (n, 3), got {self.vertices.shape}."
            raise ModelError(msg)
        if self.faces.ndim != 2 or self.faces.shape[1] != 3:
            msg = f"Mesh faces must have shape (m, 3), got {self.faces.shape}."
            raise ModelError(msg)
        if not np.isfinite(self.vertices).all():
            msg = "Mesh vertices contain NaN or infinite coordinates."
            raise ModelError(msg)
        if self.faces.size and (self.faces.min() < 0 or self.faces.max() >= len(self.vertices)):
            msg = (
                f"Mesh face indices must lie in [0, {len(self.vertices)}), "
                f"got [{self.faces.min()}, {self.faces.max()}]."
            )
            raise ModelError(msg)

    @property
    def triangle_count(self) -> int:
        return int(self.faces.shape[0])


IDENTITY: FloatArray = np.eye(4)


def check_placement(matrix: npt.ArrayLike) -> FloatArray:
    """Coerce ``matrix`` to a finite ``(4, 4) float64`` affine matrix or raise ModelError naming it."""
    m = np.asarray(matrix, dtype=np.float64)
    if m.shape != (4, 4):
        msg = f"A placement must be a 4x4 matrix, got shape {m.shape}."
        raise ModelError(msg)
    if not np.isfinite(m).all():
        msg = "A placement contains NaN or infinite values."
        raise ModelError(msg)
    if abs(m[3, 0]) + abs(m[3, 1]) + abs(m[3, 2]) + abs(m[3, 3] - 1.0) > 1e-9:
        msg = f"A placement's last row must be [0, 0, 0, 1], got {m[3].tolist()}."
        raise ModelError(msg)
    return m


def to_world(vertices: FloatArray, placement: FloatArray) -> FloatArray:
    """``(n, 3) float64``: local ``vertices`` ``(n, 3)`` put in the world by ``placement`` ``(4, 4)``.

    The one mesh-to-world transform: every map, bound and comparison goes through it, so the same
    mesh and placement give the same world coordinates bit for bit wherever they are computed.
    """
    return vertices @ placement[:3, :3].T + placement[:3, 3]


@dataclass(frozen=True, eq=False, slots=True)
class Geometry:
    """An element's shape: a local mesh and the placement that puts it in the world."""

    mesh: Mesh
    placement: FloatArray = field(default_factory=IDENTITY.copy)

    def world_vertices(self) -> FloatArray:
        """``(n, 3) float64``: the mesh vertices transformed by the placement."""
        return to_world(self.mesh.vertices, self.placement)


@dataclass(frozen=True, slots=True)
class Site:
    guid: str
    name: str


@dataclass(frozen=True, slots=True)
class Building:
    guid: str
    name: str
    site_guid: str | None


@dataclass(frozen=True, slots=True)
class Storey:
    """A building storey. ``elevation_m`` is in metres in the world frame (z of its floor datum)."""

    guid: str
    name: str
    elevation_m: float
    building_guid: str | None


@dataclass(frozen=True, eq=False, slots=True)
class Space:
    """A room (``IfcSpace``): a volume of air, bounded by elements, containing elements."""

    guid: str
    name: str
    storey_guid: str | None
    geometry: Geometry | None = None


@dataclass(frozen=True, eq=False, slots=True)
class Element:
    """A physical (or virtual, e.g. an opening) building element.

    Attributes:
        guid: the IFC GlobalId (22-character compressed form).
        ifc_class: the IFC entity name, e.g. ``"IfcWallStandardCase"``.
        ifc_types: ``ifc_class`` and all its supertypes, most specific first (``IfcWallStandardCase``,
            ``IfcWall``, ``IfcBuildingElement``, ...), so selections by type include subtypes.
        materials: IfcMaterial names, in file order, without duplicates.
        facing_materials: the subset a sensor faces: a single material, every constituent or list
            member, only the first and last layer of a layer set.
        is_static: part of the building's fixed structure (configured per IFC class).
        geometry: local mesh + placement, or None when it has no body or failed to mesh.
        mesh_kernel: the geometry kernel that meshed it (e.g. ``"manifold"``), "" when unknown.
        predefined_type: the IFC ``PredefinedType`` of a door, lift (``IfcTransportElement``: e.g.
            ``"ELEVATOR"``, ``"ESCALATOR"``) or slab (``"FLOOR"``, ``"ROOF"``), its type object's when
            the element leaves it undefined; "" when unknown or another class.
        operation_type: a door's ``OperationType`` (e.g. ``"SINGLE_SWING_LEFT"``,
            ``"DOUBLE_DOOR_SLIDING"``), its type's (``IfcDoorType``, IFC2X3 ``IfcDoorStyle``) when the
            door leaves it undefined; "" when unknown or not a door.
    """

    guid: str
    ifc_class: str
    name: str
    materials: tuple[str, ...]
    is_static: bool
    geometry: Geometry | None = None
    ifc_types: tuple[str, ...] = ()
    mesh_kernel: str = ""
    facing_materials: tuple[str, ...] = ()
    predefined_type: str = ""
    operation_type: str = ""


@dataclass(frozen=True, slots=True)
class Relation:
    """A directed pair of GlobalIds, e.g. (space, element) for adjacency."""

    subject: str
    object: str


@dataclass(frozen=True, eq=False, slots=True)
class BuildingModel:
    """Everything the graph world model is initialised from, independent of the IFC library.

    Relations are sets of GlobalId pairs:
        adjacent: (space, element) pairs from space boundaries (``bot:adjacentElement``).
        contained: (space or storey, element) pairs (``bot:containsElement``).
        decomposed: (whole, part) pairs, including (host, opening) and (opening, filling)
            (``bot:hasSubElement``).
    """

    source_name: str
    schema: str
    source_lines: int
    sites: tuple[Site, ...]
    buildings: tuple[Building, ...]
    storeys: tuple[Storey, ...]
    spaces: tuple[Space, ...]
    elements: tuple[Element, ...]
    adjacent: frozenset[Relation]
    contained: frozenset[Relation]
    decomposed: frozenset[Relation]
    mesh_failures: tuple[str, ...] = ()
    kernel_fallbacks: tuple[str, ...] = ()


Shape = tuple[Mesh, FloatArray]
"""An element's geometry as the live twin holds it: a local mesh and its ``(4, 4)`` placement."""


@dataclass(frozen=True, eq=False, slots=True)
class GeometryChange:
    """An element's geometry changed: ``new`` is its mesh and placement now, None if it has none."""

    iri: str
    new: Shape | None


@dataclass(frozen=True, slots=True)
class ObservedBox:
    """An oriented box: centre (x, y in the building's XY frame, z above the storey's elevation),
    sizes and yaw about +z; metres and radians."""

    cx: float
    cy: float
    cz: float
    sx: float
    sy: float
    sz: float
    yaw: float

    def text(self) -> str:
        return " ".join(repr(v) for v in (self.cx, self.cy, self.cz, self.sx, self.sy, self.sz, self.yaw))

    def __reduce__(self) -> tuple[Any, tuple[object, ...]]:
        return _by_fields(self)


@dataclass(frozen=True, eq=False, slots=True)
class ElementReport:
    """What one observation says about one element. Unset fields are left as they are in the twin."""

    iri: str
    ifc_class: str | None = None
    storey: str | None = None
    box: ObservedBox | None = None
    geometry: Geometry | None = None
    """A full mesh and its placement (``omg:hasGeometry``)."""
    placement: FloatArray | None = None
    """A new placement only (a move): same mesh."""
    is_open: bool | None = None
    removed: bool = False
    keepout: bool | None = None
    """A keepout zone mark (``twin:keepout``), None: left as it is."""
    speed_limit: int | None = None
    """A speed zone mark (``twin:speedLimit``, percent; 0 lifts it), None: left as it is."""
    labels: tuple[str, ...] = ()
    materials: tuple[str, ...] = ()
    classes: tuple[str, ...] = ()
    """Extra ``rdf:type`` IRIs (BEO or FURN classes such as ``furn:Table``)."""
    sense_ns: int | None = None
    """When it was seen (``twin:senseTime``, ns since the epoch); None: the view's, else arrival time."""
    distinct: bool = False
    """``twin:distinct true``: a new object, never associated with an element the twin holds."""
    unmerge: bool = False
    """``twin:unmerge true``: this IRI was merged into another element; make it its own again."""
    lifetime_s: float | None = None
    """``twin:lifetime``: how long the report holds from its observation, seconds (kept in the graph
    for its reporter, e.g. an Open-RMF obstacle's lifetime); None: left as it is."""

    @property
    def changes_geometry(self) -> bool:
        return self.box is not None or self.geometry is not None or self.placement is not None

    def __reduce__(self) -> tuple[type[ElementReport], tuple[object, ...]]:
        return _by_fields(self)


@dataclass(frozen=True, eq=False, slots=True)
class ObservedView:
    """What a robot looked at (``a twin:View``): the floor it saw on a storey, when, and which classes
    its detector reports. Elements of those classes inside ``polygons`` (less ``holes``; by area), and
    visible from ``origin`` when it is given, that the observation does not describe were not seen
    there (a miss: :mod:`twin.fusion.visibility`)."""

    storey: str
    polygons: tuple[FloatArray, ...]
    """``(n, 2) float64`` simple polygons in the map (building XY) frame, metres; their union."""
    detects: tuple[str, ...]
    """IFC classes (subtypes included)."""
    sense_ns: int | None = None
    holes: tuple[FloatArray, ...] = ()
    """``(n, 2) float64`` simple polygons inside ``polygons`` that the sensor did not see (shadows)."""
    origin: tuple[float, float, float] | None = None
    """The sensor's position (``twin:origin``): x, y in the map frame, z above the storey's elevation;
    with it, only elements visible from there past the others the twin holds collect misses."""

    def __reduce__(self) -> tuple[type[ObservedView], tuple[object, ...]]:
        return _by_fields(self)


@dataclass(frozen=True, eq=False, slots=True)
class Observation:
    """A parsed observation document: its element reports and, optionally, the view they were seen in."""

    reports: tuple[ElementReport, ...]
    view: ObservedView | None = None

    def __reduce__(self) -> tuple[type[Observation], tuple[object, ...]]:
        return (Observation, (self.reports, self.view))


def _by_fields(record: Any) -> tuple[Any, tuple[object, ...]]:
    """A record pickled as a call of its maker (:func:`_maker`) with its fields (the ROS ingest workers
    hand many over, 20 reports an array): three times as fast to load as the setstate of a frozen
    dataclass with slots, and a little smaller."""
    cls = type(record)
    return (_MAKERS[cls], _FIELDS[cls](record))


def _maker(cls: type, name: str) -> Callable[..., Any]:
    """A function that makes a ``cls`` from its fields in the order of its slots without its ``__init__``:
    the new object's slots set one by one through their descriptors, where the frozen dataclass's
    ``__init__`` calls ``object.__setattr__`` for each (a report in 0.65 us instead of 1.1, a box in 0.3
    instead of 0.5). Generated from the slots as dataclasses generate ``__init__``, so a field added
    is never left out; only for records whose ``__init__`` stores its fields and nothing else. ``name``:
    the module's global that holds it (pickle finds it again by its name)."""
    if hasattr(cls, "__post_init__"):
        raise TypeError(f"{cls.__name__} has a __post_init__: a maker would skip it")
    slots: tuple[str, ...] = getattr(cls, "__slots__")  # noqa: B009 (a dataclass's, unknown to mypy)
    args = ", ".join(f"f{i}" for i in range(len(slots)))
    body = "".join(f"    s{i}(r, f{i})\n" for i in range(len(slots)))
    env: dict[str, Any] = {"new": object.__new__, "cls": cls}
    env.update((f"s{i}", getattr(cls, slot).__set__) for i, slot in enumerate(slots))
    exec(f"def make({args}):\n    r = new(cls)\n{body}    return r\n", env)
    make: Callable[..., Any] = env["make"]
    make.__name__ = make.__qualname__ = name
    make.__module__ = __name__
    return make


_make_box = _maker(ObservedBox, "_make_box")
_make_report = _maker(ElementReport, "_make_report")
_make_view = _maker(ObservedView, "_make_view")
_MAKERS: dict[type, Callable[..., Any]] = {
    ObservedBox: _make_box,
    ElementReport: _make_report,
    ObservedView: _make_view,
}


def boxed_report(
    iri: str,
    ifc_class: str | None,
    storey: str | None,
    box: tuple[float, float, float, float, float, float, float],
    *,
    labels: tuple[str, ...],
    classes: tuple[str, ...],
    sense_ns: int | None,
    lifetime_s: float | None,
) -> ElementReport:
    """``ElementReport(iri, ifc_class=, storey=, box=ObservedBox(*box), labels=, classes=, sense_ns=,
    lifetime_s=)`` (every other field its default), made by the makers (:func:`_maker`): the ROS ingest
    workers make 20 an array, 1 us each instead of 3."""
    report: ElementReport = _make_report(
        iri, ifc_class, storey, _make_box(*box), None, None, None, False, None, None, labels, (), classes,
        sense_ns, False, False, lifetime_s,
    )  # fmt: skip
    return report


_FIELDS: dict[type, Callable[[Any], tuple[object, ...]]] = {
    cls: operator.attrgetter(*cls.__slots__)  # type: ignore[attr-defined] # (a dataclass's)
    for cls in _MAKERS
}
"""The records pickled by :func:`_by_fields`: their fields read at once, in order (their slots)."""
