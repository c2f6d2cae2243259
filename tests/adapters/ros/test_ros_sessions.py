"""Tracker sessions: a reused tracker id after the detector restarts names a new object; a daemon
restart continues the session."""

from __future__ import annotations

from adapters.ros.detections import DetectionSettings, translate_detections
from adapters.ros.sessions import TrackerSession, session_iri, sessions_from_iris
from tests.adapters.ros.test_ros_detections import NOW, TABLE_IN_CAMERA, ctx
from tests.adapters.ros_reports import cdr_detections

S = 10**9
GAP = 10 * S


def test_ids_that_keep_counting_stay_one_session_and_ids_going_back_start_a_new_one() -> None:
    s = TrackerSession()
    first = s.observe(NOW, ["1", "2"], gap_ns=GAP)
    assert first == f"s{NOW // S}"
    for i in range(3, 40):  # a tracker's ids, a few new ones out of order near the top
        assert s.observe(NOW + i * S // 10, [str(i), str(i - 1), str(i + 2)], gap_ns=GAP) == first
    again = s.observe(NOW + 5 * S, ["1", "3"], gap_ns=GAP)  # restarted: 1 and 3 again, long gone
    assert again != first and s.restarts == 1
    assert s.observe(NOW + 5 * S + S // 10, ["3", "4"], gap_ns=GAP) == again


def test_a_stamp_gap_or_a_stamp_going_back_starts_a_new_session() -> None:
    s = TrackerSession()
    a = s.observe(NOW, ["5"], gap_ns=GAP)
    b = s.observe(NOW + 11 * S, ["5"], gap_ns=GAP)
    c = s.observe(NOW + 3 * S, ["5"], gap_ns=GAP)
    assert len({a, b, c}) == 3 and s.restarts == 2


def test_a_daemon_restart_resumes_the_latest_session_from_the_twins_iris() -> None:
    iris = [
        session_iri("robot1", "s100", "3"),
        session_iri("robot1", "s200", "7"),
        session_iri("robot1", "s200", "9"),
    ]
    resumed = sessions_from_iris([*iris, "urn:robot2:x"], ["robot1", "robot2"])
    s = resumed["robot1"]
    assert s.label == "s200" and set(s.ids) == {"7", "9"}
    assert s.observe(NOW, ["9", "10"], gap_ns=GAP) == "s200"  # the same tracker still running
    assert resumed["robot2"].started_s is None


def test_the_adapter_iris_carry_the_session_and_a_restarted_detector_gets_new_ones() -> None:
    settings = DetectionSettings(robot="robot1", classes={"table": "IfcFurniture"})
    session = TrackerSession()
    one = translate_detections(
        cdr_detections(NOW, "camera_optical_frame", [TABLE_IN_CAMERA]), settings, ctx(session=session)
    )
    assert one.iris == (session_iri("robot1", f"s{NOW // S}", "7"),)
    session.highest, session.ids = 40, {"40": NOW}  # a tracker that had counted to 40, 7 long gone ...
    later = NOW + 50_000_000
    two = translate_detections(
        cdr_detections(later, "camera_optical_frame", [TABLE_IN_CAMERA]),
        settings,
        ctx(session=session, now_ns=later),
    )
    assert two.iris != one.iris and two.iris[0].endswith(":7")  # ... issues a new 7: a new session
