"""Small free regions (issue 41): pockets too small to leave keep their vertices and the graph says so;
a small region's lattice is denser, so that close points in it route nearly straight."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from twin.maps.grid import GridFrame
from twin.routes.graph import RouteVertex
from twin.routes.lines import segments_free
from twin.routes.storey import StoreyInput, build_storey

FRAME = GridFrame(origin_x=0.0, origin_y=0.0, resolution_m=0.05, width=160, height=100)


def _room_and(pocket_side_m: float) -> np.ndarray:
    """A 5 m x 3 m room and, apart from it, a square region ``pocket_side_m`` wide."""
    free = np.zeros((FRAME.height, FRAME.width), dtype=bool)
    free[10:70, 10:110] = True
    side = round(pocket_side_m / FRAME.resolution_m)
    free[20 : 20 + side, 125 : 125 + side] = True
    return free


def _region_vertices(free: np.ndarray, vertices: tuple[RouteVertex, ...], cols: slice) -> np.ndarray:
    rc = np.array(
        [((v.y - FRAME.origin_y) / 0.05 - 0.5, (v.x - FRAME.origin_x) / 0.05 - 0.5) for v in vertices]
    )
    rc = np.rint(rc).astype(int)
    return np.flatnonzero((rc[:, 1] >= cols.start) & (rc[:, 1] < cols.stop))


def test_a_small_region_apart_is_a_pocket_with_vertices_every_cell_sees_and_no_lane_out() -> None:
    free = _room_and(0.8)  # 0.64 m²
    result = build_storey(StoreyInput("level-0", 0.0, FRAME, free))
    (note,) = [n for n in result.notes if "pocket" in n]
    assert note.startswith("level-0: 1 pocket(s) of free space under 1 m²")
    assert "0.64 m² at (6.65, 1.40)" in note
    vertices = result.routes.vertices
    inside = set(_region_vertices(free, vertices, slice(120, 160)).tolist())
    assert inside  # a robot standing there is on the graph
    assert all((lane.a in inside) == (lane.b in inside) for lane in result.routes.lanes)
    cells = np.argwhere(free[:, 120:]) + np.array([0, 120])
    targets = np.array([((vertices[i].y / 0.05) - 0.5, (vertices[i].x / 0.05) - 0.5) for i in sorted(inside)])
    seen = segments_free(
        free, np.repeat(cells.astype(float), len(targets), axis=0), np.tile(targets, (len(cells), 1))
    ).reshape(len(cells), len(targets))
    assert seen.any(axis=1).all()


def test_a_region_of_a_square_metre_or_more_is_not_a_pocket() -> None:
    result = build_storey(StoreyInput("level-0", 0.0, FRAME, _room_and(1.2)))
    assert not [n for n in result.notes if "pocket" in n]
    assert not [
        n for n in build_storey(StoreyInput("level-0", 0.0, FRAME, _room_and(0.0))).notes if "pocket" in n
    ]


def test_the_pocket_size_is_a_skill_key() -> None:
    free = _room_and(1.2)  # 1.44 m²: a pocket under a 2 m² limit, none under the default 1 m²
    (note,) = [
        n
        for n in build_storey(StoreyInput("level-0", 0.0, FRAME, free, pocket_m2=2.0)).notes
        if "pocket" in n
    ]
    assert note.startswith("level-0: 1 pocket(s) of free space under 2 m²")
    assert not [
        n
        for n in build_storey(StoreyInput("level-0", 0.0, FRAME, _room_and(0.8), pocket_m2=0.0)).notes
        if "pocket" in n
    ]


def _nearest_vertex_p95(
    width_m: float, height_m: float, *, beside_hall: bool = False, small_region_m2: float = 12.0
) -> float:
    """The 95th percentile over a room's free cells of the distance to the nearest vertex (m); with
    ``beside_hall`` the storey also has a 13.5 m² region apart from the room."""
    free = np.zeros((FRAME.height, FRAME.width), dtype=bool)
    free[5 : 5 + round(height_m / 0.05), 5 : 5 + round(width_m / 0.05)] = True
    room = free.copy()
    if beside_hall:
        free[5:95, 100:160] = True  # 3 m x 4.5 m: 13.5 m², more than the room's 7.5 m²
    routes = build_storey(StoreyInput("level-0", 0.0, FRAME, free, small_region_m2=small_region_m2)).routes
    xy = np.array([(v.x, v.y) for v in routes.vertices])
    d, _ = cKDTree(xy).query((np.argwhere(room)[:, ::-1] + 0.5) * 0.05)
    return float(np.percentile(d, 95))


def test_a_room_under_twelve_square_metres_gets_vertices_about_a_quarter_metre_apart() -> None:
    assert _nearest_vertex_p95(3.0, 2.5) < 0.2  # 7.5 m²: a 0.25 m lattice
    assert _nearest_vertex_p95(4.5, 4.0) > 0.3  # 18 m²: the 0.5 m lattice
    assert _nearest_vertex_p95(4.5, 4.0, small_region_m2=20.0) < 0.2  # small under a 20 m² limit
    assert _nearest_vertex_p95(3.0, 2.5, small_region_m2=0.0) > 0.25  # never dense (0.18 dense)


def test_small_rooms_keep_the_usual_lattice_where_most_free_space_is_a_larger_region() -> None:
    assert _nearest_vertex_p95(3.0, 2.5, beside_hall=True) > 0.2
