"""Detection3DArray -> observation: classes, scores, TF at the stamp, tilt, IRIs, the view; TF and the
visibility polygon on their own."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pyoxigraph as ox
import pytest
from shapely.geometry import Point, Polygon
from shapely.ops import unary_union

from adapters.ros.detections import (
    DetectionContext,
    DetectionSettings,
    array_header,
    camera_fov,
    translate_detections,
)
from adapters.ros.observation_doc import RosInputError
from adapters.ros.tf import TfBuffer, TfError, decode_tf_message
from adapters.ros.view import polygon_area, visibility_polygon
from tests.adapters.ros_reports import OPTICAL, Cdr, Det, Tf, cdr_detections, cdr_tf, yaw_quaternion
from twin.maps.grid import GridFrame, OccupancyGrid

NOW = 1_700_000_000_000_000_000
TWIN = "https://w3id.org/building-twin#"
SETTINGS = DetectionSettings(
    robot="robot1", classes={"table": "IfcFurniture", "chair": "IfcSystemFurnitureElement"}, optical=True
)


def robot_tf(base=(14.0, 7.0), yaw: float = 0.0) -> TfBuffer:
    """map -> base_link (timed, two samples 0.2 s apart) -> camera_link -> camera_optical_frame (static)."""
    tf = TfBuffer()
    tf.add(
        decode_tf_message(
            cdr_tf(
                [
                    Tf(
                        "map",
                        "base_link",
                        (base[0] - 1.0, base[1], 0.0),
                        yaw_quaternion(yaw),
                        NOW - 100_000_000,
                    ),
                    Tf(
                        "map",
                        "base_link",
                        (base[0] + 1.0, base[1], 0.0),
                        yaw_quaternion(yaw),
                        NOW + 100_000_000,
                    ),
                ]
            )
        ),
        static=False,
    )
    tf.add(
        decode_tf_message(
            cdr_tf(
                [
                    Tf("base_link", "camera_link", (0.2, 0.0, 1.0)),
                    Tf("camera_link", "camera_optical_frame", (0, 0, 0), OPTICAL),
                ]
            )
        ),
        static=True,
    )
    return tf


def ctx(tf: TfBuffer | None = None, **kw: object) -> DetectionContext:
    base = {"storey": "ground-floor", "elevation_m": 0.0, "now_ns": NOW, "tf": tf or robot_tf()}
    return DetectionContext(**{**base, **kw})  # type: ignore[arg-type]


def triples(doc: bytes | None) -> dict[tuple[str, str], list[str]]:
    assert doc is not None
    out: dict[tuple[str, str], list[str]] = {}
    for q in ox.parse(doc, format=ox.RdfFormat.TURTLE):
        out.setdefault((str(q.subject), q.predicate.value.removeprefix(TWIN)), []).append(q.object.value)
    return out


def box_of(doc: bytes | None, iri: str) -> list[float]:
    return [float(v) for v in triples(doc)[(f"<{iri}>", "box")][0].split()]


TABLE_IN_CAMERA = Det((("table", 0.9),), (0.0, 0.625, 2.4), (0.6, 0.6, 0.75), (0.5, -0.5, 0.5, 0.5), id="7")
"""The table at map (16.6, 7.0, 0.375), upright, seen from the optical frame of a camera 1 m above a
robot at (14, 7) looking along +x."""


def test_a_table_seen_in_a_camera_frame_two_tf_hops_from_the_map_lands_at_its_map_pose() -> None:
    t = translate_detections(cdr_detections(NOW, "camera_optical_frame", [TABLE_IN_CAMERA]), SETTINGS, ctx())
    iri = "urn:twin-ros:robot1:det:7"
    assert t.iris == (iri,)
    np.testing.assert_allclose(box_of(t.document, iri), [16.6, 7.0, 0.375, 0.6, 0.6, 0.75, 0.0], atol=1e-4)
    found = triples(t.document)
    assert found[(f"<{iri}>", "ifcClass")] == ["IfcFurniture"]
    assert found[(f"<{iri}>", "storey")] == ["ground-floor"]


def test_a_class_id_with_a_descriptive_type_says_what_the_object_is() -> None:
    settings = DetectionSettings(
        robot="robot1",
        classes={"table": "IfcFurniture"},
        types={"table": "http://pi.pauwel.be/voc/furniture#Table"},
    )
    t = translate_detections(cdr_detections(NOW, "camera_optical_frame", [TABLE_IN_CAMERA]), settings, ctx())
    found = triples(t.document)
    kinds = found[("<urn:twin-ros:robot1:det:7>", "http://www.w3.org/1999/02/22-rdf-syntax-ns#type")]
    assert kinds == ["http://pi.pauwel.be/voc/furniture#Table"]


def test_the_robot_pose_is_interpolated_at_the_stamp() -> None:
    later = NOW + 50_000_000  # base_link at x = 14.5
    t = translate_detections(
        cdr_detections(later, "camera_optical_frame", [TABLE_IN_CAMERA]), SETTINGS, ctx()
    )
    assert box_of(t.document, "urn:twin-ros:robot1:det:7")[0] == pytest.approx(17.1, abs=1e-4)


def test_the_document_carries_the_view_the_sense_time_and_the_classes_it_detects() -> None:
    t = translate_detections(cdr_detections(NOW, "camera_optical_frame", [TABLE_IN_CAMERA]), SETTINGS, ctx())
    found = triples(t.document)
    (view,) = [s for (s, p), v in found.items() if p.endswith("#type") and TWIN + "View" in v]
    assert sorted(found[(view, "detects")]) == ["IfcFurniture", "IfcSystemFurnitureElement"]
    assert found[(view, "senseTime")] == ["2023-11-14T22:13:20.000000Z"]
    xy = np.array(found[(view, "polygon")][0].split(), dtype=float).reshape(-1, 2)
    np.testing.assert_allclose(xy[0], [14.2, 7.0], atol=1e-4)  # the sensor: 0.2 m ahead of the base
    assert np.hypot(*(xy[1:] - xy[0]).T).max() == pytest.approx(5.0, abs=1e-3)  # range, nothing occludes
    assert (xy[1:, 0] > 14.2).all()  # a 90 deg view looking along +x


def test_without_fusion_terms_the_document_has_the_elements_alone() -> None:
    t = translate_detections(
        cdr_detections(NOW, "camera_optical_frame", [TABLE_IN_CAMERA]), SETTINGS, ctx(fusion_terms=False)
    )
    assert b"View" not in (t.document or b"") and b"senseTime" not in (t.document or b"")
    assert t.iris == ("urn:twin-ros:robot1:det:7",)


def test_unknown_classes_and_low_scores_are_ignored_and_counted() -> None:
    dets = [
        Det((("person", 0.99),), (0, 0, 2), (0.5, 0.5, 1.7)),
        Det((("table", 0.3),), (0, 0, 2), (1, 1, 1)),
        Det(
            (("chair", 0.1), ("table", 0.8)), (0.0, 0.625, 2.4), (0.6, 0.6, 0.75), (0.5, -0.5, 0.5, 0.5), "a"
        ),
    ]
    t = translate_detections(cdr_detections(NOW, "camera_optical_frame", dets), SETTINGS, ctx())
    assert t.ignored == {"unknown_class": 1, "low_score": 1}
    assert t.iris == ("urn:twin-ros:robot1:det:a",)  # the best hypothesis wins: a table


def test_empty_ids_get_one_off_iris_and_a_tracker_id_is_stable() -> None:
    dets = [
        TABLE_IN_CAMERA,
        Det((("table", 0.9),), (0.0, 0.625, 3.4), (0.6, 0.6, 0.75), (0.5, -0.5, 0.5, 0.5)),
    ]
    one = translate_detections(cdr_detections(NOW, "camera_optical_frame", dets), SETTINGS, ctx())
    two = translate_detections(cdr_detections(NOW + 1, "camera_optical_frame", dets), SETTINGS, ctx())
    assert one.iris[0] == two.iris[0] == "urn:twin-ros:robot1:det:7"
    assert one.iris[1] != two.iris[1] and ":once:" in one.iris[1]


def test_the_same_array_gives_the_same_bytes() -> None:
    payload = cdr_detections(NOW, "camera_optical_frame", [TABLE_IN_CAMERA])
    assert (
        translate_detections(payload, SETTINGS, ctx()).document
        == translate_detections(payload, SETTINGS, ctx()).document
    )


def test_a_small_roll_is_dropped_and_a_tilted_box_is_refused_without_a_view() -> None:
    def rolled(deg: float) -> Det:
        half = math.radians(deg) / 2
        return Det(
            (("table", 0.9),), (5.0, 1.0, 0.4), (1, 1, 0.8), (math.sin(half), 0.0, 0.0, math.cos(half)), "r"
        )

    ok = translate_detections(cdr_detections(NOW, "map", [rolled(5)]), SETTINGS, ctx())
    assert box_of(ok.document, "urn:twin-ros:robot1:det:r")[6] == 0.0
    bad = translate_detections(cdr_detections(NOW, "camera_optical_frame", [rolled(40)]), SETTINGS, ctx())
    assert [c for c, _ in bad.refused] == ["tilt"] and bad.document is None


@pytest.mark.parametrize(
    ("frame", "cause"),
    [("lidar", "unknown_frame"), ("", "unknown_frame")],
)
def test_an_unresolvable_frame_refuses_the_detection(frame: str, cause: str) -> None:
    t = translate_detections(cdr_detections(NOW, frame, [TABLE_IN_CAMERA]), SETTINGS, ctx())
    assert [c for c, _ in t.refused] == [cause] and t.document is None


def test_a_stamp_outside_the_tf_history_is_refused_as_extrapolation() -> None:
    t = translate_detections(
        cdr_detections(NOW - 5_000_000_000, "camera_optical_frame", [TABLE_IN_CAMERA]), SETTINGS, ctx()
    )
    assert [c for c, _ in t.refused] == ["extrapolation"]


@pytest.mark.parametrize(
    ("payload", "context", "cause"),
    [
        (b"\x00\x01\x00\x00\xff", ctx(), "malformed"),
        (cdr_detections(NOW + 10_000_000_000, "map", []), ctx(), "future"),
        (cdr_detections(NOW, "map", [TABLE_IN_CAMERA] * 300), ctx(), "oversized"),
        (
            cdr_detections(NOW, "map", [TABLE_IN_CAMERA]) + bytes(3 << 20),
            ctx(),
            "oversized",
        ),  # before decoding
        (cdr_detections(NOW, "map", []), ctx(storey=None), "no_storey"),
    ],
)
def test_a_bad_array_is_refused_whole_with_its_cause(
    payload: bytes, context: DetectionContext, cause: str
) -> None:
    with pytest.raises(RosInputError) as err:
        translate_detections(payload, SETTINGS, context)
    assert err.value.cause == cause


def test_z_is_taken_above_the_storey_when_the_map_frame_is_the_buildings() -> None:
    settings = DetectionSettings(robot="r", classes={"table": "IfcFurniture"}, z_reference="building")
    det = Det((("table", 0.9),), (5.0, 1.0, 3.4), (1, 1, 0.8), id="z")
    t = translate_detections(cdr_detections(NOW, "map", [det]), settings, ctx(elevation_m=3.0))
    assert box_of(t.document, "urn:twin-ros:r:det:z")[2] == pytest.approx(0.4)


def test_tf_lookups_compose_hops_and_name_what_is_missing() -> None:
    tf = robot_tf()
    m = tf.lookup("map", "camera_optical_frame", NOW)
    np.testing.assert_allclose(m[:3, 3], [14.2, 7.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(m[:3, 2], [1.0, 0.0, 0.0], atol=1e-9)  # optical z = forward = map +x
    inverse = tf.lookup("camera_optical_frame", "map", NOW)
    np.testing.assert_allclose(inverse @ m, np.eye(4), atol=1e-9)
    with pytest.raises(TfError, match="'lidar' is not in the robot's TF") as err:
        tf.lookup("map", "lidar", NOW)
    assert err.value.cause == "unknown_frame"


def test_the_view_stops_at_walls_of_the_structure_grid() -> None:
    data = np.zeros((100, 100), dtype=np.int8)
    data[:, 60] = 100  # a wall at x = 3.0 .. 3.05
    grid = OccupancyGrid(GridFrame(0.0, 0.0, 0.05, 100, 100), data, "s", "localization", 0.0)
    polygon = visibility_polygon(
        grid, (1.0, 2.5), heading_rad=0.0, fov_rad=math.radians(60), range_m=8.0, rays=33
    )
    xy = np.array(polygon)
    assert xy[1:, 0].max() <= 3.0 + 1e-9  # nothing beyond the wall
    assert xy[1:, 0].max() > 2.9
    assert polygon_area(polygon) < 0.5 * 2.0 * 2.0 * math.tan(math.radians(30)) * 2 + 0.1


def test_a_transform_or_frame_not_in_yet_is_one_to_wait_for_and_an_old_stamp_is_not() -> None:
    tf = robot_tf()
    assert tf.waits_for("map", "camera_optical_frame", NOW + 1_000_000_000)  # after the newest sample
    assert not tf.waits_for("map", "camera_optical_frame", NOW)
    assert not tf.waits_for("map", "camera_optical_frame", NOW - 1_000_000_000)  # before the oldest: never
    assert tf.waits_for("map", "lidar", NOW)  # nobody published it yet: it may come


def test_the_array_header_is_read_without_decoding_the_rest() -> None:
    assert array_header(cdr_detections(NOW + 5, "camera_optical_frame", [TABLE_IN_CAMERA])) == (
        "camera_optical_frame",
        NOW + 5,
    )
    assert array_header(b"\x00\x01\x00\x00\x01") is None


def test_no_view_is_claimed_while_the_structure_that_hides_its_parts_is_unknown() -> None:
    payload = cdr_detections(NOW, "camera_optical_frame", [TABLE_IN_CAMERA])
    t = translate_detections(payload, SETTINGS, ctx(occlusion_known=False))
    assert (
        t.document is not None
        and b"twin:View" not in t.document
        and b"<urn:twin-ros:robot1:det:7>" in t.document
    )


def seen_region(doc: bytes | None) -> tuple[Any, list[str]]:
    """The view's floor (shapely: its polygons less its holes) and its origin triple."""
    found = triples(doc)
    (view,) = [s for (s, p), v in found.items() if p.endswith("#type") and TWIN + "View" in v]

    def ring(text: str) -> Polygon:
        return Polygon(np.array(text.split(), dtype=float).reshape(-1, 2))

    region = unary_union([ring(p) for p in found[(view, "polygon")]])
    for hole in found.get((view, "hole"), []):
        region = region.difference(ring(hole))
    return region, found.get((view, "origin"), [])


PERSON_IN_CAMERA = Det((("person", 0.95),), (0.0, 0.1, 2.0), (0.5, 1.8, 0.4))
"""A person 2 m ahead of the camera (map (16.2, 7.0)), of a class the robot does not map."""


def test_the_view_leaves_out_the_shadow_of_every_detection_and_carries_the_sensor_s_origin() -> None:
    payload = cdr_detections(NOW, "camera_optical_frame", [PERSON_IN_CAMERA])
    t = translate_detections(payload, SETTINGS, ctx())
    region, origin = seen_region(t.document)
    assert t.ignored == {"unknown_class": 1} and t.iris == ()
    assert origin == ["14.2 7 1"]  # map x, y and z above the storey's floor
    assert not region.contains(Point(18.0, 7.0))  # behind the person
    assert not region.contains(Point(16.2, 7.0))  # under the person
    assert region.contains(Point(18.0, 8.0)) and region.contains(Point(15.5, 7.0))


def test_a_z_forward_frame_not_named_optical_looks_where_the_setting_says() -> None:
    tf = robot_tf()
    tf.add(decode_tf_message(cdr_tf([Tf("camera_link", "cam_front", (0, 0, 0), OPTICAL)])), static=True)
    payload = cdr_detections(NOW, "cam_front", [])
    ahead, _ = seen_region(translate_detections(payload, SETTINGS, ctx(tf)).document)
    default = DetectionSettings(robot="robot1", classes={"table": "IfcFurniture"})  # optical = false
    aside, _ = seen_region(translate_detections(payload, default, ctx(tf)).document)
    assert ahead.contains(Point(17.0, 7.0)) and not ahead.contains(Point(14.2, 4.5))
    assert aside.contains(Point(14.2, 4.5)) and not aside.contains(Point(17.0, 7.0))  # its x: map -y


def test_a_detection_whose_frame_does_not_resolve_leaves_the_array_without_a_view() -> None:
    person = Det((("person", 0.95),), (0.0, 0.1, 2.0), (0.5, 1.8, 0.4))
    far_away = cdr_detections(NOW, "camera_optical_frame", [TABLE_IN_CAMERA])
    t = translate_detections(far_away, SETTINGS, ctx())
    assert b"twin:View" in (t.document or b"")
    c = Cdr().header(NOW, "camera_optical_frame").u32(2)
    for frame, d in (("camera_optical_frame", TABLE_IN_CAMERA), ("lidar_link", person)):
        c.header(NOW, frame).u32(1).string(d.results[0][0]).f64(d.results[0][1])
        c.pose((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)).f64(*([0.0] * 36))
        c.pose(d.position, d.orientation).f64(*d.size).string(d.id)
    t = translate_detections(c.bytes(), SETTINGS, ctx())
    assert b"twin:View" not in (t.document or b"") and t.iris == ("urn:twin-ros:robot1:det:7",)
    assert t.refused == ()  # an unmapped class: nothing refused, but its shadow is unknown


def test_camera_info_s_fields_of_view_take_the_place_of_the_configured_ones() -> None:
    payload = cdr_detections(NOW, "camera_optical_frame", [])
    wide, _ = seen_region(translate_detections(payload, SETTINGS, ctx()).document)
    narrow, _ = seen_region(translate_detections(payload, SETTINGS, ctx(fov_rad=(0.5, 0.6))).document)
    assert wide.contains(Point(17.0, 8.2)) and not narrow.contains(Point(17.0, 8.2))
    assert narrow.contains(Point(18.5, 7.0))
    assert not narrow.contains(Point(16.5, 7.0))  # the floor under its 34 deg vertical field of view


def test_camera_info_gives_the_narrower_side_s_fields_of_view_and_an_uncalibrated_one_is_refused() -> None:
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import CameraInfo

    info = CameraInfo(width=640, height=480)
    info.k = [500.0, 0.0, 300.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0]  # the principal point 20 px left
    h, v = camera_fov(serialize_message(info))
    assert h == pytest.approx(2 * math.atan(300 / 500)) and v == pytest.approx(2 * math.atan(240 / 500))
    with pytest.raises(RosInputError, match="describes no camera: width 0") as err:
        camera_fov(serialize_message(CameraInfo()))
    assert err.value.cause == "malformed"
