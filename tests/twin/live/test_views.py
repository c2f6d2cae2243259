"""Views that saw it: only what a view's sensor could see collects misses. Concave views and holes are
tested by area; with the sensor's origin (``twin:origin``) the elements the twin holds and the boxes
reported with the view hide what stands behind them; an element detected in the same observation is
never missed by its view."""

from __future__ import annotations

from dataclasses import replace

import pytest

from tests.twin.box_lab import OX, OY
from tests.twin.fusion.fusion_helpers import at, sensed
from tests.twin.live_helpers import PREFIX, box_turtle, observe, started
from twin.config import Limits
from twin.errors import ObservationError
from twin.live import TwinService
from twin.live.parse import parse_observation_document

BENCH = "urn:robot1:bench"
SPOT = "urn:robot1:box-in-the-open"
ROOM_B = [(8.1, 0.1), (11.9, 0.1), (11.9, 3.9), (8.1, 3.9)]
SENSOR = (10.0, 0.3, 0.6)  # the robot's camera in Room B's south, 0.6 m above the floor


def points(ring: list[tuple[float, float]]) -> str:
    return " ".join(f"{OX + x} {OY + y}" for x, y in ring)


def view(
    ns: int,
    polygons: list[list[tuple[float, float]]],
    *,
    holes: list[list[tuple[float, float]]] = (),  # type: ignore[assignment]
    origin: tuple[float, float, float] | None = None,
    body: str = "",
) -> bytes:
    terms = [f'twin:polygon "{points(p)}"' for p in polygons] + [f'twin:hole "{points(h)}"' for h in holes]
    if origin is not None:
        terms.append(f'twin:origin "{OX + origin[0]} {OY + origin[1]} {origin[2]}"')
    return (
        PREFIX
        + body
        + '[] a twin:View ; twin:storey "ground-floor" ; twin:detects "IfcFurnishingElement" ; '
        + f"twin:senseTime {at(ns)} ; "
        + " ; ".join(terms)
        + " .\n"
    ).encode()


def room_b_with(service: TwinService, *extra: bytes) -> int:
    """The bench (2.4 x 0.5 x 0.5 m across Room B), a box in the open near the east wall, and ``extra``;
    returns a sense time after them."""
    t = service.clock() - 20 * 10**9
    observe(service, "robot1", sensed(box_turtle(BENCH, 10.0, 2.0, sx=2.4, sy=0.5, sz=0.5), t))
    observe(service, "robot1", sensed(box_turtle(SPOT, 11.5, 0.6, sx=0.4, sy=0.4, sz=0.4), t))
    for payload in extra:
        assert observe(service, "robot1", sensed(payload, t)).ok
    return t


def three_views(service: TwinService, t: int, make: object) -> None:
    for i in range(1, 4):  # three views over 1.5 s: enough to remove what they should have seen
        reply = observe(service, "robot2", make(t + i * 5 * 10**8))  # type: ignore[operator]
        assert reply.ok, reply.body


def misses(service: TwinService, iri: str) -> int:
    track = service.live.fusion.tracks.get(iri)
    return 0 if track is None else len(track.misses)


def test_a_bench_standing_in_a_concave_view_across_its_notch_is_not_missed() -> None:
    service, _ = started()
    t = room_b_with(service)
    slot = [(10.2, 3.9), (10.2, 1.5), (9.8, 1.5), (9.8, 3.9)]  # cut from the north edge down to y = 1.5
    notch = [(8.1, 0.1), (11.9, 0.1), (11.9, 3.9), *slot, (8.1, 3.9)]
    three_views(service, t, lambda ns: view(ns, [notch]))
    assert not service.states[BENCH].removed and misses(service, BENCH) == 0
    assert service.states[SPOT].removed  # the views do see what stands wholly in them


def test_a_person_s_shadow_left_out_as_a_hole_keeps_the_bench_behind_the_person() -> None:
    service, _ = started()
    t = room_b_with(service)
    shadow = [(9.8, 1.2), (10.2, 1.2), (10.8, 3.9), (9.2, 3.9)]  # behind a person at (10, 1)
    three_views(service, t, lambda ns: view(ns, [ROOM_B], holes=[shadow], origin=SENSOR))
    assert not service.states[BENCH].removed and misses(service, BENCH) == 0
    assert service.states[SPOT].removed


def test_without_the_shadow_the_bench_the_person_hid_is_removed() -> None:
    service, _ = started()
    t = room_b_with(service)
    three_views(service, t, lambda ns: view(ns, [ROOM_B]))
    assert service.states[BENCH].removed and service.states[SPOT].removed


def test_a_cabinet_the_twin_holds_taller_than_the_sensor_hides_the_bench_from_a_view_with_an_origin() -> None:
    service, _ = started()
    cabinet = box_turtle("urn:ops:cabinet", 10.0, 1.0, sx=1.2, sy=0.4, sz=1.8, cls="IfcBuildingElementProxy")
    t = room_b_with(service, cabinet)
    three_views(service, t, lambda ns: view(ns, [ROOM_B], origin=SENSOR))
    assert not service.states[BENCH].removed and misses(service, BENCH) == 0
    assert service.states[SPOT].removed  # beside the cabinet: in plain sight


def test_a_person_reported_with_the_view_hides_the_bench_though_the_twin_does_not_hold_the_person() -> None:
    service, _ = started()
    t = room_b_with(service)
    rules = service.config.fusion  # one-off person IRIs are never created: held as tentative (by IRI,
    # not by place as a streaming robot's new objects are: stream_sightings = 1)
    held = replace(rules, tentative_sightings=2, stream_sightings=1)
    service.observer.config = replace(service.config, fusion=held)

    def with_person(ns: int) -> bytes:
        person = (
            f'<urn:robot2:person-{ns}> twin:ifcClass "IfcBuildingElementProxy" ; '
            'twin:storey "ground-floor" ; '
            f'twin:box "{OX + 10.0} {OY + 1.0} 0.9 1.0 0.4 1.8 0" .\n'
        )
        return view(ns, [ROOM_B], origin=SENSOR, body=person)

    three_views(service, t, with_person)
    assert not service.states[BENCH].removed and misses(service, BENCH) == 0
    assert not any("person" in iri for iri in service.states)
    assert service.states[SPOT].removed


def test_an_element_detected_in_the_observation_is_never_missed_by_its_view() -> None:
    service, _ = started()
    t = room_b_with(service)
    seen = [
        box_turtle("urn:robot2:b", 10.02, 2.0, sx=2.4, sy=0.5, sz=0.5),  # resolved: a confirmation
        box_turtle("urn:robot2:b", 10.2, 2.0, sx=2.4, sy=0.5, sz=0.5),  # a short move: held as unsure
        box_turtle("urn:robot2:b", 10.9, 2.3, sx=2.4, sy=0.5, sz=0.5),  # a move, applied
    ]
    for i, body in enumerate(seen):
        ns = t + (i + 1) * 6 * 10**8
        element = body.decode().removeprefix(PREFIX)
        reply = observe(service, "robot2", view(ns, [ROOM_B], origin=SENSOR, body=element))
        assert reply.ok and reply.body.get("resolved", {}).get("urn:robot2:b") == BENCH, reply.body
    assert not service.states[BENCH].removed and misses(service, BENCH) == 0


def test_a_view_s_origin_and_holes_are_parsed_and_a_bad_origin_is_refused_naming_it() -> None:
    doc = view(1_800_000_000 * 10**9, [ROOM_B], holes=[[(9, 1), (10, 1), (10, 2)]], origin=SENSOR)
    v = parse_observation_document(doc, limits=Limits()).view
    assert v is not None and v.origin == (OX + 10.0, OY + 0.3, 0.6) and len(v.holes) == 1
    bad = doc.replace(f'twin:origin "{OX + 10.0} {OY + 0.3} 0.6"'.encode(), b'twin:origin "1 2"')
    with pytest.raises(ObservationError, match=r"twin:origin must be 3 numbers, got 2 in '1 2'"):
        parse_observation_document(bad, limits=Limits())
