"""Typed reports inside the process: a Detection3DArray handed to the core as its typed records gives
the same twin as the same array written as Turtle and parsed again, and the records pass the same
validator as a parsed document."""

from __future__ import annotations

import math
import pickle
from dataclasses import astuple, replace

import numpy as np
import pytest

from adapters.ros.detections import DetectionContext, DetectionSettings, translate_detections
from adapters.ros.observation_doc import (
    BoxReport,
    ViewReport,
    _m,
    _rad,
    _ring,
    observation_records,
    observation_turtle,
)
from adapters.ros.tf import TfBuffer, decode_tf_message
from tests.adapters.ros_reports import Det, Tf, cdr_detections, cdr_tf, yaw_quaternion
from tests.conftest import imported
from tests.twin.box_lab import OX, OY, box_lab
from tests.twin.live_helpers import started
from twin.config import Limits, load_config
from twin.errors import ObservationError
from twin.graph.vocab import FURN
from twin.live import Reply, TwinService
from twin.live.parse import parse_observation_document
from twin.live.validate import Checked, check_observation, checked, limits_key
from twin.records import ElementReport, Observation, ObservedBox, ObservedView

S = 1_000_000_000
T0 = 1_800_000_000 * S + 123_456_789  # a stamp whose nanoseconds the Turtle path cuts to microseconds
ROOM_B = (OX + 10.0, OY + 2.0)  # the robot stands in Room B of the box lab, looking along +x


def arrays() -> list[tuple[int, list[Det]]]:
    """Four arrays over 1.5 s: three tables (one turned, one at a negative local y) seen, one moved
    0.8 m, then one left out of the view (a miss), then seen again."""

    def tables(moved: float, without: int | None = None) -> list[Det]:
        spots = [(0.9, 0.3, 0.3), (1.2, -0.4 + moved, -1.1), (1.5, 0.5, 2.0)]
        return [
            Det((("table", 0.9),), (x, y, 0.375), (0.5, 0.4, 0.75), yaw_quaternion(yaw), id=f"t{i}")
            for i, (x, y, yaw) in enumerate(spots)
            if i != without
        ]

    return [(T0, tables(0.0)), (T0 + S // 2, tables(0.8)), (T0 + S, tables(0.8, without=2)),
            (T0 + 3 * S // 2, tables(0.8))]  # fmt: skip


def feed(typed: bool) -> TwinService:
    now = [T0]
    service = TwinService(imported(box_lab()), load_config(), clock=lambda: now[0])  # the same times
    service.start()
    settings = DetectionSettings(robot="robot1", classes={"table": "IfcFurniture"}, range_m=3.0)
    tf = TfBuffer()
    for stamp, dets in arrays():
        now[0] = stamp + S // 10
        tf.add(
            decode_tf_message(cdr_tf([Tf("map", "base_link", (*ROOM_B, 0.2), stamp_ns=stamp)])), static=False
        )
        ctx = DetectionContext("ground-floor", 0.0, now[0], tf)
        t = translate_detections(cdr_detections(stamp, "base_link", dets), settings, ctx, typed=typed)
        assert t.document is not None and not t.refused
        replies: list[Reply] = []
        service.submit_observation("robot1", t.document, replies.append)
        service.process()
        assert [r.ok for r in replies] == [True], replies[0].body
    return service


def quads(service: TwinService) -> set[tuple[str, ...]]:
    rows = service.store.select("SELECT ?g ?s ?p ?o WHERE { GRAPH ?g { ?s ?p ?o } }")
    rows += service.store.select("SELECT ?s ?p ?o WHERE { ?s ?p ?o }")
    return {tuple(str(v) for v in r.values()) for r in rows}


def test_arrays_through_the_typed_path_and_through_turtle_give_the_same_twin() -> None:
    by_turtle, typed = feed(typed=False), feed(typed=True)
    assert quads(by_turtle) == quads(typed)
    assert by_turtle.revision == typed.revision > 1
    assert by_turtle.states == typed.states
    assert by_turtle.live.fusion.tracks.keys() == typed.live.fusion.tracks.keys()
    missed = {iri: len(t.misses) for iri, t in typed.live.fusion.tracks.items()}
    assert missed == {iri: len(t.misses) for iri, t in by_turtle.live.fusion.tracks.items()}


def test_the_typed_records_are_what_the_turtle_parses_to() -> None:
    box = BoxReport(
        "urn:twin-ros:r:det:t%2F1",
        "IfcFurniture",
        "ground-floor",
        (1.00004, -2.5, 0.375, 0.5, 0.4, 0.75, 7.0),
    )
    other = BoxReport(
        "urn:twin-ros:r:det:t", "IfcFurniture", "ground-floor", (-0.00001, 2, 0.3, 0.2, 0.2, 0.6, -1e-9)
    )
    rings = (((0.0, 0.0), (3.00006, -1.0), (3.0, 1.0)), ((0, 0), (1, 1)))  # the second too short: dropped
    hole = ((1.0, 0.0), (2.0, 0.1), (2.0, -0.1))
    view = ViewReport("ground-floor", rings, ("IfcFurniture",), holes=(hole,), origin=(0.1, 0.2, 0.35))
    for kwargs in ({"view": view}, {"view": None}, {"view": view, "fusion_terms": False}):
        args = {"boxes": [box, other], "sense_ns": T0, **kwargs}
        turtle = observation_turtle(**args)  # type: ignore[arg-type]
        records = observation_records(**args)  # type: ignore[arg-type]
        assert turtle is not None and records is not None
        parsed = parse_observation_document(turtle, limits=Limits())
        assert [r.iri for r in records.reports] == [r.iri for r in parsed.reports]
        assert [astuple(r) for r in records.reports] == [astuple(r) for r in parsed.reports]
        assert (records.view is None) == (parsed.view is None)
        if parsed.view is not None and records.view is not None:
            v, w = records.view, parsed.view
            assert (v.storey, v.detects, v.sense_ns, v.origin) == (w.storey, w.detects, w.sense_ns, w.origin)
            for ours, theirs in zip(
                records.view.polygons + records.view.holes,
                parsed.view.polygons + parsed.view.holes,
                strict=True,
            ):
                assert ours.tolist() == theirs.tolist()


@pytest.mark.parametrize(
    ("box", "match"),
    [
        ((0, 0, 0.3, 0.0, 0.2, 0.6, 0), "box size sx=0.0 m is outside"),
        ((math.nan, 0, 0.3, 0.2, 0.2, 0.6, 0), "NaN or infinite"),
        ((0, 0, 0.3, 0.2, 999.0, 0.6, 0), "box size sy=999.0 m is outside"),
    ],
)
def test_typed_records_are_refused_by_the_same_checks_as_a_parsed_document(
    box: tuple[float, ...], match: str
) -> None:
    report = BoxReport("urn:twin-ros:r:det:1", "IfcFurniture", "ground-floor", box)  # type: ignore[arg-type]
    records = observation_records(boxes=[report])
    assert records is not None
    with pytest.raises(ObservationError, match=match):
        check_observation(records, limits=Limits())
    turtle = observation_turtle(boxes=[report])
    assert turtle is not None
    with pytest.raises(ObservationError, match=match):
        parse_observation_document(turtle, limits=Limits())


def test_a_refused_typed_observation_is_answered_with_the_reason_and_the_twin_keeps_running() -> None:
    service, _ = started()
    bad = observation_records(
        boxes=[BoxReport("not an iri", "IfcFurniture", "ground-floor", (0, 0, 0.3, 0.2, 0.2, 0.6, 0))]
    )
    assert bad is not None
    replies: list[Reply] = []
    service.submit_observation("robot1", bad, replies.append)
    service.process()
    assert not replies[0].ok and "is not an absolute IRI" in str(replies[0].body["error"])


def test_a_descriptive_type_goes_the_same_way_and_a_foreign_one_is_refused_on_both_paths() -> None:
    furn = FURN + "Chair"
    box = BoxReport(
        "urn:twin-ros:r:det:1", "IfcFurniture", "ground-floor", (0, 0, 0.4, 0.5, 0.5, 0.8, 0), kind=furn
    )
    records, turtle = observation_records(boxes=[box]), observation_turtle(boxes=[box])
    assert records is not None and turtle is not None
    assert (
        records.reports[0].classes == parse_observation_document(turtle, limits=Limits()).reports[0].classes
    )
    foreign = replace(box, kind="http://example.org/Chair")
    records, turtle = observation_records(boxes=[foreign]), observation_turtle(boxes=[foreign])
    assert records is not None and turtle is not None
    with pytest.raises(ObservationError, match="is not allowed; only BEO and FURN"):
        check_observation(records, limits=Limits())
    with pytest.raises(ObservationError, match="is not allowed; only BEO and FURN"):
        parse_observation_document(turtle, limits=Limits())


def test_a_view_s_points_are_rounded_at_once_as_the_turtle_path_rounds_each() -> None:
    rng = np.random.default_rng(3)
    values = [*rng.uniform(-300.0, 300.0, 4000).tolist(), *(k / 1e4 + 5e-5 for k in range(-300, 300))]
    values += [float(np.nextafter(v, d)) for v in values[-600:] for d in (-1e9, 1e9)] + [-0.0, 1e-9, -1e-9]
    ring = list(zip(values[::2], values[1::2], strict=False))
    got = _ring(ring)
    want = np.array([(_m(x), _m(y)) for x, y in ring])
    assert np.array_equal(got, want)
    assert not np.signbit(got).any() or np.array_equal(np.signbit(got), np.signbit(want))


def test_a_box_s_numbers_are_rounded_at_once_as_the_turtle_path_rounds_each() -> None:
    rng = np.random.default_rng(5)
    ties = [k / 1e4 + 5e-5 for k in range(-40, 40)]  # halves of the last digit, and their neighbours
    near = [float(np.nextafter(v, d)) for v in ties for d in (-1e9, 1e9)]
    metres = [*rng.uniform(-300.0, 300.0, 600).tolist(), *ties, *near, -0.0, 1e-9, -1e-9, 3]
    yaws = [*rng.uniform(-7.0, 7.0, 600).tolist(), *(k / 1e6 + 5e-7 for k in range(-40, 40)), -0.0, math.pi]
    rows = [(*metres[i : i + 6], yaws[i % len(yaws)]) for i in range(0, len(metres) - 6, 6)]
    boxes = [BoxReport(f"urn:r:{i}", "IfcFurniture", "g", row) for i, row in enumerate(rows)]
    records = observation_records(boxes=boxes, fusion_terms=False)
    assert records is not None
    got = {r.iri: astuple(r.box) for r in records.reports if r.box is not None}
    for b in boxes:
        want = (*(_m(v) for v in b.box[:6]), _rad(b.box[6]))
        assert [struct_bits(v) for v in got[b.iri]] == [struct_bits(v) for v in want], b.box


def struct_bits(v: float) -> bytes:
    return np.float64(v).tobytes()


def test_typed_records_come_back_from_a_worker_with_every_field() -> None:
    box = ObservedBox(1.0, 2.0, 0.375, 0.8, 0.6, 0.75, 0.1)
    report = ElementReport(
        "urn:r:1", "IfcFurniture", "ground-floor", box, labels=("a",), classes=(FURN + "Table",),
        sense_ns=T0, distinct=True, lifetime_s=2.5,
    )  # fmt: skip
    view = ObservedView("ground-floor", (np.zeros((3, 2)),), ("IfcFurniture",), T0, origin=(1.0, 2.0, 1.2))
    back = pickle.loads(pickle.dumps(Observation((report,), view), protocol=pickle.HIGHEST_PROTOCOL))
    assert astuple(back.reports[0].box) == astuple(box)
    got = back.reports[0]
    assert [getattr(got, n) for n in ElementReport.__slots__ if n != "box"] == [
        getattr(report, n) for n in ElementReport.__slots__ if n != "box"
    ]
    assert back.view is not None and back.view.origin == view.origin and back.view.sense_ns == T0
    assert np.array_equal(back.view.polygons[0], view.polygons[0])


def test_records_a_worker_checked_under_the_writers_limits_are_not_checked_again() -> None:
    box = (1, 2, 0.3, 0.4, 0.4, 0.6, 0)
    good = observation_records(boxes=[BoxReport("urn:twin-ros:r:det:1", "IfcFurniture", "ground-floor", box)])
    bad = observation_records(
        boxes=[BoxReport("not an iri", "IfcFurniture", "ground-floor", (0, 0, 0.3, 0.2, 0.2, 0.6, 0))]
    )
    assert good is not None and bad is not None
    made = checked(good, limits=Limits())
    assert isinstance(made, Checked) and made.observation is good and made.passed(Limits())
    assert not made.passed(Limits(box_size_m=0.3))  # a writer with other limits checks it again
    assert checked(bad, limits=Limits()) is bad  # goes on unmarked: the writer refuses it
    back = pickle.loads(pickle.dumps(made, protocol=pickle.HIGHEST_PROTOCOL))
    assert isinstance(back, Checked) and back.limits == made.limits
    assert [astuple(r) for r in back.observation.reports] == [astuple(r) for r in good.reports]
    service, _ = started()
    replies: list[list[Reply]] = [[], [], []]
    service.submit_observation("robot1", checked(bad, limits=Limits()), replies[0].append)
    trusted = Checked(bad, limits_key(service.config.limits))  # (marked as a worker marks what passed)
    service.submit_observation("robot1", trusted, replies[1].append)
    other = Checked(bad, limits_key(Limits(box_size_m=49.0)))  # checked under other limits
    service.submit_observation("robot1", other, replies[2].append)
    service.process()
    [unmarked], [taken], [rechecked] = replies
    assert not unmarked.ok and "is not an absolute IRI" in str(unmarked.body["error"])
    assert not taken.ok and "is not an absolute IRI" not in str(taken.body["error"])  # not checked again
    assert not rechecked.ok and "is not an absolute IRI" in str(rechecked.body["error"])


def test_a_translator_with_the_twins_limits_hands_over_checked_records() -> None:
    from adapters.zenoh.ros_workers import RobotSpec, RobotTranslator, Translated

    settings = DetectionSettings(robot="r", classes={"table": "IfcFurniture"}, range_m=3.0)
    documents = []
    for limits in (Limits(), None):
        t = RobotTranslator(
            [RobotSpec("r", settings, None)], fusion_terms=True, typed=True, clock=lambda: T0, limits=limits
        )
        t.set_storey("r", "ground-floor")
        t.handle("r", "tf", cdr_tf([Tf("map", "base_link", (*ROOM_B, 0.2), stamp_ns=T0)]), 0)
        (out,) = t.handle("r", "detections", cdr_detections(T0, "base_link", arrays()[0][1]), 0)
        assert isinstance(out, Translated)
        documents.append(out.translation.document)
    made, plain = documents
    assert isinstance(made, Checked) and made.passed(Limits())
    assert isinstance(plain, Observation)  # (no limits: the writer checks it)
    assert [astuple(r) for r in made.observation.reports] == [astuple(r) for r in plain.reports]


def test_a_workers_outcome_comes_back_whole_and_its_records_stay_frozen() -> None:
    from dataclasses import FrozenInstanceError

    from adapters.ros.observation_doc import Translation
    from adapters.ros.sessions import TrackerSession
    from adapters.zenoh.ros_workers import Translated

    report = ElementReport("urn:r:1", "IfcFurniture", "g", ObservedBox(1.0, 2.0, 0.4, 0.8, 0.6, 0.75, 0.1))
    ids: dict[str, int | None] = {"t0": T0, "t1": None}
    session = TrackerSession(started_s=17, ids=ids, highest=3, last_stamp_ns=T0, restarts=2)
    t = Translation(
        Observation((report,)), iris=("urn:r:1",), ignored={"class": 2}, refused=(("malformed", "x"),),
        extra=(b"doc",), removes=("urn:r:2",),
    )  # fmt: skip
    back = pickle.loads(pickle.dumps(Translated("robot0", t, 42, session), protocol=pickle.HIGHEST_PROTOCOL))
    assert (back.owner, back.received_ns) == ("robot0", 42)
    assert back.session == session and back.session is not session
    assert back.translation.iris == t.iris and back.translation.ignored == {"class": 2}
    assert back.translation.refused == t.refused and back.translation.extra == (b"doc",)
    assert back.translation.removes == ("urn:r:2",) and back.translation.settle is None
    assert isinstance(back.translation.document, Observation)
    got = back.translation.document.reports[0]
    assert got.iri == "urn:r:1" and got.box == report.box and got.removed is False
    with pytest.raises(FrozenInstanceError):
        got.iri = "urn:r:other"  # type: ignore[misc]
    assert got.box is not None
    with pytest.raises(FrozenInstanceError):
        got.box.cx = 0.0  # type: ignore[misc]


def test_a_record_that_checks_itself_gets_no_maker_that_would_skip_the_check() -> None:
    from dataclasses import dataclass

    from twin.records import _maker

    @dataclass(frozen=True, slots=True)
    class Checked:
        x: float

        def __post_init__(self) -> None:
            if self.x < 0:
                raise ValueError(self.x)

    with pytest.raises(TypeError, match="__post_init__"):
        _maker(Checked, "_make_checked")


def test_a_boxed_report_made_without_the_dataclass_init_has_every_field_the_init_gives() -> None:
    from twin.records import boxed_report

    box = (1.5, -2.25, 0.375, 0.2, 0.3, 0.75, -1.25)
    cases = [(("t1",), (FURN + "Table",), 17_000, 2.5), ((), (), None, None)]
    for labels, classes, sense_ns, lifetime_s in cases:
        fast = boxed_report(
            "urn:x", "IfcFurniture", "urn:s", box, labels=labels, classes=classes, sense_ns=sense_ns,
            lifetime_s=lifetime_s,
        )  # fmt: skip
        slow = ElementReport(
            "urn:x", ifc_class="IfcFurniture", storey="urn:s", box=ObservedBox(*box), labels=labels,
            classes=classes, sense_ns=sense_ns, lifetime_s=lifetime_s,
        )  # fmt: skip
        assert astuple(fast) == astuple(slow)
        assert type(fast) is ElementReport and type(fast.box) is ObservedBox
