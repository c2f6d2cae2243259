"""Plan an observation: check it against the twin, and write only what it changes.

:func:`plan_observation` decides everything before anything changes: whether each element exists,
whether the robot may change it (its rights: ``create`` new dynamic elements, change ``dynamic``
ones, open and close ``doors``, change ``static`` structure), that its storey exists and its geometry
lies within the site. It returns the :class:`~twin.store.ChangeSet` and the geometry changes for the
live maps; on any problem it raises ObservationError and nothing is changed.

Only what differs from the twin is written: a moved box rewrites its placement, not its mesh; a door
seen in the state it is in, or a table within 1 mm and 0.1 mrad of where it stands
(:mod:`twin.tolerances`), writes nothing. An observation that changes nothing at all is a
*re-confirmation* (``plan.unchanged``): no transaction, no revision, no map work. An element's
provenance (``twin:observedBy``, ``twin:observedAt``, ``twin:revision``) is that of its latest change.

Example::

    plan = plan_observation(reports, robot="robot1", rights=cfg.rights_of("robot1"), site=site,
                            states=states, shapes=shapes, revision=7, stamp_ns=time.time_ns())
    if not plan.unchanged:
        store.apply(plan.changes)
"""

from __future__ import annotations

import datetime
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from twin import vocab
from twin.config import Right
from twin.errors import ObservationError
from twin.ifc_classes import supertypes
from twin.live.state import ElementState, SiteFrame
from twin.meshcodec import encode_mesh, encode_placement
from twin.observations import ElementReport
from twin.records import FloatArray, GeometryChange, Mesh, Shape
from twin.shapes import box_mesh, box_placement
from twin.store import ChangeSet, Object, RdfLiteral, Triple
from twin.tolerances import SAME_ANGLE_RAD, SAME_POSITION_M


@dataclass(frozen=True, eq=False, slots=True)
class ObservationPlan:
    changes: ChangeSet
    geometry: tuple[GeometryChange, ...]
    states: dict[str, ElementState] = field(default_factory=dict)
    """The new state of every element the observation changed."""
    upserted: tuple[str, ...] = ()
    removed: tuple[str, ...] = ()
    written: dict[str, dict[str, Object | None]] = field(default_factory=dict)
    """The single-valued triples this plan writes, by subject (see :data:`Held`)."""
    cleared: frozenset[str] = frozenset()
    """Subjects whose every triple this plan removes (before writing ``written``)."""

    @property
    def unchanged(self) -> bool:
        """True for a re-confirmation: the observation changes nothing the twin holds."""
        return not self.changes


def _fail(message: str) -> ObservationError:
    return ObservationError(message)


def _need(rights: frozenset[Right], right: Right, robot: str, what: str) -> None:
    if right not in rights:
        raise _fail(f"Robot {robot!r} may not {what} (it lacks the {right!r} right).")


def _lit(value: str, datatype: str = vocab.XSD_STRING) -> RdfLiteral:
    return RdfLiteral(value, datatype)


def _bool(value: bool) -> RdfLiteral:
    return RdfLiteral("true" if value else "false", vocab.XSD_BOOLEAN)


def same_mesh(a: Mesh, b: Mesh) -> bool:
    """The same mesh exactly (vertices, faces, closedness)."""
    return a is b or (
        a.closed == b.closed
        and a.vertices.shape == b.vertices.shape
        and a.faces.shape == b.faces.shape
        and bool(np.array_equal(a.faces, b.faces))
        and bool(np.array_equal(a.vertices, b.vertices))
    )


def same_shape(a: Shape, b: Shape) -> bool:
    """The same geometry within the re-confirmation tolerances: the same faces, every world vertex
    within :data:`~twin.tolerances.SAME_POSITION_M`, the orientation within
    :data:`~twin.tolerances.SAME_ANGLE_RAD`."""
    (ma, pa), (mb, pb) = a, b
    if ma.closed != mb.closed or ma.faces.shape != mb.faces.shape or ma.vertices.shape != mb.vertices.shape:
        return False
    if ma is not mb and not np.array_equal(ma.faces, mb.faces):
        return False
    wa = ma.vertices @ pa[:3, :3].T + pa[:3, 3]
    wb = mb.vertices @ pb[:3, :3].T + pb[:3, 3]
    if len(wa) and float(np.abs(wa - wb).max()) > SAME_POSITION_M:
        return False
    # the angle of the relative rotation (orthonormal parts of the placements)
    r = _rotation(pa).T @ _rotation(pb)
    cos = (float(np.trace(r)) - 1.0) / 2.0
    return bool(np.arccos(np.clip(cos, -1.0, 1.0)) <= SAME_ANGLE_RAD)


def _rotation(p: FloatArray) -> FloatArray:
    m = p[:3, :3]
    scale = np.linalg.norm(m, axis=0)
    scale[scale == 0] = 1.0
    return np.asarray(m / scale)


def _quantised(placement: FloatArray) -> FloatArray:
    """A box's placement rounded (rotation to 1e-9, position to 1 um): far below the re-confirmation
    tolerances, and a shorter literal in the store for every move."""
    out = np.round(placement, 9)
    out[:3, 3] = np.round(placement[:3, 3], 6)
    return np.asarray(out)


def _geometry_triples(iri: str, mesh: Mesh, placement: FloatArray) -> list[Triple]:
    g = vocab.geometry_iri(iri)
    return [
        Triple(iri, vocab.OMG_HAS_GEOMETRY, g),
        Triple(g, vocab.RDF_TYPE, vocab.OMG_GEOMETRY),
        Triple(g, vocab.FOG_PLY_BINARY_LE, _lit(encode_mesh(mesh), vocab.XSD_BASE64)),
        Triple(g, vocab.TWIN_PLACEMENT, _lit(encode_placement(placement), vocab.TWIN_MATRIX4)),
        Triple(g, vocab.TWIN_CLOSED, _bool(mesh.closed)),
        Triple(g, vocab.TWIN_TRIANGLES, _lit(str(mesh.triangle_count), vocab.XSD_INTEGER)),
    ]


def _shape(report: ElementReport, site: SiteFrame, current: Shape | None) -> Shape | None:
    """The element's reported mesh and placement, None when the report leaves the geometry alone."""
    if report.box is not None:
        b = report.box
        storey = site.storeys.get(report.storey or "")
        if storey is None:
            known = ", ".join(sorted(site.storeys)) or "none"
            raise _fail(f"Element <{report.iri}>: unknown storey {report.storey!r}; storeys: {known}.")
        mesh = box_mesh(b.sx, b.sy, b.sz)
        if current is not None and same_mesh(mesh, current[0]):
            mesh = current[0]  # a moved box keeps its mesh: one object, one literal
        return mesh, _quantised(box_placement(b.cx, b.cy, storey.elevation_m + b.cz, yaw=b.yaw))
    if report.geometry is not None:
        return report.geometry.mesh, report.geometry.placement
    if report.placement is not None:
        if current is None:
            raise _fail(f"Element <{report.iri}>: twin:placement moves an element, but it has no geometry.")
        return current[0], report.placement
    return None


def _check_inside(iri: str, shape: Shape, site: SiteFrame) -> None:
    mesh, placement = shape
    world = mesh.vertices @ placement[:3, :3].T + placement[:3, 3]
    lo, hi = world.min(axis=0), world.max(axis=0)
    b = site.site_box
    if (lo < np.array(b[:3])).any() or (hi > np.array(b[3:])).any():
        box = ", ".join(f"{v:.2f}" for v in (*lo, *hi))
        extent = ", ".join(f"{v:.2f}" for v in b)
        raise _fail(f"Element <{iri}>: its geometry ({box}) lies outside the site's extent ({extent}).")


Held = Mapping[str, Mapping[str, Object | None]]
"""Subject -> predicate -> the exact object of the single-valued triples the writer last wrote."""


@dataclass(slots=True)
class _Writer:
    """The triples one observation removes (patterns and exact triples) and adds.

    A single-valued triple the writer wrote before is replaced by deleting that exact triple: a pattern
    (``DELETE WHERE``) would scan every version the store still holds as a tombstone, which grows with
    every change until compaction; an exact delete costs the same all day.
    """

    held: Held
    remove: list[tuple[str, str | None]] = field(default_factory=list)
    delete: list[Triple] = field(default_factory=list)
    add: list[Triple] = field(default_factory=list)
    written: dict[str, dict[str, Object | None]] = field(default_factory=dict)
    cleared: set[str] = field(default_factory=set)

    def _current(self, subject: str, predicate: str) -> Object | bool | None:
        """The object held now, None if there is none, False if unknown (a pattern must remove it)."""
        mine = self.written.get(subject)
        if mine is not None and (predicate in mine or subject in self.cleared):
            return mine.get(predicate)
        held = self.held.get(subject)
        if held is not None and predicate in held:
            return held[predicate]
        return False

    def set(self, subject: str, predicate: str, obj: Object | None) -> None:
        """Make ``obj`` the one object of ``(subject, predicate)`` (None: remove it)."""
        current = self._current(subject, predicate)
        if current == obj:
            return
        if current is False:
            self.remove.append((subject, predicate))
        elif current is not None and not isinstance(current, bool):
            self.delete.append(Triple(subject, predicate, current))
        if obj is not None:
            self.add.append(Triple(subject, predicate, obj))
        self.written.setdefault(subject, {})[predicate] = obj

    def clear(self, subject: str) -> None:
        """Remove every triple of ``subject``."""
        self.remove.append((subject, None))
        self.written[subject] = {}
        self.cleared.add(subject)

    def changed(self) -> tuple[int, int, int]:
        return (len(self.remove), len(self.delete), len(self.add))


def _create(
    r: ElementReport, site: SiteFrame, robot: str, rights: frozenset[Right], w: _Writer
) -> ElementState:
    if r.ifc_class is None:
        raise _fail(f"Element <{r.iri}> is new: give its twin:ifcClass.")
    chain = supertypes(site.schema, r.ifc_class)
    if chain is None:
        raise _fail(f"Element <{r.iri}>: {r.ifc_class!r} is not an IFC element class.")
    if r.box is None and r.geometry is None:
        raise _fail(f"Element <{r.iri}> is new: give its twin:box or omg:hasGeometry.")
    is_static = any(t in site.static_types for t in chain)
    _need(rights, "create", robot, f"create <{r.iri}>")
    if is_static:
        _need(rights, "static", robot, f"create the static {chain[0]} <{r.iri}>")
    classes = {vocab.BOT_ELEMENT}
    w.add += [
        Triple(r.iri, vocab.RDF_TYPE, vocab.BOT_ELEMENT),
        Triple(r.iri, vocab.TWIN_IFC_CLASS, _lit(chain[0])),
        Triple(r.iri, vocab.TWIN_IS_STATIC, _bool(is_static)),
        *(Triple(r.iri, vocab.TWIN_IFC_TYPE, _lit(t)) for t in chain),
    ]
    semantic = vocab.semantic_class(chain[0])
    if semantic is not None:
        w.add.append(Triple(r.iri, vocab.RDF_TYPE, semantic))
        classes.add(semantic)
    return ElementState(r.iri, chain[0], chain, is_static, classes=frozenset(classes))


def plan_observation(
    reports: Sequence[ElementReport],
    *,
    robot: str,
    rights: frozenset[Right],
    site: SiteFrame,
    states: Mapping[str, ElementState],
    shapes: Mapping[str, Shape | None],
    held: Held,
    revision: int,
    stamp_ns: int,
) -> ObservationPlan:
    """Check ``reports`` against the twin and plan the transaction; ObservationError names a problem.

    Args:
        reports: the parsed observation.
        robot: who observed it (provenance; rights).
        rights: what this robot may change.
        site: the storeys, schema and extent.
        states: every element's current state.
        shapes: the current mesh and placement of each reported element that has geometry.
        held: the single-valued triples written before (exact deletes instead of patterns).
        revision: the twin revision this change will be (if it changes anything).
        stamp_ns: when the observation was received.
    """
    w = _Writer(held)
    geometry: list[GeometryChange] = []
    new_states: dict[str, ElementState] = {}
    upserted, removed = [], []
    for r in reports:
        state = states.get(r.iri)
        exists = state is not None and not state.removed
        current = shapes.get(r.iri)
        before = w.changed()
        if r.removed:
            if not exists or state is None:
                raise _fail(f"Element <{r.iri}> cannot be removed: the twin has no such element.")
            _need(rights, "static" if state.is_static else "dynamic", robot, f"remove <{r.iri}>")
            g = vocab.geometry_iri(r.iri)
            w.set(r.iri, vocab.OMG_HAS_GEOMETRY, None)
            w.clear(g)
            w.set(r.iri, vocab.TWIN_REMOVED, _bool(True))
            if current is not None:
                geometry.append(GeometryChange(r.iri, None))
            state = replace(state, removed=True)
            removed.append(r.iri)
        else:
            if state is None or not exists:
                if state is not None:  # re-created after its removal: start from a clean node
                    w.clear(r.iri)
                state = _create(r, site, robot, rights, w)
                current = None
            elif r.ifc_class is not None and r.ifc_class.lower() != state.ifc_class.lower():
                raise _fail(
                    f"Element <{r.iri}> is an {state.ifc_class}: an observation cannot make it {r.ifc_class}."
                )
            change: Right = "static" if state.is_static else "dynamic"
            if r.is_open is not None:
                if not state.is_door:
                    raise _fail(
                        f"Element <{r.iri}> is an {state.ifc_class}, not a door: it cannot be opened."
                    )
                if r.is_open != state.is_open:
                    _need(rights, "doors", robot, f"open or close <{r.iri}>")
                    w.set(r.iri, vocab.TWIN_IS_OPEN, _bool(r.is_open))
                    state = replace(state, is_open=r.is_open)
            if r.keepout is not None and r.keepout != state.keepout:
                what = "mark <{}> as a keepout zone" if r.keepout else "lift the keepout zone <{}>"
                _need(rights, "zones", robot, what.format(r.iri))
                w.set(r.iri, vocab.TWIN_KEEPOUT, _bool(r.keepout) if r.keepout else None)
                state = replace(state, keepout=r.keepout)
            if r.speed_limit is not None and r.speed_limit != state.speed_limit:
                _need(rights, "zones", robot, f"set the speed limit of <{r.iri}>")
                limit = _lit(str(r.speed_limit), vocab.XSD_INTEGER) if r.speed_limit else None
                w.set(r.iri, vocab.TWIN_SPEED_LIMIT, limit)
                state = replace(state, speed_limit=r.speed_limit)
            shape = _shape(r, site, current)
            if shape is not None:
                _check_inside(r.iri, shape, site)
                if current is None or not same_shape(shape, current):
                    if exists:
                        _need(rights, change, robot, f"change <{r.iri}>")
                    g = vocab.geometry_iri(r.iri)
                    if current is not None and shape[0] is current[0]:  # a move: the placement only
                        w.set(g, vocab.TWIN_PLACEMENT, _lit(encode_placement(shape[1]), vocab.TWIN_MATRIX4))
                    else:
                        w.clear(g)
                        for t in _geometry_triples(r.iri, *shape):
                            w.set(t.subject, t.predicate, t.object)
                    geometry.append(GeometryChange(r.iri, shape))
            if r.storey is not None:
                storey = site.storeys.get(r.storey)
                if storey is None:
                    known = ", ".join(sorted(site.storeys)) or "none"
                    raise _fail(f"Element <{r.iri}>: unknown storey {r.storey!r}; storeys: {known}.")
                if state.storey != r.storey or not exists:
                    if exists:
                        _need(rights, change, robot, f"change <{r.iri}>")
                    old = site.storeys.get(state.storey or "")
                    if old is not None and exists:
                        w.delete.append(Triple(old.iri, vocab.BOT_CONTAINS_ELEMENT, r.iri))
                    w.add.append(Triple(storey.iri, vocab.BOT_CONTAINS_ELEMENT, r.iri))
                    state = replace(state, storey=r.storey)
            labels = [v for v in r.labels if v not in state.labels]
            materials = [
                v for v in r.materials if v not in state.materials or v not in state.facing_materials
            ]
            classes = [v for v in r.classes if v not in state.classes]
            if (labels or materials or classes) and exists:
                _need(rights, change, robot, f"change <{r.iri}>")
            w.add += [Triple(r.iri, vocab.RDFS_LABEL, _lit(v)) for v in labels]
            # What a robot reports is what its sensors face: each material is a facing one too.
            w.add += [
                Triple(r.iri, p, _lit(m))
                for m in materials
                for p in (vocab.TWIN_MATERIAL, vocab.TWIN_FACING_MATERIAL)
            ]
            w.add += [Triple(r.iri, vocab.RDF_TYPE, c) for c in classes]
            if labels or materials or classes:
                state = replace(
                    state,
                    name=r.labels[0] if r.labels else state.name,
                    labels=state.labels | set(labels),
                    materials=state.materials | set(materials),
                    facing_materials=state.facing_materials | set(materials),
                    classes=state.classes | set(classes),
                )
            state = replace(state, removed=False)
        if w.changed() == before:
            continue  # this element is as the twin holds it
        when = datetime.datetime.fromtimestamp(stamp_ns / 1e9, tz=datetime.UTC).isoformat()
        w.set(r.iri, vocab.TWIN_OBSERVED_BY, _lit(robot))
        w.set(r.iri, vocab.TWIN_OBSERVED_AT, _lit(when, vocab.XSD_DATETIME))
        w.set(r.iri, vocab.TWIN_REVISION, _lit(str(revision), vocab.XSD_INTEGER))
        new_states[r.iri] = state
        if not r.removed:
            upserted.append(r.iri)
    if not new_states:
        return ObservationPlan(ChangeSet(), ())
    w.set(site.model_iri, vocab.TWIN_REVISION, _lit(str(revision), vocab.XSD_INTEGER))
    return ObservationPlan(
        changes=ChangeSet(remove=tuple(w.remove), add=tuple(w.add), delete=tuple(w.delete)),
        geometry=tuple(geometry),
        states=new_states,
        upserted=tuple(upserted),
        removed=tuple(removed),
        written=w.written,
        cleared=frozenset(w.cleared),
    )
