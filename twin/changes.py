"""Turn an observation into one store transaction: check it against the twin, then write the triples.

:func:`plan_observation` decides everything before anything changes: whether each element exists,
whether the robot may change it (its rights: ``create`` new dynamic elements, change ``dynamic``
ones, open and close ``doors``, change ``static`` structure), that its storey exists and its geometry
lies within the site. It returns the :class:`~twin.store.ChangeSet` (with provenance:
``twin:observedBy``, ``twin:observedAt``, ``twin:revision``) and the geometry changes for the map
engine; on any problem it raises ObservationError and nothing is changed.

Example::

    plan = plan_observation(reports, robot="robot1", rights=cfg.rights_of("robot1"), twin=state, ...)
    store.apply(plan.changes)
"""

from __future__ import annotations

import datetime
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from twin import vocab
from twin.config import Right
from twin.engine import GeometryChange, Shape
from twin.errors import ObservationError
from twin.ifc_classes import supertypes
from twin.meshcodec import encode_mesh, encode_placement
from twin.observations import ElementReport
from twin.records import Mesh
from twin.shapes import box_mesh, box_placement
from twin.store import ChangeSet, GraphStore, Literal, Triple


@dataclass(frozen=True, slots=True)
class ElementState:
    """What the twin knows of an element, beyond its geometry."""

    iri: str
    ifc_class: str
    ifc_types: tuple[str, ...]
    is_static: bool
    name: str = ""
    storey: str | None = None
    is_open: bool | None = None
    removed: bool = False

    @property
    def is_door(self) -> bool:
        return "IfcDoor" in self.ifc_types


@dataclass(frozen=True, slots=True)
class StoreyFrame:
    key: str
    iri: str
    elevation_m: float


@dataclass(frozen=True, slots=True)
class TwinContext:
    """The read-only facts a plan is checked against."""

    states: Mapping[str, ElementState]
    storeys: Mapping[str, StoreyFrame]
    schema: str
    static_types: tuple[str, ...]
    site_box: tuple[float, float, float, float, float, float]
    """World ``xmin, ymin, zmin, xmax, ymax, zmax`` observed geometry must lie in (margin included)."""
    model_iri: str


@dataclass(frozen=True, eq=False, slots=True)
class ObservationPlan:
    changes: ChangeSet
    geometry: tuple[GeometryChange, ...]
    states: dict[str, ElementState] = field(default_factory=dict)
    """The new state of every element the observation touched."""
    upserted: tuple[str, ...] = ()
    removed: tuple[str, ...] = ()


def load_states(store: GraphStore) -> dict[str, ElementState]:
    """Every element's class, supertypes, static flag, name, storey, door state and removal."""
    rows = store.select(
        """SELECT ?e ?cls ?static (SAMPLE(?n) AS ?name) (SAMPLE(?key) AS ?storey) (SAMPLE(?open) AS ?isOpen)
                  (SAMPLE(?gone) AS ?removed) (GROUP_CONCAT(DISTINCT ?t; separator=" ") AS ?types) WHERE {
             ?e a bot:Element ; twin:ifcClass ?cls .
             OPTIONAL { ?e twin:isStatic ?static }
             OPTIONAL { ?e twin:ifcType ?t }
             OPTIONAL { ?e rdfs:label ?n }
             OPTIONAL { ?st twin:storeyKey ?key ; bot:containsElement ?e }
             OPTIONAL { ?e twin:isOpen ?open }
             OPTIONAL { ?e twin:removed ?gone }
           } GROUP BY ?e ?cls ?static"""
    )
    out = {}
    for r in rows:
        iri = r["e"] or ""
        cls = r["cls"] or ""
        types = tuple((r["types"] or cls).split())
        out[iri] = ElementState(
            iri=iri,
            ifc_class=cls,
            ifc_types=(cls, *(t for t in types if t != cls)),
            is_static=r["static"] in ("true", "1"),
            name=r["name"] or "",
            storey=r["storey"],
            is_open=None if r["isOpen"] is None else r["isOpen"] in ("true", "1"),
            removed=r["removed"] in ("true", "1"),
        )
    return out


def _fail(message: str) -> ObservationError:
    return ObservationError(message)


def _need(rights: frozenset[Right], right: Right, robot: str, what: str) -> None:
    if right not in rights:
        raise _fail(f"Robot {robot!r} may not {what} (it lacks the {right!r} right).")


def _lit(value: str, datatype: str = vocab.XSD_STRING) -> Literal:
    return Literal(value, datatype)


def _bool(value: bool) -> Literal:
    return Literal("true" if value else "false", vocab.XSD_BOOLEAN)


def _geometry_triples(iri: str, mesh: Mesh, placement: np.ndarray) -> list[Triple]:
    g = vocab.geometry_iri(iri)
    return [
        Triple(iri, vocab.OMG_HAS_GEOMETRY, g),
        Triple(g, vocab.RDF_TYPE, vocab.OMG_GEOMETRY),
        Triple(g, vocab.FOG_PLY_BINARY_LE, _lit(encode_mesh(mesh), vocab.XSD_BASE64)),
        Triple(g, vocab.TWIN_PLACEMENT, _lit(encode_placement(placement), vocab.TWIN_MATRIX4)),
        Triple(g, vocab.TWIN_CLOSED, _bool(mesh.closed)),
        Triple(g, vocab.TWIN_TRIANGLES, _lit(str(mesh.triangle_count), vocab.XSD_INTEGER)),
    ]


def _shape(report: ElementReport, ctx: TwinContext, current: Shape | None, robot: str) -> Shape | None:
    """The element's new mesh and placement, or None when the report leaves the geometry alone."""
    if report.box is not None:
        b = report.box
        storey = ctx.storeys.get(report.storey or "")
        if storey is None:
            known = ", ".join(sorted(ctx.storeys)) or "none"
            raise _fail(f"Element <{report.iri}>: unknown storey {report.storey!r}; storeys: {known}.")
        return box_mesh(b.sx, b.sy, b.sz), box_placement(b.cx, b.cy, storey.elevation_m + b.cz, yaw=b.yaw)
    if report.geometry is not None:
        return report.geometry.mesh, report.geometry.placement
    if report.placement is not None:
        if current is None:
            raise _fail(f"Element <{report.iri}>: twin:placement moves an element, but it has no geometry.")
        return current[0], report.placement
    return None


def _check_inside(iri: str, shape: Shape, ctx: TwinContext) -> None:
    mesh, placement = shape
    world = mesh.vertices @ placement[:3, :3].T + placement[:3, 3]
    lo, hi = world.min(axis=0), world.max(axis=0)
    b = ctx.site_box
    if (lo < np.array(b[:3])).any() or (hi > np.array(b[3:])).any():
        box = ", ".join(f"{v:.2f}" for v in (*lo, *hi))
        site = ", ".join(f"{v:.2f}" for v in b)
        raise _fail(f"Element <{iri}>: its geometry ({box}) lies outside the site's extent ({site}).")


def plan_observation(
    reports: Sequence[ElementReport],
    *,
    robot: str,
    rights: frozenset[Right],
    ctx: TwinContext,
    shapes: Mapping[str, Shape | None],
    revision: int,
    stamp_ns: int,
) -> ObservationPlan:
    """Check ``reports`` against the twin and build the transaction; ObservationError names a problem.

    Args:
        reports: the parsed observation.
        robot: who observed it (provenance; rights).
        rights: what this robot may change.
        ctx: the twin's elements, storeys, schema and extent.
        shapes: the current mesh and placement of each reported element that has geometry.
        revision: the twin revision this change will be.
        stamp_ns: when the observation was received.
    """
    remove: list[tuple[str, str | None]] = []
    add: list[Triple] = []
    geometry: list[GeometryChange] = []
    states: dict[str, ElementState] = {}
    upserted, removed = [], []
    when = datetime.datetime.fromtimestamp(stamp_ns / 1e9, tz=datetime.UTC).isoformat()
    for r in reports:
        state = ctx.states.get(r.iri)
        exists = state is not None and not state.removed
        if r.removed:
            if not exists or state is None:
                raise _fail(f"Element <{r.iri}> cannot be removed: the twin has no such element.")
            _need(rights, "static" if state.is_static else "dynamic", robot, f"remove <{r.iri}>")
            g = vocab.geometry_iri(r.iri)
            remove += [(r.iri, vocab.OMG_HAS_GEOMETRY), (g, None), (r.iri, vocab.TWIN_REMOVED)]
            add.append(Triple(r.iri, vocab.TWIN_REMOVED, _bool(True)))
            if shapes.get(r.iri) is not None:
                geometry.append(GeometryChange(r.iri, None))
            states[r.iri] = replace(state, removed=True)
            removed.append(r.iri)
        else:
            if state is None or not exists:
                if r.ifc_class is None:
                    raise _fail(f"Element <{r.iri}> is new: give its twin:ifcClass.")
                chain = supertypes(ctx.schema, r.ifc_class)
                if chain is None:
                    raise _fail(f"Element <{r.iri}>: {r.ifc_class!r} is not an IFC element class.")
                if r.box is None and r.geometry is None:
                    raise _fail(f"Element <{r.iri}> is new: give its twin:box or omg:hasGeometry.")
                is_static = any(t in ctx.static_types for t in chain)
                _need(rights, "create", robot, f"create <{r.iri}>")
                if is_static:
                    _need(rights, "static", robot, f"create the static {chain[0]} <{r.iri}>")
                if state is not None:  # re-created after its removal: start from a clean node
                    remove += [(r.iri, None)]
                state = ElementState(r.iri, chain[0], chain, is_static, storey=r.storey)
                add += [
                    Triple(r.iri, vocab.RDF_TYPE, vocab.BOT_ELEMENT),
                    Triple(r.iri, vocab.TWIN_IFC_CLASS, _lit(chain[0])),
                    Triple(r.iri, vocab.TWIN_IS_STATIC, _bool(is_static)),
                    *(Triple(r.iri, vocab.TWIN_IFC_TYPE, _lit(t)) for t in chain),
                ]
                semantic = vocab.semantic_class(chain[0])
                if semantic is not None:
                    add.append(Triple(r.iri, vocab.RDF_TYPE, semantic))
            else:
                if r.ifc_class is not None and r.ifc_class.lower() != state.ifc_class.lower():
                    raise _fail(
                        f"Element <{r.iri}> is an {state.ifc_class}: "
                        f"an observation cannot make it {r.ifc_class}."
                    )
                if r.changes_geometry or r.labels or r.materials or r.classes or r.storey:
                    _need(rights, "static" if state.is_static else "dynamic", robot, f"change <{r.iri}>")
                remove.append((r.iri, vocab.TWIN_REMOVED))
            if r.is_open is not None:
                if not state.is_door:
                    raise _fail(
                        f"Element <{r.iri}> is an {state.ifc_class}, not a door: it cannot be opened."
                    )
                _need(rights, "doors", robot, f"open or close <{r.iri}>")
                remove.append((r.iri, vocab.TWIN_IS_OPEN))
                add.append(Triple(r.iri, vocab.TWIN_IS_OPEN, _bool(r.is_open)))
                state = replace(state, is_open=r.is_open)
            shape = _shape(r, ctx, shapes.get(r.iri), robot)
            if shape is not None:
                _check_inside(r.iri, shape, ctx)
                g = vocab.geometry_iri(r.iri)
                remove += [(r.iri, vocab.OMG_HAS_GEOMETRY), (g, None)]
                add += _geometry_triples(r.iri, *shape)
                geometry.append(GeometryChange(r.iri, shape))
            if r.storey is not None:
                storey = ctx.storeys.get(r.storey)
                if storey is None:
                    known = ", ".join(sorted(ctx.storeys)) or "none"
                    raise _fail(f"Element <{r.iri}>: unknown storey {r.storey!r}; storeys: {known}.")
                if state.storey != r.storey or not exists:
                    add.append(Triple(storey.iri, vocab.BOT_CONTAINS_ELEMENT, r.iri))
                    state = replace(state, storey=r.storey)
            for label in r.labels:
                add.append(Triple(r.iri, vocab.RDFS_LABEL, _lit(label)))
            if r.labels:
                state = replace(state, name=r.labels[0])
            # What a robot reports is what its sensors face: each material is a facing one too.
            add += [
                Triple(r.iri, p, _lit(m))
                for m in r.materials
                for p in (vocab.TWIN_MATERIAL, vocab.TWIN_FACING_MATERIAL)
            ]
            add += [Triple(r.iri, vocab.RDF_TYPE, c) for c in r.classes]
            states[r.iri] = replace(state, removed=False)
            upserted.append(r.iri)
        remove += [(r.iri, p) for p in (vocab.TWIN_OBSERVED_BY, vocab.TWIN_OBSERVED_AT, vocab.TWIN_REVISION)]
        add += [
            Triple(r.iri, vocab.TWIN_OBSERVED_BY, _lit(robot)),
            Triple(r.iri, vocab.TWIN_OBSERVED_AT, _lit(when, vocab.XSD_DATETIME)),
            Triple(r.iri, vocab.TWIN_REVISION, _lit(str(revision), vocab.XSD_INTEGER)),
        ]
    remove.append((ctx.model_iri, vocab.TWIN_REVISION))
    add.append(Triple(ctx.model_iri, vocab.TWIN_REVISION, _lit(str(revision), vocab.XSD_INTEGER)))
    return ObservationPlan(
        changes=ChangeSet(remove=tuple(remove), add=tuple(add)),
        geometry=tuple(geometry),
        states=states,
        upserted=tuple(upserted),
        removed=tuple(removed),
    )
