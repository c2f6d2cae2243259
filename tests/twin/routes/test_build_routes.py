"""Route graphs of the box lab: safe lanes, doors, spaces, lifts, and the errors of bad profiles."""

from __future__ import annotations

from dataclasses import replace

import networkx as nx
import numpy as np
import pytest
from scipy import ndimage
from scipy.spatial import cKDTree

from tests.conftest import imported
from tests.twin.routes.lift_lab import LIFT, lift_lab
from twin.config import load_config
from twin.graph.rdf import literal_value
from twin.graph.store import GraphStore
from twin.maps.render import build_map, plan_map
from twin.maps.scene import Scene, load_scene
from twin.routes import RouteError, parse_routes
from twin.routes.build import build_routes, prepare_routes, routable_cells, sanitise, unique
from twin.routes.graph import RouteGraph
from twin.routes.lines import segments_free
from twin.selection.skill_selection import selection_query
from twin.selection.skills import SkillProfile


@pytest.fixture(scope="module")
def lab_with_lift() -> tuple[GraphStore, Scene]:
    store = imported(lift_lab())
    return store, load_scene(store)


def _skills(radius: float) -> dict[str, SkillProfile]:
    cfg = load_config()
    nav = replace(cfg.skills["lab-navigation"], name="nav", inflation_radius_m=radius)
    return {**cfg.skills, "nav": nav}


def _graph(store: GraphStore, scene: Scene, radius: float, **keys: object) -> RouteGraph:
    return build_routes(
        store, scene, parse_routes("fleet", {"kind": "routes", "navigation": "nav", **keys}), _skills(radius)
    )


def _free(store: GraphStore, scene: Scene, skill: SkillProfile, storey: str) -> tuple[np.ndarray, object]:
    exempt = {
        literal_value(r["e"])
        for r in store.select(
            'SELECT ?e WHERE { { ?e twin:ifcType "IfcDoor" } UNION '
            '{ ?e twin:ifcType "IfcTransportElement" } }'
        )
    }
    iris = [
        i
        for r in store.select(selection_query(skill))
        if (i := literal_value(r["element"]) or "") not in exempt
    ]
    grid = build_map(scene, plan_map(scene, skill, storey, iris))
    return grid.data == 0, grid.frame


@pytest.mark.parametrize("radius", [0.25, 0.45])
def test_every_lane_centre_line_is_free_in_the_inflated_map_with_doors_open(
    lab_with_lift: tuple[GraphStore, Scene], radius: float
) -> None:
    store, scene = lab_with_lift
    graph = _graph(store, scene, radius)
    for s in graph.storeys:
        free, frame = _free(store, scene, _skills(radius)["nav"], s.storey)
        xy = np.array([(v.x, v.y) for v in s.vertices])
        cells = np.stack(
            [
                (xy[:, 1] - frame.origin_y) / frame.resolution_m - 0.5,
                (xy[:, 0] - frame.origin_x) / frame.resolution_m - 0.5,
            ],
            1,
        )
        a = np.array([lane.a for lane in s.lanes])
        b = np.array([lane.b for lane in s.lanes])
        assert segments_free(free, cells[a], cells[b]).all()
        lengths = np.hypot(*(xy[a] - xy[b]).T)
        assert lengths.max() <= 3.0 + 1e-6


@pytest.mark.parametrize("radius", [0.25, 0.45])
def test_the_graph_connects_what_the_map_connects_and_nothing_else(
    lab_with_lift: tuple[GraphStore, Scene], radius: float
) -> None:
    store, scene = lab_with_lift
    graph = _graph(store, scene, radius)
    g = graph.to_networkx().to_undirected()
    for s in graph.storeys:
        routes = parse_routes("fleet", {"kind": "routes", "navigation": "nav"})
        _, free = routable_cells(prepare_routes(store, scene, routes, _skills(radius)), s.storey)
        frame = _free(store, scene, _skills(radius)["nav"], s.storey)[1]
        labels, count = ndimage.label(free, structure=np.ones((3, 3)))
        res = frame.resolution_m
        label_of = {
            (s.storey, i): int(
                labels[round((v.y - frame.origin_y) / res - 0.5), round((v.x - frame.origin_x) / res - 0.5)]
            )
            for i, v in enumerate(s.vertices)
        }
        assert 0 not in label_of.values()
        assert set(label_of.values()) == set(range(1, count + 1))  # every free region has a vertex
        sub = g.subgraph(label_of)
        for part in nx.connected_components(sub):
            assert len({label_of[n] for n in part}) == 1  # no lane joins regions the map keeps apart
        assert nx.number_connected_components(sub) == count


def test_a_lane_passes_door_a_for_a_small_robot_carrying_its_name(
    lab_with_lift: tuple[GraphStore, Scene],
) -> None:
    store, scene = lab_with_lift
    graph = _graph(store, scene, 0.25)
    ground = graph.storey("ground-floor")
    (lane,) = [lane for lane in ground.lanes if lane.door]
    assert lane.door == "Door_A"
    a, b = ground.vertices[lane.a], ground.vertices[lane.b]
    assert sorted([a.y, b.y])[0] < 4.9 < sorted([a.y, b.y])[1]  # one vertex each side of the door
    assert abs(a.x - 12.0) < 0.1 and abs(b.x - 12.0) < 0.1
    (door,) = graph.doors
    assert door.passable
    # a right-hand swing door: its hinge (the +x end) first
    assert np.array(door.endpoints) == pytest.approx(np.array([[12.45, 4.9], [11.55, 4.9]]))


def test_a_robot_too_wide_for_door_a_gets_no_lane_through_it_and_the_graph_says_so(
    lab_with_lift: tuple[GraphStore, Scene],
) -> None:
    store, scene = lab_with_lift
    graph = _graph(store, scene, 0.45)
    assert not any(lane.door for s in graph.storeys for lane in s.lanes)
    assert not graph.doors[0].passable
    assert any("door Door_A (0.90 m wide) is not passable" in note for note in graph.notes)


def test_every_space_has_a_named_vertex_prefixed_by_its_level(
    lab_with_lift: tuple[GraphStore, Scene],
) -> None:
    store, scene = lab_with_lift
    graph = build_routes(
        store,
        scene,
        parse_routes("fleet", {"kind": "routes", "navigation": "nav"}),
        _skills(0.25),
        level_names={"ground-floor": "L1", "first-floor": "L2"},
    )
    names = [v.name for s in graph.storeys for v in s.vertices if v.kind == "space"]
    assert sorted(names) == ["L1_Corridor", "L1_Room_A", "L1_Room_B", "L2_Hall"]
    room_a = next(v for v in graph.storey("ground-floor").vertices if v.name == "L1_Room_A")
    assert 10.0 < room_a.x < 14.0 and 5.0 < room_a.y < 9.0


def test_a_lift_has_a_vertex_in_its_cabin_on_both_storeys_at_the_same_place(
    lab_with_lift: tuple[GraphStore, Scene],
) -> None:
    store, scene = lab_with_lift
    graph = _graph(store, scene, 0.25)
    (lift,) = graph.lifts
    assert (lift.name, lift.storeys) == ("Lift_1", ("ground-floor", "first-floor"))
    assert (lift.x, lift.y, lift.width_m, lift.depth_m) == pytest.approx((19.7, 7.7, 1.4, 1.4))
    stops = [(s.storey, v) for s in graph.storeys for v in s.vertices if v.lift == "Lift_1"]
    assert [st for st, _ in stops] == ["ground-floor", "first-floor"]
    assert {(v.x, v.y) for _, v in stops} == {(19.7, 7.7)}
    g = graph.to_networkx()  # the lift joins the storeys: Room B reaches the hall
    room_b = next(
        ("ground-floor", i)
        for i, v in enumerate(graph.storey("ground-floor").vertices)
        if v.name.endswith("Room_B")
    )
    hall = next(
        ("first-floor", i)
        for i, v in enumerate(graph.storey("first-floor").vertices)
        if v.name.endswith("Hall")
    )
    assert nx.has_path(g, room_b, hall)


def test_configured_waypoints_are_vertices_with_their_flags(lab_with_lift: tuple[GraphStore, Scene]) -> None:
    store, scene = lab_with_lift
    graph = _graph(
        store,
        scene,
        0.25,
        waypoints={
            "charger1": {"storey": "first-floor", "x": 13.0, "y": 7.0, "charger": True},
            "desk": {"at": "Room A", "parking_spot": True},
        },
    )
    first = {v.name: v for v in graph.storey("first-floor").vertices}
    ground = {v.name: v for v in graph.storey("ground-floor").vertices}
    assert first["charger1"].charger and (first["charger1"].x, first["charger1"].y) == (13.0, 7.0)
    assert ground["desk"].parking_spot and 10.0 < ground["desk"].x < 14.0
    g = graph.to_networkx()
    assert g.degree[("first-floor", list(first).index("charger1"))] >= 1


def test_a_robot_wider_than_every_door_is_refused_in_one_line(
    lab_with_lift: tuple[GraphStore, Scene],
) -> None:
    store, scene = lab_with_lift
    with pytest.raises(
        RouteError, match=r"radius 0.5 m .* fits through none of the model's 1 doors \(the widest is 0.90 m\)"
    ):
        _graph(store, scene, 0.5)


def test_a_storey_without_free_space_is_refused_in_one_line(lab_with_lift: tuple[GraphStore, Scene]) -> None:
    store, scene = lab_with_lift
    with pytest.raises(
        RouteError, match=r"storey 'ground-floor' has no free space for its robot .*radius 3.0 m"
    ):
        _graph(store, scene, 3.0)
    with pytest.raises(RouteError, match=r"storey 'first-floor' has no free space"):
        _graph(store, scene, 3.0, storeys=["first-floor"])


def test_an_unknown_storey_or_waypoint_space_is_refused(lab_with_lift: tuple[GraphStore, Scene]) -> None:
    store, scene = lab_with_lift
    with pytest.raises(RouteError, match="storey 'roof' is not a storey of this model"):
        _graph(store, scene, 0.25, storeys=["roof"])
    with pytest.raises(RouteError, match="waypoint 'w' is at 'Attic', which names no space"):
        _graph(store, scene, 0.25, waypoints={"w": {"at": "Attic"}})


def test_lanes_stay_over_the_floor_unless_the_skill_goes_outdoors(
    lab_with_lift: tuple[GraphStore, Scene],
) -> None:
    store, scene = lab_with_lift
    inside = _graph(store, scene, 0.25).storey("first-floor")  # the hall floats: no ground around it
    outside = _graph(store, scene, 0.25, outdoors=True).storey("first-floor")
    assert all(10.0 <= v.x <= 22.0 and 5.0 <= v.y <= 9.0 for v in inside.vertices)
    assert any(v.y < 4.5 for v in outside.vertices)  # the map's free margin round the building
    ground = _graph(store, scene, 0.25).storey("ground-floor")  # Door A's outside: a pad of ground
    assert min(v.y for v in ground.vertices) < 4.9 < max(v.y for v in ground.vertices)
    assert all(v.y > 3.0 for v in ground.vertices)


def test_names_are_sanitised_and_made_unique() -> None:
    taken: set[str] = set()
    assert [unique(sanitise(n), taken) for n in ("Door A", "Door-A", "", "Raum ü 1")] == [
        "Door_A",
        "Door_A_2",
        "unnamed",
        "Raum_1",
    ]


def _close_pair_ratios(store: GraphStore, scene: Scene, spacing_m: float) -> np.ndarray:
    """Route over straight distance for 200 pairs of free cells 0.4-1.5 m apart that see each other on
    the ground floor (0.25 m robot), each end joined to the best of its 16 nearest vertices it sees."""
    routes = parse_routes("fleet", {"kind": "routes", "navigation": "nav", "spacing_m": spacing_m})
    storey = build_routes(store, scene, routes, _skills(0.25)).storey("ground-floor")
    _, free = routable_cells(prepare_routes(store, scene, routes, _skills(0.25)), "ground-floor")
    frame = _free(store, scene, _skills(0.25)["nav"], "ground-floor")[1]
    res = frame.resolution_m
    xy = np.array([(v.x, v.y) for v in storey.vertices])
    cells = np.stack([(xy[:, 1] - frame.origin_y) / res - 0.5, (xy[:, 0] - frame.origin_x) / res - 0.5], 1)
    g = nx.Graph()
    for lane in storey.lanes:
        g.add_edge(lane.a, lane.b, weight=float(np.hypot(*(xy[lane.a] - xy[lane.b]))))
    tree = cKDTree(cells)
    rng = np.random.default_rng(7)
    pts = np.argwhere(free).astype(np.float64)

    def joins(p: np.ndarray) -> list[tuple[int, float]]:
        d, near = tree.query(p, k=16)
        seen = segments_free(free, np.repeat(p[None], 16, axis=0), cells[near])
        return [(int(j), float(dd) * res) for j, dd, ok in zip(near, d, seen, strict=True) if ok]

    ratios: list[float] = []
    while len(ratios) < 200:
        s, t = pts[rng.integers(len(pts))], pts[rng.integers(len(pts))]
        straight = float(np.hypot(*(s - t))) * res
        if not 0.4 <= straight <= 1.5 or not segments_free(free, s[None], t[None])[0]:
            continue
        tj = dict(joins(t))
        best = min(
            ds + min((d + tj[j] for j, d in nx.single_source_dijkstra_path_length(g, i).items() if j in tj))
            for i, ds in joins(s)
        )
        ratios.append(best / straight)
    return np.array(ratios)


def test_close_points_route_almost_straight_with_half_metre_vertex_spacing(
    lab_with_lift: tuple[GraphStore, Scene],
) -> None:
    store, scene = lab_with_lift
    fine, coarse = (_close_pair_ratios(store, scene, s) for s in (0.5, 1.5))
    assert np.median(fine) <= 1.1 and np.percentile(fine, 90) <= 1.3
    assert np.percentile(coarse, 90) > 2.0  # vertices 1.5 m apart: close points detour to reach one


def test_only_a_transport_element_of_a_lift_type_is_a_lift() -> None:
    store = imported(lift_lab(lift_type="ESCALATOR"))
    scene = load_scene(store)
    graph = _graph(store, scene, 0.25)
    assert graph.lifts == () and not any(v.lift for s in graph.storeys for v in s.vertices)
    assert not any(  # the escalator is an obstacle: no vertex in its footprint
        LIFT.xmin < v.x < LIFT.xmax and LIFT.ymin < v.y < LIFT.ymax
        for v in graph.storey("ground-floor").vertices
    )
    (escalator,) = _graph(store, scene, 0.25, lift_types=["escalator"]).lifts
    assert escalator.storeys == ("ground-floor", "first-floor")


def test_a_one_handed_door_lists_its_hinge_first_and_its_swing() -> None:
    for operation, hinge_x, swing in (("SINGLE_SWING_LEFT", 11.55, -1), ("SINGLE_SWING_RIGHT", 12.45, 1)):
        store = imported(lift_lab(door_operation=operation))
        (door,) = _graph(store, load_scene(store), 0.25).doors
        assert (door.operation, door.swing) == (operation, swing)
        assert door.endpoints[0][0] == pytest.approx(hinge_x)
