"""A fleet's route graph from the twin: its navigation skill's maps, doors, spaces and lifts.

For each storey the fleet serves, the free cells are those of its navigation skill's map (inflated by
the robot's radius, the robot's height band) drawn with every door open and every lift car left out
(``IfcDoor`` and ``IfcTransportElement`` elements are not drawn), less the cells of its keepout
skills' zones. :func:`twin.routes.storey.build_storey` makes each storey's graph from them; lifts join
the storeys: a vertex at the cabin's centre on every storey the lift serves, at the same x, y.

Doors are the ``IfcDoor`` elements (subtypes included) with geometry; lifts the
``IfcTransportElement`` elements with geometry whose predefined type is one of the skill's
``lift_types`` (``ELEVATOR`` by default: an escalator or a crane is an obstacle, not a lift). A lift
serves the storeys whose floor lies within its geometry's height, with at least a storey's robot
height above. A door's ``OperationType`` says which end is its hinge (or where it slides to) and
which way it swings, read in its placement's frame (IFC: hinged on the left or right as seen along
the door's local +y, opening towards +y).

Example::

    graph = build_routes(store, scene, cfg.routes["cleaners"], cfg.skills, margin_m=cfg.margin_m)
"""

from __future__ import annotations

import logging
import re
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage
from scipy.spatial import ConvexHull, QhullError

from twin.config.routes import RouteProfile, Waypoint, check_routes
from twin.errors import RouteError
from twin.graph.rdf import literal_value
from twin.graph.store import GraphStore
from twin.maps.grid import GridFrame
from twin.maps.render import MapPlan, build_map, occupancy, plan_map
from twin.maps.scene import Scene, StoreyInfo
from twin.records import to_world
from twin.routes.graph import DoorCrossing, Lift, RouteGraph, RouteVertex, StoreyRoutes
from twin.routes.one_way import apply_one_way
from twin.routes.storey import DoorShape, SpaceArea, StoreyInput, build_storey
from twin.selection.skill_selection import selection_query
from twin.selection.skills import SkillProfile

log = logging.getLogger(__name__)

DOOR_TYPES = ("IfcDoor",)
LIFT_TYPES = ("IfcTransportElement",)
_UNSAFE = re.compile(r"[^A-Za-z0-9_]+")

_ELEMENTS = """SELECT ?e ?name ?gid ?predefined ?operation WHERE {{
  ?e twin:ifcType "{ifc_type}" ; omg:hasGeometry ?g .
  OPTIONAL {{ ?e rdfs:label ?name }}
  OPTIONAL {{ ?e props:globalIdIfcRoot_attribute_simple ?gid }}
  OPTIONAL {{ ?e twin:predefinedType ?predefined }}
  OPTIONAL {{ ?e twin:operationType ?operation }}
  FILTER NOT EXISTS {{ ?e twin:removed true }}
}} ORDER BY ?e"""
_SPACES = "SELECT ?sp ?name WHERE { ?sp a bot:Space . OPTIONAL { ?sp rdfs:label ?name } } ORDER BY ?sp"
_BUILDING = "SELECT ?name WHERE { ?b a bot:Building . OPTIONAL { ?b rdfs:label ?name } } ORDER BY ?b LIMIT 1"


@dataclass(frozen=True, slots=True)
class _Named:
    iri: str
    name: str
    predefined: str = ""
    operation: str = ""


def sanitise(text: str) -> str:
    """A name RMF and nav2 take as is: letters, digits and ``_`` (runs of anything else become one
    ``_``), never empty."""
    return _UNSAFE.sub("_", text).strip("_") or "unnamed"


def unique(name: str, taken: set[str]) -> str:
    """``name``, or ``name_2``, ``name_3``, ... whichever is not in ``taken`` (which it joins)."""
    out, k = name, 2
    while out in taken:
        out, k = f"{name}_{k}", k + 1
    taken.add(out)
    return out


def build_routes(
    store: GraphStore,
    scene: Scene,
    routes: RouteProfile,
    skills: Mapping[str, SkillProfile],
    *,
    margin_m: float = 1.0,
    door_names: Mapping[str, str] | None = None,
    level_names: Mapping[str, str] | None = None,
) -> RouteGraph:
    """The fleet's route graph of the building.

    Args:
        door_names: door IRI -> the name its lanes carry (the RMF door names of the configured door
            tables); other doors are named after their IFC name (sanitised, unique).
        level_names: storey key -> RMF level name (the prefix of space and lift vertex names);
            default: the storey key.

    Raises:
        RouteError: a missing navigation or keepout skill, an unknown storey, a robot wider than every
            door, a storey named in ``storeys`` (or the model's only one) with no free space, a
            waypoint off the served storeys. Without ``storeys``, a storey with no free space (a
            roof) is left out with a note.
    """
    ctx = prepare_routes(store, scene, routes, skills, margin_m=margin_m, door_names=door_names)
    nav, radius, door_shapes = ctx.nav, ctx.nav.inflation_radius_m, ctx.door_shapes
    levels = dict(level_names or {})
    storeys = ctx.storeys
    lift_records = _lifts(scene, ctx.lifts, storeys, nav)
    space_names = {
        literal_value(r["sp"]) or "": literal_value(r["name"]) or "" for r in store.select(_SPACES)
    }
    taken: set[str] = {w.name for w in routes.waypoints}
    results: list[StoreyRoutes] = []
    crossings: list[DoorCrossing] = []
    notes: list[str] = []
    storeys = list(storeys)
    frees: list[tuple[MapPlan, np.ndarray]] = []
    refused: list[RouteError] = []
    for storey in list(storeys):
        try:
            frees.append(routable_cells(ctx, storey.key))
        except RouteError as err:
            if routes.storeys:  # asked for by name: an error
                raise
            refused.append(err)
            notes.append(f"{storey.key}: not served, no free space for this robot")
            storeys.remove(storey)
    if not storeys:  # no storey at all: the first one's error
        raise refused[0]
    if door_shapes and 2 * radius > max(d.width_m for _, d in door_shapes) + 1e-6:
        widest = max(d.width_m for _, d in door_shapes)
        msg = (
            f"Routes skill {routes.name!r}: a robot of radius {radius} m (navigation skill "
            f"{nav.name!r}) fits through none of the model's {len(door_shapes)} doors (the widest is "
            f"{widest:.2f} m)."
        )
        raise RouteError(msg)
    for storey, (plan, free) in zip(storeys, frees, strict=True):
        level = levels.get(storey.key, storey.key)
        on_storey = [d for st, d in door_shapes if _on(scene, st, plan) and _sill_on(scene, st, plan)]
        spaces = _space_areas(scene, plan, space_names, level, taken)
        points = [
            RouteVertex(
                lift.x,
                lift.y,
                name=unique(f"{sanitise(level)}_{lift.name}", taken),
                kind="lift",
                lift=lift.name,
            )
            for lift in lift_records
            if storey.key in lift.storeys
        ]
        points += _waypoints(scene, routes, storey=storey, plan=plan, free=free, space_names=space_names)
        result = build_storey(
            StoreyInput(
                storey=storey.key,
                elevation_m=storey.elevation_m,
                frame=plan.frame,
                free=free,
                doors=on_storey,
                spaces=spaces,
                points=points,
                max_lane_m=routes.max_lane_m,
                spacing_m=routes.spacing_m,
                door_reach_m=door_reach(radius),
                small_region_m2=routes.small_region_m2,
                pocket_m2=routes.pocket_m2,
            )
        )
        results.append(result.routes)
        notes += result.notes
        crossings += [
            DoorCrossing(
                d.name,
                d.iri,
                storey.key,
                d.endpoints,
                d.width_m,
                d.name in result.passable,
                operation=d.operation,
                swing=d.swing,
            )
            for d in on_storey
        ]
    served = {st.key for st in storeys}
    for stretch in routes.one_way:
        if stretch.storey is not None and stretch.storey not in served:
            msg = (
                f"Routes skill {routes.name!r}: one_way storey {stretch.storey!r} is not served; "
                f"served: {', '.join(sorted(served))}."
            )
            raise RouteError(msg)
    directed, one_way_notes = apply_one_way(results, routes.one_way)
    notes += one_way_notes
    rows = store.select(_BUILDING)
    building = (literal_value(rows[0]["name"]) if rows else None) or "building"
    for note in notes:
        log.info("Routes %s: %s", routes.name, note)
    return RouteGraph(
        skill=routes.name,
        fleet=routes.fleet,
        graph_name=routes.graph_name,
        building=building,
        speed_m_s=routes.speed_m_s,
        robot_radius_m=radius,
        storeys=directed,
        doors=tuple(crossings),
        lifts=tuple(lift_records),
        notes=tuple(notes),
    )


@dataclass(frozen=True, slots=True)
class RouteContext:
    """What every storey of a routes skill's graph is made from (see :func:`prepare_routes`)."""

    store: GraphStore
    scene: Scene
    routes: RouteProfile
    nav: SkillProfile
    margin_m: float
    storeys: list[StoreyInfo]
    iris: list[str]
    """The navigation skill's elements but doors and lifts."""
    keepouts: list[tuple[SkillProfile, list[str]]]
    door_shapes: list[tuple[int, DoorShape]]
    lifts: list[_Named]
    slabs: np.ndarray
    """Element indices of the slabs (floors) of the model."""


def door_reach(radius_m: float) -> float:
    """How far from a door's leaf its side vertices lie (the robot's radius + 0.25 m, at least 0.5 m)."""
    return max(radius_m, 0.25) + 0.25


def prepare_routes(
    store: GraphStore,
    scene: Scene,
    routes: RouteProfile,
    skills: Mapping[str, SkillProfile],
    *,
    margin_m: float = 1.0,
    door_names: Mapping[str, str] | None = None,
) -> RouteContext:
    """Check the routes skill against the skills and the model, and gather its elements."""
    check_routes(routes, skills)
    nav = skills[routes.navigation]
    storeys = _served(scene, routes)
    doors = _elements(store, DOOR_TYPES[0])
    lifts = [
        t for t in _elements(store, LIFT_TYPES[0]) if (t.predefined or "NOTDEFINED") in routes.lift_types
    ]
    exempt = {d.iri for d in doors} | {lift.iri for lift in lifts}
    iris = [
        i
        for r in store.select(selection_query(nav))
        if (i := literal_value(r["element"]) or "") not in exempt
    ]
    keepouts = []
    for k in routes.keepout:
        keepout = replace(skills[k], resolution_m=nav.resolution_m)
        keepouts.append(
            (keepout, [literal_value(r["element"]) or "" for r in store.select(selection_query(keepout))])
        )
    slabs = scene.elements.indices_of([s.iri for s in _elements(store, "IfcSlab")])
    return RouteContext(
        store=store,
        scene=scene,
        routes=routes,
        nav=nav,
        margin_m=margin_m,
        storeys=storeys,
        iris=iris,
        keepouts=keepouts,
        door_shapes=_door_shapes(scene, doors, door_names or {}),
        lifts=lifts,
        slabs=slabs,
    )


def routable_cells(ctx: RouteContext, storey_key: str) -> tuple[MapPlan, np.ndarray]:
    """The plan of the storey's navigation map and the cells where the robot's centre may be: free in
    that map drawn with doors open and lift cars left out, outside the keepout zones and, unless the
    skill sets ``outdoors``, over the storey's floor (its slabs and spaces, and the ground about its
    doors)."""
    scene, nav = ctx.scene, ctx.nav
    plan = plan_map(scene, nav, storey_key, ctx.iris, margin_m=ctx.margin_m)
    free = build_map(scene, plan).data == 0
    for keepout, iris in ctx.keepouts:
        kplan = plan_map(scene, keepout, storey_key, iris, margin_m=ctx.margin_m)
        free &= build_map(scene, kplan).data == 0
    if not ctx.routes.outdoors:
        floor = _floor(ctx, plan)
        if floor is not None:
            free &= floor
    if not free.any():
        msg = (
            f"Routes skill {ctx.routes.name!r}: storey {storey_key!r} has no free space for its robot "
            f"(navigation skill {nav.name!r}: radius {nav.inflation_radius_m} m, height "
            f"{nav.robot_height_m} m)."
        )
        raise RouteError(msg)
    return plan, free


FLOOR_BAND_M = (-0.6, 0.05)
"""A slab is the storey's floor where it lies in this band about the storey's elevation (m)."""


def _floor(ctx: RouteContext, plan: MapPlan) -> np.ndarray | None:
    """The cells over the storey's floor: its slabs' and spaces' footprints (small gaps closed), and
    a disc about each of its doors (the ground outside an entrance); None: the storey has neither."""
    scene, frame = ctx.scene, plan.frame
    elev = plan.storey.elevation_m
    lo, hi = elev + FLOOR_BAND_M[0], elev + FLOOR_BAND_M[1]
    b = scene.elements.bounds[ctx.slabs] if len(ctx.slabs) else np.empty((0, 6))
    slabs = ctx.slabs[(b[:, 5] >= lo) & (b[:, 5] <= hi + 0.3)] if len(b) else ctx.slabs
    if not len(slabs) and not len(plan.spaces):
        return None
    floor = np.zeros(frame.shape, dtype=np.bool_)
    if len(slabs):
        floor |= occupancy(scene.elements, slabs, replace(plan, z_lo=lo, z_hi=hi), frame.full)
    if len(plan.spaces):
        floor |= occupancy(
            scene.spaces, plan.spaces, replace(plan, z_lo=elev + 0.1, z_hi=elev + 0.5), frame.full
        )
    if not floor.any():
        return None
    gap = max(1, round(0.25 / frame.resolution_m))
    floor = np.asarray(ndimage.binary_closing(floor, structure=np.ones((3, 3), dtype=bool), iterations=gap))
    res = frame.resolution_m
    reach = door_reach(ctx.nav.inflation_radius_m) + ctx.nav.inflation_radius_m
    for index, door in ctx.door_shapes:
        if not (_on(scene, index, plan) and _sill_on(scene, index, plan)):
            continue
        r = (door.width_m / 2 + reach) / res
        cx, cy = (door.x - frame.origin_x) / res - 0.5, (door.y - frame.origin_y) / res - 0.5
        window = frame.window_for(door.x - r * res, door.y - r * res, door.x + r * res, door.y + r * res)
        rows = np.arange(window.row0, window.row1)[:, None]
        cols = np.arange(window.col0, window.col1)[None, :]
        floor[window.row0 : window.row1, window.col0 : window.col1] |= (rows - cy) ** 2 + (
            cols - cx
        ) ** 2 <= r * r
    return floor


def _served(scene: Scene, routes: RouteProfile) -> list[StoreyInfo]:
    if not scene.storeys:
        msg = "The model has no storey (IfcBuildingStorey): route graphs are made per storey."
        raise RouteError(msg)
    if not routes.storeys:
        return list(scene.storeys)
    known = {s.key: s for s in scene.storeys}
    for key in routes.storeys:
        if key not in known:
            msg = (
                f"Routes skill {routes.name!r}: storey {key!r} is not a storey of this model; "
                f"storeys: {', '.join(known)}."
            )
            raise RouteError(msg)
    return [s for s in scene.storeys if s.key in routes.storeys]


def _elements(store: GraphStore, ifc_type: str) -> list[_Named]:
    out = []
    for r in store.select(_ELEMENTS.format(ifc_type=ifc_type)):
        iri = literal_value(r["e"]) or ""
        out.append(
            _Named(
                iri,
                literal_value(r["name"]) or literal_value(r["gid"]) or iri.rsplit("#", 1)[-1],
                literal_value(r["predefined"]) or "",
                literal_value(r["operation"]) or "",
            )
        )
    return out


def _door_shapes(scene: Scene, doors: list[_Named], names: Mapping[str, str]) -> list[tuple[int, DoorShape]]:
    """Each door with geometry: its element index and its shape in plan (centre, width direction,
    width and thickness from the principal axes of its vertices' x, y)."""
    out: list[tuple[int, DoorShape]] = []
    taken: set[str] = set()
    for door in doors:
        i = scene.elements.index.get(door.iri)
        if i is None:
            continue
        shape = scene.shapes.get(door.iri)
        if shape is not None:  # its vertices: a detailed door has far fewer than 3 per triangle
            xy = to_world(shape[0].vertices, shape[1])[:, :2]
        else:
            triangles, _ = scene.elements.triangles_of(np.array([i], dtype=np.intp))
            xy = triangles.reshape(-1, 3)[:, :2]
        if len(xy) < 3:
            continue
        u, _, along, across, mid = _min_rectangle(xy)
        name = unique(sanitise(names.get(door.iri, door.name)), taken)
        hinge_first, swing = _handedness(door.operation, u, None if shape is None else shape[1])
        out.append(
            (
                i,
                DoorShape(
                    name=name,
                    iri=door.iri,
                    x=float(mid[0]),
                    y=float(mid[1]),
                    ux=float(u[0]),
                    uy=float(u[1]),
                    width_m=float(along.max() - along.min()),
                    thickness_m=float(across.max() - across.min()),
                    operation=door.operation,
                    hinge_first=hinge_first,
                    swing=swing,
                ),
            )
        )
    return out


def _handedness(operation: str, u: np.ndarray, placement: np.ndarray | None) -> tuple[bool, int]:
    """``(hinge_first, swing)`` of a door of IFC ``operation`` whose width runs along ``u`` (see
    :class:`twin.routes.storey.DoorShape`): a left-hand door has its hinge (or slides) towards its
    local -x end, a right-hand one towards +x, and a swing from the hinge towards local +y is
    anticlockwise (-1) when the hinge is at -x; ``(True, 0)`` when the operation has no hand or the
    placement's x axis does not lie along the width."""
    left, right = operation.endswith("_LEFT"), operation.endswith("_RIGHT")
    if placement is None or not (left or right):
        return True, 0
    x_axis, y_axis = placement[:2, 0], placement[:2, 1]
    along = float(x_axis @ u) / max(float(np.hypot(*x_axis)), 1e-12)
    if abs(along) < 0.9:
        return True, 0
    # endpoints[0] lies at -u: it is the local -x end when u runs along +x
    hinge_first = (along > 0) == left
    # the leaf turns from the hinge's side towards local +y: from +x, anticlockwise seen from above
    # when the frame's x, y run anticlockwise (z up)
    up = 1 if float(x_axis[0] * y_axis[1] - x_axis[1] * y_axis[0]) >= 0 else -1
    swing = 0 if "SWING" not in operation or operation.startswith("DOUBLE_DOOR") else (-up if left else up)
    return hinge_first, swing


def _min_rectangle(
    xy: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The smallest rectangle around points ``xy`` (``(n, 2)``): its long axis ``u``, short axis ``n``,
    the points' coordinates along each (from the points' mean) and the rectangle's centre."""
    centre = xy.mean(axis=0)
    try:
        hull = xy[ConvexHull(xy).vertices]
    except QhullError:  # flat: every point on a line
        hull = xy
    edges = np.roll(hull, -1, axis=0) - hull
    lengths = np.hypot(*edges.T)
    dirs = edges[lengths > 1e-9] / lengths[lengths > 1e-9, None]
    if not len(dirs):
        dirs = np.array([[1.0, 0.0]])
    best: tuple[float, np.ndarray] | None = None
    for d in dirs:
        nd = np.array([-d[1], d[0]])
        a, c = (hull - centre) @ d, (hull - centre) @ nd
        area = float(np.ptp(a) * np.ptp(c))
        if best is None or area < best[0] - 1e-12:
            best = (area, d if np.ptp(a) >= np.ptp(c) else nd)
    assert best is not None
    u = best[1]
    if u[0] < -1e-9 or (abs(u[0]) <= 1e-9 and u[1] < 0):
        u = -u
    n = np.array([-u[1], u[0]])
    along, across = (xy - centre) @ u, (xy - centre) @ n
    mid = centre + u * (along.max() + along.min()) / 2 + n * (across.max() + across.min()) / 2
    return u, n, along, across, mid


def _on(scene: Scene, index: int, plan: MapPlan) -> bool:
    """Whether element ``index`` reaches into the plan's height band and lies on its grid."""
    b = scene.elements.bounds[index]
    f = plan.frame
    return bool(
        b[2] <= plan.z_hi
        and b[5] >= plan.z_lo
        and b[0] < f.origin_x + f.width * f.resolution_m
        and b[3] > f.origin_x
        and b[1] < f.origin_y + f.height * f.resolution_m
        and b[4] > f.origin_y
    )


DOOR_SILL_M = (-0.3, 0.5)
"""A door is on a storey when its bottom lies in this band about the storey's elevation (m)."""


def _sill_on(scene: Scene, index: int, plan: MapPlan) -> bool:
    """Whether element ``index`` (a door) stands on the plan's storey: its bottom near the floor."""
    bottom = float(scene.elements.bounds[index][2])
    elev = plan.storey.elevation_m
    return elev + DOOR_SILL_M[0] <= bottom <= elev + DOOR_SILL_M[1]


def _lifts(scene: Scene, lifts: list[_Named], storeys: list[StoreyInfo], nav: SkillProfile) -> list[Lift]:
    out: list[Lift] = []
    taken: set[str] = set()
    for lift in lifts:
        i = scene.elements.index.get(lift.iri)
        if i is None or np.isnan(scene.elements.bounds[i]).any():
            continue
        b = scene.elements.bounds[i]
        served = tuple(s.key for s in storeys if b[2] - 0.05 <= s.elevation_m <= b[5] - nav.robot_height_m)
        if not served:
            continue
        out.append(
            Lift(
                name=unique(sanitise(lift.name), taken),
                iri=lift.iri,
                x=round(float(b[0] + b[3]) / 2, 6),
                y=round(float(b[1] + b[4]) / 2, 6),
                yaw=0.0,
                width_m=round(float(b[3] - b[0]), 6),
                depth_m=round(float(b[4] - b[1]), 6),
                storeys=served,
            )
        )
    return out


def _space_areas(
    scene: Scene, plan: MapPlan, names: Mapping[str, str], level: str, taken: set[str]
) -> list[SpaceArea]:
    """The storey's spaces and their cells (their geometry in the map's height band)."""
    out = []
    frame = plan.frame
    for iri, storey_iri in sorted(scene.space_storey.items()):
        if storey_iri != plan.storey.iri or iri not in scene.spaces.index:
            continue
        i = scene.spaces.index[iri]
        b = scene.spaces.bounds[i]
        if np.isnan(b).any():
            continue
        window = frame.window_for(float(b[0]), float(b[1]), float(b[3]), float(b[4]))
        if window.empty:
            continue
        cells = np.zeros(frame.shape, dtype=np.bool_)
        cells[window.row0 : window.row1, window.col0 : window.col1] = occupancy(
            scene.spaces, np.array([i], dtype=np.intp), plan, window
        )
        name = unique(f"{sanitise(level)}_{sanitise(names.get(iri) or iri.rsplit('#', 1)[-1])}", taken)
        out.append(SpaceArea(name, cells))
    return out


def _waypoints(
    scene: Scene,
    routes: RouteProfile,
    *,
    storey: StoreyInfo,
    plan: MapPlan,
    free: np.ndarray,
    space_names: Mapping[str, str],
) -> list[RouteVertex]:
    """The configured waypoints on this storey, each at its position (``at``: the named space's most
    interior free point)."""
    out = []
    for wp in routes.waypoints:
        where = _where(scene, routes, wp, plan=plan, free=free, space_names=space_names)
        if where is None:
            continue
        out.append(
            RouteVertex(
                where[0],
                where[1],
                name=wp.name,
                kind="waypoint",
                charger=wp.charger,
                holding_point=wp.holding_point,
                parking_spot=wp.parking_spot,
                dock=wp.dock,
            )
        )
    return out


def _where(
    scene: Scene,
    routes: RouteProfile,
    wp: Waypoint,
    *,
    plan: MapPlan,
    free: np.ndarray,
    space_names: Mapping[str, str],
) -> tuple[float, float] | None:
    storey = plan.storey
    if wp.at is None:
        if wp.storey not in {s.key for s in scene.storeys} or (
            routes.storeys and wp.storey not in routes.storeys
        ):
            msg = (
                f"Routes skill {routes.name!r}: waypoint {wp.name!r} is on storey {wp.storey!r}, "
                "which the fleet does not serve."
            )
            raise RouteError(msg)
        return (wp.x, wp.y) if wp.storey == storey.key else None
    frame = plan.frame
    spaces = [iri for iri, name in space_names.items() if name == wp.at]
    if spaces:
        on = [
            iri for iri in spaces if scene.space_storey.get(iri) == storey.iri and iri in scene.spaces.index
        ]
        if not on:
            return None
        i = scene.spaces.index[on[0]]
        cells = occupancy(scene.spaces, np.array([i], dtype=np.intp), plan, frame.full) & free
        if not cells.any():
            return None
        depth = ndimage.distance_transform_edt(np.pad(cells, 1))[1:-1, 1:-1]
        r, c = np.unravel_index(int(np.argmax(depth)), depth.shape)
        return _centre(frame, int(r), int(c))
    msg = (
        f"Routes skill {routes.name!r}: waypoint {wp.name!r} is at {wp.at!r}, which names no space "
        "of the model."
    )
    raise RouteError(msg)


def _centre(frame: GridFrame, row: int, col: int) -> tuple[float, float]:
    res = frame.resolution_m
    x, y = frame.origin_x + (col + 0.5) * res, frame.origin_y + (row + 0.5) * res
    return (round(float(x), 6), round(float(y), 6))
