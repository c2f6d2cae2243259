"""One storey's route graph from its free space: medial-axis lanes, doors, spaces and attached points.

Given the cells a robot's centre may occupy (``free``: the fleet's inflated navigation map with doors
open and lift cars exempt, keepout zones removed), the lanes follow the pruned skeleton of free space
(:mod:`twin.routes.skeleton`): vertices at its junctions and dead ends, the runs between simplified to
straight lanes whose centre lines are free (:mod:`twin.routes.lines`), with a vertex at least every
``spacing_m`` along them. Then:

- **doors**: where the skeleton crosses a door's plane within the door's width, a vertex on each side
  (where the skeleton leaves a band of ``door_reach_m`` about the door) and one straight lane between
  them carrying the door's name; a door the skeleton does not cross is not passable for this robot;
- **spaces**: a named vertex at the skeleton point of the space most interior to its free part;
- **points** (lift cabins, configured waypoints): a vertex exactly there, joined by a straight lane
  to the nearest skeleton point it sees;
- **open space**: a lattice of vertices ``spacing_m`` apart where free space lies away from every lane
  (rooms), joined to the neighbours each sees; half ``spacing_m`` apart in free regions under
  :attr:`StoreyInput.small_region_m2` (rooms whose doors the robot does not fit, pockets) on a storey
  whose free space lies mostly in such regions;
- **pockets**: free regions under :attr:`StoreyInput.pocket_m2` with no space, lift or waypoint are
  listed in a note (they keep their vertices: a robot standing in one is on the graph, and no lane leaves it);
- **shortcuts**: a straight lane between two vertices within ``max_lane_m`` that see each other when
  the graph's way between them is much longer (open rooms: the skeleton's way is a detour).

Vertices ``spacing_m`` apart (0.5 m by default) keep routes between close points short: a point joins
the graph at a vertex it sees, and a route between two points a metre apart is only about as long as
their distance when a vertex lies near the line between them.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import networkx as nx
import numpy as np
import numpy.typing as npt
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from twin.maps.grid import GridFrame
from twin.routes.graph import RouteLane, RouteVertex, StoreyRoutes
from twin.routes.lines import BoolArray, FloatArray, segments_free
from twin.routes.skeleton import Chain, IntArray, pruned_skeleton, simplify, trace

log = logging.getLogger(__name__)

SIMPLIFY_M = 0.1
"""How far a lane may stray from the medial axis it replaces (m)."""
SHORTCUT_RATIO = 1.15
"""A shortcut is added where the graph's way is longer than this many times the straight line."""
OPEN_SPACE_FRACTION = 0.75
"""Open space gets lattice vertices where it lies this many lattice spacings from every lane."""
POCKETS_LISTED = 3


@dataclass(frozen=True, slots=True)
class DoorShape:
    """A door on the storey: centre (m), unit vector along its width, width and thickness (m), its IFC
    operation type ("" unknown) and which way it opens (see :class:`twin.routes.graph.DoorCrossing`:
    ``hinge_first`` says whether ``endpoints[0]`` is the hinge, ``swing`` 1 clockwise, -1 anticlockwise,
    0 unknown)."""

    name: str
    iri: str
    x: float
    y: float
    ux: float
    uy: float
    width_m: float
    thickness_m: float
    operation: str = ""
    hinge_first: bool = True
    swing: int = 0

    @property
    def endpoints(self) -> tuple[tuple[float, float], tuple[float, float]]:
        h = self.width_m / 2
        ends = ((self.x - h * self.ux, self.y - h * self.uy), (self.x + h * self.ux, self.y + h * self.uy))
        return ends if self.hinge_first else (ends[1], ends[0])


@dataclass(frozen=True, slots=True)
class SpaceArea:
    """An IfcSpace on the storey: its vertex's name and its cells (``(h, w) bool`` over the frame)."""

    name: str
    cells: BoolArray


@dataclass(frozen=True, slots=True)
class StoreyInput:
    """What one storey's graph is made from."""

    storey: str
    elevation_m: float
    frame: GridFrame
    free: BoolArray
    doors: Sequence[DoorShape] = ()
    spaces: Sequence[SpaceArea] = ()
    points: Sequence[RouteVertex] = ()
    max_lane_m: float = 3.0
    spacing_m: float = 0.5
    door_reach_m: float = 0.6
    small_region_m2: float = 12.0
    """On a storey whose free space lies mostly in regions smaller than this (m²: rooms whose doors the
    robot does not fit, pockets), those regions get their open-space lattice half ``spacing_m`` apart:
    every pair of points in one is close, and a route between close points is about as long as their
    distance only through a vertex near the line between them. Where most free space is one larger
    region, its routes are the storey's and the small regions keep the usual lattice: four times the
    vertices in dozens of closed rooms would cost more ids than nav2's 65,535 (the generated 12k
    building). ``[skills.NAME] small_region_m2``."""
    pocket_m2: float = 1.0
    """A free region smaller than this (m², of the robot's centre) with no space, lift or waypoint in it
    is a pocket: somewhere between furniture and walls a robot can stand but not leave.
    ``[skills.NAME] pocket_m2``."""


@dataclass(slots=True)
class StoreyResult:
    routes: StoreyRoutes
    passable: set[str] = field(default_factory=set)
    """Names of the doors a lane passes through."""
    notes: list[str] = field(default_factory=list)


def build_storey(inp: StoreyInput) -> StoreyResult:
    """The storey's graph (see the module's docstring)."""
    frame, free = inp.frame, inp.free
    res = frame.resolution_m
    h, w = free.shape
    notes: list[str] = []
    clearance: FloatArray = ndimage.distance_transform_edt(free)
    skeleton = pruned_skeleton(free, clearance)
    sk_idx = np.flatnonzero(skeleton)
    sk_rc = np.stack(np.divmod(sk_idx, w), axis=1).astype(np.float64)
    forced: list[IntArray] = []
    # doors: skeleton pixels in each door's band; the band's edge pixels become nodes
    band_of = np.full(h * w, -1, dtype=np.int64)
    side_of = np.zeros(h * w, dtype=np.int8)
    for k, door in enumerate(inp.doors):
        cx, cy = _cell(frame, door.x, door.y)
        dr, dc = sk_rc[:, 0] - cy, sk_rc[:, 1] - cx
        along = (dc * door.ux + dr * door.uy) * res
        across = (dc * -door.uy + dr * door.ux) * res
        reach = door.thickness_m / 2 + inp.door_reach_m
        inside = (np.abs(along) <= door.width_m / 2) & (np.abs(across) <= reach)
        band_of[sk_idx[inside]] = k
        side_of[sk_idx[inside]] = np.where(across[inside] >= 0, 1, -1)
    if inp.doors:
        in_band = (band_of >= 0).reshape(h, w)
        outside = skeleton & ~in_band
        near_out = ndimage.binary_dilation(outside, structure=np.ones((3, 3), dtype=bool))
        edge = np.flatnonzero(in_band & near_out)
        forced.append(edge)
    # spaces: the skeleton point most interior to the space's free cells
    space_node: dict[int, str] = {}
    for space in inp.spaces:
        cells = space.cells & free
        on = skeleton & cells
        if not on.any():
            if cells.any():
                notes.append(f"{inp.storey}: space {space.name} has free cells but no lane reaches them")
            continue
        depth = _depth(cells)
        idx = np.flatnonzero(on)
        d = depth.flat[idx]
        deep = idx[d >= d.max() - 1.0]  # the deepest skeleton points (within a cell): the most central
        rows, cols = np.nonzero(cells)
        centre = np.array([rows.mean(), cols.mean()])
        rc = np.stack(np.divmod(deep, w), axis=1)
        best = int(deep[np.argmin(np.hypot(*(rc - centre).T))])
        if best in space_node:
            notes.append(f"{inp.storey}: spaces {space_node[best]} and {space.name} share a vertex")
            continue
        space_node[best] = space.name
        forced.append(np.array([best], dtype=np.int64))
    # points: attach each to the nearest skeleton pixel it sees
    tree = cKDTree(sk_rc) if len(sk_rc) else None
    attach: list[tuple[RouteVertex, int]] = []
    for point in inp.points:
        cx, cy = _cell(frame, point.x, point.y)
        r, c = round(cy), round(cx)
        if not (0 <= r < h and 0 <= c < w and free[r, c]):
            notes.append(
                f"{inp.storey}: {point.kind} {point.name or point.lift} at ({point.x:.2f}, "
                f"{point.y:.2f}) is not in free space for this robot"
            )
            continue
        target = _visible_pixel(tree, sk_idx, free, (cy, cx)) if tree is not None else None
        if target is None:
            notes.append(f"{inp.storey}: {point.kind} {point.name or point.lift} sees no lane")
            continue
        attach.append((point, target))
        forced.append(np.array([target], dtype=np.int64))
    forced_px = np.unique(np.concatenate(forced)) if forced else np.empty(0, dtype=np.int64)
    nodes, chains = trace(skeleton, forced_px)
    # vertices of nodes
    vertices: list[RouteVertex] = []
    vertex_of: dict[int, int] = {}
    node_rc: dict[int, tuple[float, float]] = {}
    for node, pixels in nodes.items():
        rc = np.stack(np.divmod(pixels, w), axis=1).astype(np.float64)
        pick = int(np.argmin(np.hypot(*(rc - rc.mean(axis=0)).T)))
        node_rc[node] = (float(rc[pick, 0]), float(rc[pick, 1]))
        x, y = _world(frame, *node_rc[node])
        name = space_node.get(node, "")
        vertex_of[node] = len(vertices)
        vertices.append(RouteVertex(x, y, name=name, kind="space" if name else "lane"))
    lanes: dict[tuple[int, int], str] = {}
    tol = max(SIMPLIFY_M / res, 1.5)
    max_cells = min(inp.spacing_m, inp.max_lane_m) / res
    door_kinds: set[int] = set()
    fill: set[int] = set()  # vertices that only subdivide a lane or fill open space
    passable: set[str] = set()
    for chain in chains:
        rc = np.stack(np.divmod(chain.pixels, w), axis=1).astype(np.float64)
        # from the start node's vertex to the end node's, through the chain's own pixels
        rc = np.concatenate([[node_rc[chain.start]], rc, [node_rc[chain.end]]])
        step = np.r_[True, np.any(rc[1:] != rc[:-1], axis=1)]
        rc = rc[step]
        if len(rc) == 1:
            continue
        door_k = _door_of(chain.pixels, band_of, side_of)
        if door_k is not None and segments_free(free, rc[:1], rc[-1:])[0]:
            keep = np.array([0, len(rc) - 1])
        else:
            keep = simplify(rc, free, tolerance=tol)
        ids = [vertex_of[chain.start]]
        for k in keep[1:-1]:
            x, y = _world(frame, *rc[k])
            ids.append(len(vertices))
            vertices.append(RouteVertex(x, y))
        ids.append(vertex_of[chain.end])
        pts = rc[keep]
        crossing = np.zeros(len(pts) - 1, dtype=np.bool_)
        if door_k is not None:
            crossed = inp.doors[door_k]
            cx, cy = _cell(frame, crossed.x, crossed.y)
            across = np.sign((pts[:, 1] - cx) * -crossed.uy + (pts[:, 0] - cy) * crossed.ux)
            crossing = (across[:-1] != across[1:]) | (across[:-1] == 0)
        for s in range(len(ids) - 1):
            a, b = ids[s], ids[s + 1]
            name = ""
            if door_k is not None and crossing[s]:
                name = inp.doors[door_k].name
                door_kinds.update((a, b))
                passable.add(name)
            n_parts = 1 if name else max(1, math.ceil(float(np.hypot(*(pts[s + 1] - pts[s]))) / max_cells))
            prev, prev_rc = a, pts[s]
            longest = inp.max_lane_m / res
            for part in range(1, n_parts):
                on_lane = pts[s] + (pts[s + 1] - pts[s]) * part / n_parts
                p = _snap(free, prev_rc, on_lane, pts[s + 1])
                if p is None:  # no cell centre near: skip it, unless the lane would grow too long
                    ahead = pts[s] + (pts[s + 1] - pts[s]) * (part + 1) / n_parts
                    if float(np.hypot(*(ahead - prev_rc))) <= longest:
                        continue
                    p = on_lane
                x, y = _world(frame, float(p[0]), float(p[1]))
                fill.add(len(vertices))
                vertices.append(RouteVertex(x, y))
                _add_lane(lanes, prev, len(vertices) - 1, "")
                prev, prev_rc = len(vertices) - 1, p
            _add_lane(lanes, prev, b, name)
    for i in door_kinds:
        if vertices[i].kind == "lane":
            vertices[i] = replace(vertices[i], kind="door")
    for point, target in attach:
        vertices.append(point)
        _add_lane(lanes, len(vertices) - 1, vertex_of[target], "")
    first_lattice = len(vertices)
    spacing = min(inp.spacing_m, inp.max_lane_m)
    labels, _ = ndimage.label(free, structure=np.ones((3, 3), dtype=bool))
    area = np.bincount(labels.ravel()).astype(np.float64)
    area *= res * res
    small = area < inp.small_region_m2
    small[0] = False
    if area[small].sum() > area[1:].sum() / 2:
        _open_space(vertices, lanes, frame, free, spacing / 2, where=small[labels])
    _open_space(vertices, lanes, frame, free, spacing)
    fill.update(range(first_lattice, len(vertices)))
    _shortcuts(vertices, lanes, frame, free, inp.max_lane_m, fill=fill)
    used = sorted({i for ab in lanes for i in ab} | {i for i, v in enumerate(vertices) if v.name or v.lift})
    if len(used) < len(vertices):  # drop vertices no lane uses (isolated skeleton specks) but named ones
        keep_vertex = set(used) | {vertex_of[n] for n in nodes if len(nodes[n]) > 0 and _alone(n, chains)}
        remap = {old: new for new, old in enumerate(sorted(keep_vertex))}
        vertices = [vertices[i] for i in sorted(keep_vertex)]
        lanes = {(remap[a], remap[b]): d for (a, b), d in lanes.items()}
    notes += _pockets(inp, vertices, labels, area)
    for door in inp.doors:
        if door.name not in passable:
            notes.append(
                f"{inp.storey}: door {door.name} ({door.width_m:.2f} m wide) is not passable for this robot"
            )
    routes = StoreyRoutes(
        storey=inp.storey,
        elevation_m=inp.elevation_m,
        vertices=tuple(vertices),
        lanes=tuple(RouteLane(a, b, d) for (a, b), d in sorted(lanes.items())),
    )
    return StoreyResult(routes, passable, notes)


def _pockets(
    inp: StoreyInput, vertices: Sequence[RouteVertex], labels: IntArray, area: FloatArray
) -> list[str]:
    """A note on the storey's pockets (:attr:`StoreyInput.pocket_m2`): they keep their vertices (a robot
    standing in one is on the graph, its cells see one) and no lane leaves them, as no path on the map
    does.
    ``labels``: the free regions (8-connected, 0 blocked), ``area``: each label's area (m²)."""
    frame, res = inp.frame, inp.frame.resolution_m
    n = len(area) - 1
    if n < 2:
        return []
    xy = np.array([(v.x, v.y) for v in vertices], dtype=np.float64).reshape(-1, 2)
    rc = np.rint(
        np.stack([(xy[:, 1] - frame.origin_y) / res - 0.5, (xy[:, 0] - frame.origin_x) / res - 0.5], 1)
    )
    rc = np.clip(rc.astype(np.int64), 0, np.array(inp.free.shape) - 1)
    region = labels[rc[:, 0], rc[:, 1]]
    served = {int(r) for r, v in zip(region, vertices, strict=True) if v.name or v.lift or v.kind != "lane"}
    small = [r for r in range(1, n + 1) if area[r] < inp.pocket_m2 and r not in served]
    if not small:
        return []
    where = []
    for r in sorted(small, key=lambda r: -area[r])[:POCKETS_LISTED]:
        rows, cols = np.nonzero(labels == r)
        x, y = _world(frame, float(rows.mean()), float(cols.mean()))
        where.append(f"{area[r]:.2f} m² at ({x:.2f}, {y:.2f})")
    more = f", and {len(small) - POCKETS_LISTED} more" if len(small) > POCKETS_LISTED else ""
    return [
        f"{inp.storey}: {len(small)} pocket(s) of free space under {inp.pocket_m2:g} m² that a robot can "
        f"stand in but not leave ({'; '.join(where)}{more}): on the graph, joined to nothing outside"
    ]


def _snap(free: BoolArray, before: FloatArray, p: FloatArray, after: FloatArray) -> FloatArray | None:
    """``p`` (cell coordinates, on the free lane ``before`` -> ``after``) moved to the centre of a cell
    next to it from which both parts of the lane stay free: a vertex between cells would lie on the
    edge of free space; None when no such cell is next to it."""
    for candidate in (np.rint(p), *(np.array(c, dtype=np.float64) for c in _corners(p))):
        r, c = int(candidate[0]), int(candidate[1])
        if not (0 <= r < free.shape[0] and 0 <= c < free.shape[1] and free[r, c]):
            continue
        if segments_free(free, np.array([before, candidate]), np.array([candidate, after])).all():
            return candidate
    return None


def _corners(p: FloatArray) -> list[tuple[float, float]]:
    fr, fc = math.floor(p[0]), math.floor(p[1])
    return [(fr, fc), (fr, fc + 1), (fr + 1, fc), (fr + 1, fc + 1)]


def _depth(cells: BoolArray) -> FloatArray:
    """``(h, w)``: each cell's distance (cells) to the nearest cell outside ``cells``, computed on
    ``cells``' bounding box only."""
    rows, cols = np.nonzero(cells)
    r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
    depth = np.zeros(cells.shape)
    depth[r0:r1, c0:c1] = ndimage.distance_transform_edt(np.pad(cells[r0:r1, c0:c1], 1))[1:-1, 1:-1]
    return depth


def _alone(node: int, chains: Sequence[Chain]) -> bool:
    """A node no chain touches: an isolated free speck, still a place the robot can be."""
    return not any(node in (c.start, c.end) for c in chains)


def _add_lane(lanes: dict[tuple[int, int], str], a: int, b: int, door: str) -> None:
    if a == b:
        return
    key = (min(a, b), max(a, b))
    if door or key not in lanes:
        lanes[key] = door


def _door_of(pixels: IntArray, band_of: IntArray, side_of: npt.NDArray[np.int8]) -> int | None:
    """The door a chain passes through: all its pixels in one door's band, on both of its sides."""
    bands = band_of[pixels]
    inner = bands[1:-1] if len(bands) > 2 else bands
    if len(inner) == 0 or inner[0] < 0 or not np.all(inner == inner[0]):
        return None
    sides = side_of[pixels][band_of[pixels] == inner[0]]
    if (sides > 0).any() and (sides < 0).any():
        return int(inner[0])
    return None


def _visible_pixel(
    tree: cKDTree, sk_idx: IntArray, free: BoolArray, rc: tuple[float, float], k: int = 64
) -> int | None:
    """The nearest skeleton pixel that the point ``rc`` (cell coordinates) sees."""
    k = min(k, len(sk_idx))
    _, near = tree.query(np.array(rc), k=k)
    near = np.atleast_1d(near)
    w = free.shape[1]
    targets = np.stack(np.divmod(sk_idx[near], w), axis=1).astype(np.float64)
    ok = segments_free(free, np.repeat(np.array([rc]), len(near), axis=0), targets)
    hits = np.flatnonzero(ok)
    return int(sk_idx[near[hits[0]]]) if len(hits) else None


def _open_space(
    vertices: list[RouteVertex],
    lanes: dict[tuple[int, int], str],
    frame: GridFrame,
    free: BoolArray,
    spacing_m: float,
    *,
    where: BoolArray | None = None,
) -> None:
    """Fill open space: a lattice of vertices ``spacing_m`` apart where free space (within ``where``,
    when given) lies farther from every lane than most of a spacing, each joined to the vertices within
    1.5 spacings it sees.

    The medial axis of a wide room is one line (or an X) down its middle: a route between two points
    near one wall would go to the middle and back. The lattice gives such rooms lanes where robots
    actually cross them."""
    if not vertices or not lanes:
        return
    res = frame.resolution_m
    step = spacing_m
    lane_cells = np.zeros_like(free)
    xy = np.array([(v.x, v.y) for v in vertices])
    cells = np.stack([(xy[:, 1] - frame.origin_y) / res - 0.5, (xy[:, 0] - frame.origin_x) / res - 0.5], 1)
    for a, b in lanes:
        n = max(2, math.ceil(float(np.hypot(*(cells[b] - cells[a]))) * 2) + 1)
        pts = np.rint(cells[a] + (cells[b] - cells[a]) * np.linspace(0.0, 1.0, n)[:, None]).astype(np.int64)
        lane_cells[pts[:, 0], pts[:, 1]] = True
    far = ndimage.distance_transform_edt(~lane_cells) * res >= OPEN_SPACE_FRACTION * step
    k = max(1, round(step / res))
    h, w = free.shape
    # lattice nodes anchored to the world (not the grid's origin): the same cells whatever the extent
    r0 = (-round(frame.origin_y / res)) % k
    c0 = (-round(frame.origin_x / res)) % k
    rows, cols = np.meshgrid(np.arange(r0, h, k), np.arange(c0, w, k), indexing="ij")
    keep = free[rows, cols] & far[rows, cols]
    if where is not None:
        keep &= where[rows, cols]
    new = np.stack([rows[keep], cols[keep]], axis=1).astype(np.float64)
    if not len(new):
        return
    first = len(vertices)
    for r, c in new:
        x, y = _world(frame, float(r), float(c))
        vertices.append(RouteVertex(x, y))
    every = np.concatenate([cells, new])
    tree = cKDTree(every)
    pairs = np.array(sorted(tree.query_pairs(1.5 * step / res + 1e-6)), dtype=np.int64).reshape(-1, 2)
    pairs = pairs[(pairs >= first).any(axis=1)]
    if not len(pairs):
        return
    blocked = np.array([v.kind in ("door", "lift") for v in vertices])
    pairs = pairs[~blocked[pairs].any(axis=1)]
    visible = segments_free(free, every[pairs[:, 0]], every[pairs[:, 1]])
    for a, b in pairs[visible]:
        _add_lane(lanes, int(a), int(b), "")


def _shortcuts(
    vertices: list[RouteVertex],
    lanes: dict[tuple[int, int], str],
    frame: GridFrame,
    free: BoolArray,
    max_lane_m: float,
    *,
    fill: set[int] | None = None,
) -> None:
    """Add straight lanes between vertices within ``max_lane_m`` that see each other where the graph's
    way is more than :data:`SHORTCUT_RATIO` times longer (door vertices excepted: a door's lane is
    the way through it; and pairs of ``fill`` vertices, which subdivide lanes or make the open-space
    lattice, whose neighbours already join them about straight)."""
    if len(vertices) < 3:
        return
    xy = np.array([(v.x, v.y) for v in vertices])
    g = nx.Graph()
    g.add_nodes_from(range(len(vertices)))
    for a, b in lanes:
        g.add_edge(a, b, weight=float(np.hypot(*(xy[a] - xy[b]))))
    pairs = np.array(sorted(cKDTree(xy).query_pairs(max_lane_m)), dtype=np.int64).reshape(-1, 2)
    if not len(pairs):
        return
    blocked = np.array([vertices[i].kind in ("door", "lift") for i in range(len(vertices))])
    pairs = pairs[~blocked[pairs].any(axis=1)]
    if fill:
        filler = np.zeros(len(vertices), dtype=np.bool_)
        filler[list(fill)] = True
        pairs = pairs[~filler[pairs].all(axis=1)]
    pairs = pairs[[(int(a), int(b)) not in lanes for a, b in pairs]] if len(pairs) else pairs
    if not len(pairs):
        return
    straight = np.hypot(*(xy[pairs[:, 0]] - xy[pairs[:, 1]]).T)
    # first the graph's ways as they are (cheap, all sources in chunks): only detours need a sight test
    n = len(vertices)
    ab = np.array(list(lanes), dtype=np.int64).reshape(-1, 2)
    w = np.hypot(*(xy[ab[:, 0]] - xy[ab[:, 1]]).T) + 1e-9
    adjacency = coo_matrix((w, (ab[:, 0], ab[:, 1])), shape=(n, n)).tocsr()
    way = np.empty(len(pairs))
    sources = np.unique(pairs[:, 0])
    for chunk in np.array_split(sources, max(1, len(sources) // 256)):
        rows = dijkstra(adjacency, directed=False, indices=chunk, limit=SHORTCUT_RATIO * max_lane_m)
        at = np.isin(pairs[:, 0], chunk)
        way[at] = rows[np.searchsorted(chunk, pairs[at, 0]), pairs[at, 1]]
    detour = way > SHORTCUT_RATIO * straight
    pairs, straight = pairs[detour], straight[detour]
    res = frame.resolution_m
    cells = np.stack([(xy[:, 1] - frame.origin_y) / res - 0.5, (xy[:, 0] - frame.origin_x) / res - 0.5], 1)
    # a coarse sight test first (most pairs within reach lie behind a wall), the full one on the rest
    seen = segments_free(free, cells[pairs[:, 0]], cells[pairs[:, 1]], samples_per_cell=1)
    pairs, straight = pairs[seen], straight[seen]
    visible = segments_free(free, cells[pairs[:, 0]], cells[pairs[:, 1]])
    pairs, straight = pairs[visible], straight[visible]
    order = np.lexsort((straight, pairs[:, 0]))
    pairs, straight = pairs[order], straight[order]
    # each source's search reaches only as far as its farthest candidate needs
    reach = dict(zip(pairs[:, 0].tolist(), straight.tolist(), strict=False))  # the last (longest) wins
    source, dist = -1, {}
    for (pa, pb), d in zip(pairs, straight, strict=True):
        a, b = int(pa), int(pb)
        if a != source:
            cutoff = SHORTCUT_RATIO * reach[a] + 1e-6
            source, dist = a, nx.single_source_dijkstra_path_length(g, a, cutoff=cutoff, weight="weight")
        if dist.get(b, math.inf) > SHORTCUT_RATIO * d:
            lanes[(a, b)] = ""
            g.add_edge(a, b, weight=float(d))
            dist[b] = float(d)


def _cell(frame: GridFrame, x: float, y: float) -> tuple[float, float]:
    """``(col, row)`` cell coordinates of world ``(x, y)`` (cell centres at whole numbers)."""
    res = frame.resolution_m
    return (x - frame.origin_x) / res - 0.5, (y - frame.origin_y) / res - 0.5


def _world(frame: GridFrame, row: float, col: float) -> tuple[float, float]:
    res = frame.resolution_m
    x, y = frame.origin_x + (col + 0.5) * res, frame.origin_y + (row + 0.5) * res
    return (round(float(x), 6), round(float(y), 6))
