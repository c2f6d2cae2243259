"""Plan an observation: check it against the twin, and write only what it changes.

:func:`plan_observation` decides everything before anything changes: whether each element exists,
whether the robot may change it (its rights: ``create`` new dynamic elements, change ``dynamic``
ones, open and close ``doors``, change ``static`` structure), that its storey exists and its geometry
lies within the site. It returns the :class:`~twin.graph.store.ChangeSet` and the geometry changes for the
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
import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from twin.config import Right
from twin.errors import ObservationError
from twin.graph import vocab
from twin.graph.ifc_classes import supertypes
from twin.graph.meshcodec import encode_placement
from twin.graph.rdf import ChangeSet, Object, Triple
from twin.live.same import quantised, quantised_box_values, quantised_sizes, same_mesh, same_shape
from twin.live.state import ElementState, SiteFrame
from twin.live.writes import Held, TripleWriter, boolean, geometry_triples, literal
from twin.maps.shapes import box_mesh, box_placement
from twin.records import ElementReport, GeometryChange, Mesh, Shape
from twin.tolerances import TOLERANCES


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


def _iso(ns: int) -> str:
    """An ``xsd:dateTime`` to the nanosecond, UTC."""
    seconds, nanos = divmod(ns, 1_000_000_000)
    return f"{_second(seconds)}.{nanos:09d}Z"


@functools.lru_cache(maxsize=64)
def _second(seconds: int) -> str:
    """``YYYY-MM-DDTHH:MM:SS`` of a second, UTC (robots report many times a second: made once each)."""
    return datetime.datetime.fromtimestamp(seconds, tz=datetime.UTC).strftime("%Y-%m-%dT%H:%M:%S")


def _observed_at(stamp_ns: int) -> str:
    """``datetime.fromtimestamp(stamp_ns / 1e9, tz=UTC).isoformat()``, the same text, with the second's
    part made once per second: microseconds from the float's fraction rounded half to even, as
    ``fromtimestamp`` rounds them (a fraction that rounds up to a whole second carries into it)."""
    fraction, whole = math.modf(stamp_ns / 1e9)
    micros = round(fraction * 1e6)
    seconds = int(whole)
    if micros >= 1_000_000:
        micros -= 1_000_000
        seconds += 1
    elif micros < 0:  # before 1970
        return datetime.datetime.fromtimestamp(stamp_ns / 1e9, tz=datetime.UTC).isoformat()
    return f"{_second(seconds)}.{micros:06d}+00:00" if micros else f"{_second(seconds)}+00:00"


def _fail(message: str) -> ObservationError:
    return ObservationError(message)


def _need(rights: frozenset[Right], right: Right, robot: str, what: str) -> None:
    if right not in rights:
        raise _fail(f"Robot {robot!r} may not {what} (it lacks the {right!r} right).")


def _shape(report: ElementReport, site: SiteFrame, current: Shape | None) -> tuple[Shape | None, str | None]:
    """The element's reported mesh and placement, None when the report leaves the geometry alone; and
    for a box, its placement's literal text (made with the placement, in Python floats)."""
    if report.box is not None:
        b = report.box
        storey = site.storeys.get(report.storey or "")
        if storey is None:
            known = ", ".join(sorted(site.storeys)) or "none"
            raise _fail(f"Element <{report.iri}>: unknown storey {report.storey!r}; storeys: {known}.")
        mesh = _box_mesh(*quantised_sizes(b.sx, b.sy, b.sz))
        if current is not None and same_mesh(mesh, current[0]):
            mesh = current[0]  # a moved box keeps its mesh: one object, one literal
        cz = storey.elevation_m + b.cz
        values = quantised_box_values(b.cx, b.cy, cz, b.yaw)
        if values is None:  # not finite, or far out: the array path (the extent check refuses it)
            return (mesh, quantised(box_placement(b.cx, b.cy, cz, yaw=b.yaw))), None
        return (mesh, np.array(values).reshape(4, 4)), " ".join(map(repr, values))
    if report.geometry is not None:
        return (report.geometry.mesh, report.geometry.placement), None
    if report.placement is not None:
        if current is None:
            raise _fail(f"Element <{report.iri}>: twin:placement moves an element, but it has no geometry.")
        return (current[0], report.placement), None
    return None, None


@functools.lru_cache(maxsize=256)
def _box_mesh(sx: float, sy: float, sz: float) -> Mesh:
    """The box mesh of these sizes, one object per sizes (a record, never changed): a box reported
    again at its sizes is its mesh at once (``same_mesh`` by identity)."""
    return box_mesh(sx, sy, sz)


def _check_inside(iri: str, shape: Shape, site: SiteFrame) -> None:
    mesh, placement = shape
    world = mesh.vertices @ placement[:3, :3].T + placement[:3, 3]
    lo, hi = world.min(axis=0).tolist(), world.max(axis=0).tolist()
    b = site.site_box
    below = any(v < m for v, m in zip(lo, b[:3], strict=True))
    if below or any(v > m for v, m in zip(hi, b[3:], strict=True)):
        box = ", ".join(f"{v:.2f}" for v in (*lo, *hi))
        extent = ", ".join(f"{v:.2f}" for v in b)
        raise _fail(f"Element <{iri}>: its geometry ({box}) lies outside the site's extent ({extent}).")


def _create(
    r: ElementReport, site: SiteFrame, robot: str, rights: frozenset[Right], w: TripleWriter
) -> ElementState:
    creating = any(v is not None for v in (r.ifc_class, r.storey, r.box, r.geometry))
    changing = any(v is not None for v in (r.is_open, r.placement, r.keepout, r.speed_limit))
    if changing and not creating:  # a change to an element that is not there
        raise _fail(
            f"No element <{r.iri}> in the twin: only an element it holds can be opened, closed, moved or "
            "marked (a new one needs twin:ifcClass, twin:storey and twin:box or omg:hasGeometry)."
        )
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
        Triple(r.iri, vocab.TWIN_IFC_CLASS, literal(chain[0])),
        Triple(r.iri, vocab.TWIN_IS_STATIC, boolean(is_static)),
        *(Triple(r.iri, vocab.TWIN_IFC_TYPE, literal(t)) for t in chain),
    ]
    semantic = vocab.semantic_class(chain[0])
    if semantic is not None:
        w.add.append(Triple(r.iri, vocab.RDF_TYPE, semantic))
        classes.add(semantic)
    return ElementState(r.iri, chain[0], chain, is_static, classes=frozenset(classes))


@dataclass(slots=True)
class _Step:
    """One report being planned: what it says, who says it, and the twin as the plan left it."""

    r: ElementReport
    robot: str
    rights: frozenset[Right]
    site: SiteFrame
    w: TripleWriter
    geometry: list[GeometryChange]
    state: ElementState | None
    current: Shape | None

    @property
    def exists(self) -> bool:
        return self.state is not None and not self.state.removed


def _remove(step: _Step, *, reason: str | None, merged_into: str | None) -> ElementState:
    """``twin:removed true``: the element becomes a tombstone (no geometry; why, if fusion says)."""
    r, w, state = step.r, step.w, step.state
    if not step.exists or state is None:
        raise _fail(f"Element <{r.iri}> cannot be removed: the twin has no such element.")
    _need(step.rights, state.change_right, step.robot, f"remove <{r.iri}>")
    w.set(r.iri, vocab.OMG_HAS_GEOMETRY, None)
    w.clear(vocab.geometry_iri(r.iri))
    w.set(r.iri, vocab.TWIN_REMOVED, boolean(True))
    if step.current is not None:
        step.geometry.append(GeometryChange(r.iri, None))
    if reason is not None:
        w.set(r.iri, vocab.TWIN_REMOVED_BECAUSE, literal(reason))
    if merged_into is not None:
        w.set(r.iri, vocab.TWIN_MERGED_INTO, merged_into)
    return replace(state, removed=True)


def _upsert(step: _Step) -> ElementState:
    """Create the element or check its class, then its door state, zone marks, geometry, storey and
    descriptive values, in that order."""
    r, state = step.r, step.state
    exists = step.exists
    if r.unmerge:
        _need(step.rights, "merges", step.robot, f"undo the merge of <{r.iri}>")
        if state is not None and not state.removed:
            raise _fail(f"Element <{r.iri}> is an element of its own: there is no merge to undo.")
    if state is None or not exists:
        if state is not None:  # re-created after its removal: start from a clean node
            step.w.clear(r.iri)
        state = _create(r, step.site, step.robot, step.rights, step.w)
        if r.distinct or r.unmerge:
            step.w.add.append(Triple(r.iri, vocab.TWIN_DISTINCT, boolean(True)))
        step.current = None
    elif r.ifc_class is not None and r.ifc_class.lower() != state.ifc_class.lower():
        raise _fail(
            f"Element <{r.iri}> is an {state.ifc_class}: an observation cannot make it {r.ifc_class}."
        )
    change = state.change_right
    state = _door(step, state)
    state = _zones(step, state)
    _geometry(step, change, exists=exists)
    state = _storey(step, state, change, exists=exists)
    _lifetime(step, change, exists=exists)
    state = _descriptive(step, state, change, exists=exists)
    return replace(state, removed=False) if state.removed else state


def _door(step: _Step, state: ElementState) -> ElementState:
    r = step.r
    if r.is_open is None:
        return state
    if not state.is_door:
        raise _fail(f"Element <{r.iri}> is an {state.ifc_class}, not a door: it cannot be opened.")
    if r.is_open != state.is_open:
        _need(step.rights, "doors", step.robot, f"open or close <{r.iri}>")
        step.w.set(r.iri, vocab.TWIN_IS_OPEN, boolean(r.is_open))
        state = replace(state, is_open=r.is_open)
    return state


def _zones(step: _Step, state: ElementState) -> ElementState:
    r, w = step.r, step.w
    if r.keepout is not None and r.keepout != state.keepout:
        what = "mark <{}> as a keepout zone" if r.keepout else "lift the keepout zone <{}>"
        _need(step.rights, "zones", step.robot, what.format(r.iri))
        w.set(r.iri, vocab.TWIN_KEEPOUT, boolean(r.keepout) if r.keepout else None)
        state = replace(state, keepout=r.keepout)
    if r.speed_limit is not None and r.speed_limit != state.speed_limit:
        _need(step.rights, "zones", step.robot, f"set the speed limit of <{r.iri}>")
        limit = literal(str(r.speed_limit), vocab.XSD_INTEGER) if r.speed_limit else None
        w.set(r.iri, vocab.TWIN_SPEED_LIMIT, limit)
        state = replace(state, speed_limit=r.speed_limit)
    return state


def _geometry(step: _Step, change: Right, *, exists: bool) -> None:
    """The reported shape, written only when it differs (a move: the placement alone)."""
    r, w, current = step.r, step.w, step.current
    shape, text = _shape(r, step.site, current)
    if shape is None:
        return
    if text is None or not _box_inside(shape, step.site):
        _check_inside(r.iri, shape, step.site)
    moved = current is None or (text is not None and _box_moved(shape, current))
    if not moved and current is not None and same_shape(shape, current):
        return
    if exists:
        _need(step.rights, change, step.robot, f"change <{r.iri}>")
    g = vocab.geometry_iri(r.iri)
    if current is not None and shape[0] is current[0]:  # a move: the placement only
        placement = encode_placement(shape[1]) if text is None else text
        w.set(g, vocab.TWIN_PLACEMENT, literal(placement, vocab.TWIN_MATRIX4))
    else:
        w.clear(g)
        for t in geometry_triples(r.iri, *shape):
            w.set(t.subject, t.predicate, t.object)
    step.geometry.append(GeometryChange(r.iri, shape))


_MARGIN_M = 1e-6
"""How far from a limit the Python-float checks of a box decide alone: their world coordinates differ
from the array path's by rounding (about 1e-12 m in a building); nearer, the array path decides."""


def _box_inside(shape: Shape, site: SiteFrame) -> bool:
    """A box (a centred mesh of corners ±h, an upright placement) lies inside the site by more than
    :data:`_MARGIN_M`: its world extent is the centre ± |R| h. False: let :func:`_check_inside` say."""
    mesh, placement = shape
    corner: list[float] = mesh.vertices[7].tolist()  # the (+, +, +) corner: half the sizes
    rows: list[list[float]] = placement.tolist()
    hx, hy, hz = corner
    (r00, r01, _, tx), (r10, r11, _, ty), (_, _, _, tz), _ = rows
    ex, ey = abs(r00) * hx + abs(r01) * hy, abs(r10) * hx + abs(r11) * hy
    lo_x, lo_y, lo_z, hi_x, hi_y, hi_z = site.site_box
    m = _MARGIN_M
    return (
        tx - ex > lo_x + m
        and ty - ey > lo_y + m
        and tz - hz > lo_z + m
        and tx + ex < hi_x - m
        and ty + ey < hi_y - m
        and tz + hz < hi_z - m
    )


def _box_moved(shape: Shape, current: Shape) -> bool:
    """A box (centred: each corner's opposite is a corner) at the held mesh whose centre moved by more
    than ``same_position_m`` (and :data:`_MARGIN_M`) along an axis: not the same shape, whatever the
    turn (of a corner and its opposite, one moves by at least the centre's move). False: let
    :func:`~twin.live.same.same_shape` say."""
    if shape[0] is not current[0]:
        return False
    a, b = shape[1], current[1]
    limit = TOLERANCES.same_position_m + _MARGIN_M
    return (
        abs(float(a[0, 3]) - float(b[0, 3])) > limit
        or abs(float(a[1, 3]) - float(b[1, 3])) > limit
        or abs(float(a[2, 3]) - float(b[2, 3])) > limit
    )


def _storey(step: _Step, state: ElementState, change: Right, *, exists: bool) -> ElementState:
    r, site, w = step.r, step.site, step.w
    if r.storey is None:
        return state
    storey = site.storeys.get(r.storey)
    if storey is None:
        known = ", ".join(sorted(site.storeys)) or "none"
        raise _fail(f"Element <{r.iri}>: unknown storey {r.storey!r}; storeys: {known}.")
    if state.storey == r.storey and exists:
        return state
    if exists:
        _need(step.rights, change, step.robot, f"change <{r.iri}>")
    old = site.storeys.get(state.storey or "")
    if old is not None and exists:
        w.delete.append(Triple(old.iri, vocab.BOT_CONTAINS_ELEMENT, r.iri))
    w.add.append(Triple(storey.iri, vocab.BOT_CONTAINS_ELEMENT, r.iri))
    return replace(state, storey=r.storey)


def _lifetime(step: _Step, change: Right, *, exists: bool) -> None:
    """An RMF obstacle's lifetime (``twin:lifetime``, single-valued): written only when it differs."""
    r, w = step.r, step.w
    if r.lifetime_s is None:
        return
    lifetime = literal(f"{r.lifetime_s:.9f}".rstrip("0").rstrip("."), vocab.XSD_DECIMAL)
    mark = w.changed()
    w.set(r.iri, vocab.TWIN_LIFETIME, lifetime)
    if exists and w.changed() != mark:
        _need(step.rights, change, step.robot, f"change <{r.iri}>")


def _descriptive(step: _Step, state: ElementState, change: Right, *, exists: bool) -> ElementState:
    """Labels, materials (each a facing one too: what a robot reports is what its sensors face) and
    descriptive types (``a furn:Table``) not yet held."""
    r, w = step.r, step.w
    labels = [v for v in r.labels if v not in state.labels]
    materials = [v for v in r.materials if v not in state.materials or v not in state.facing_materials]
    classes = [v for v in r.classes if v not in state.classes]
    if not (labels or materials or classes):
        return state
    if exists:
        _need(step.rights, change, step.robot, f"change <{r.iri}>")
    w.add += [Triple(r.iri, vocab.RDFS_LABEL, literal(v)) for v in labels]
    w.add += [
        Triple(r.iri, p, literal(m))
        for m in materials
        for p in (vocab.TWIN_MATERIAL, vocab.TWIN_FACING_MATERIAL)
    ]
    w.add += [Triple(r.iri, vocab.RDF_TYPE, c) for c in classes]
    return replace(
        state,
        name=min(state.labels | set(labels)) if labels else state.name,  # as loading names it
        labels=state.labels | set(labels),
        materials=state.materials | set(materials),
        facing_materials=state.facing_materials | set(materials),
        classes=state.classes | set(classes),
    )


def _provenance(
    step: _Step, state: ElementState, *, revision: int, stamp_ns: int, sensed: int
) -> ElementState:
    """Who changed the element, when it arrived, at which revision, and when it was seen."""
    r, w = step.r, step.w
    when = _observed_at(stamp_ns)
    w.set(r.iri, vocab.TWIN_OBSERVED_BY, literal(step.robot))
    w.set(r.iri, vocab.TWIN_OBSERVED_AT, literal(when, vocab.XSD_DATETIME))
    w.set(r.iri, vocab.TWIN_REVISION, literal(str(revision), vocab.XSD_INTEGER))
    w.set(r.iri, vocab.TWIN_SENSE_TIME, literal(_iso(sensed), vocab.XSD_DATETIME))
    return replace(state, sensed_ns=sensed)


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
    sense_ns: Mapping[str, int] | None = None,
    reasons: Mapping[str, str] | None = None,
    merged: Mapping[str, str] | None = None,
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
        sense_ns: when each element's change was seen (``twin:senseTime``; default ``stamp_ns``).
        reasons: why fusion removes an element (``twin:removedBecause``: absence, a merge).
        merged: elements fusion merged into another (``twin:mergedInto``).
    """
    if not reports:  # fusion confirmed everything: nothing to check or write
        return ObservationPlan(ChangeSet(), ())
    sense_ns = sense_ns or {}
    reasons = reasons or {}
    merged = merged or {}
    w = TripleWriter(held)
    geometry: list[GeometryChange] = []
    new_states: dict[str, ElementState] = {}
    upserted, removed = [], []
    for r in reports:
        step = _Step(r, robot, rights, site, w, geometry, states.get(r.iri), shapes.get(r.iri))
        before = w.changed()
        if r.removed:
            state = _remove(step, reason=reasons.get(r.iri), merged_into=merged.get(r.iri))
            removed.append(r.iri)
        else:
            state = _upsert(step)
        if w.changed() == before:
            continue  # this element is as the twin holds it
        state = _provenance(
            step, state, revision=revision, stamp_ns=stamp_ns, sensed=sense_ns.get(r.iri, stamp_ns)
        )
        new_states[r.iri] = state
        if not r.removed:
            upserted.append(r.iri)
    if not new_states:
        return ObservationPlan(ChangeSet(), ())
    w.set(site.model_iri, vocab.TWIN_REVISION, literal(str(revision), vocab.XSD_INTEGER))
    return ObservationPlan(
        changes=ChangeSet(remove=tuple(w.remove), add=tuple(w.add), delete=tuple(w.delete)),
        geometry=tuple(geometry),
        states=new_states,
        upserted=tuple(upserted),
        removed=tuple(removed),
        written=w.written,
        cleared=frozenset(w.cleared),
    )
