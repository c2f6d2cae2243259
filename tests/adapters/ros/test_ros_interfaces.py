"""The interfaces the daemon subscribes to (detections, Open-RMF obstacles and door states, TF,
diagnostics): their RIHS01 type hashes as rosbags computes them from the registered definitions equal
what ROS 2's rosidl generators compute from the upstream ``.msg`` files (``../shared/ros-msgs/``) or
what the wheels ship. No code shared with ``adapters.ros`` on the oracle's side."""

from __future__ import annotations

from pathlib import Path

import pytest

from adapters.ros.building_map_msgs import BUILDING_MAP
from adapters.ros.interfaces import DETECTION_3D_ARRAY, DIAGNOSTIC_ARRAY, DOOR_STATE, OBSTACLES, TF_MESSAGE
from adapters.ros.rmw_zenoh import type_hash
from tests.adapters.rosidl_build import generated_package_hashes, shipped_hash

UPSTREAM = Path(__file__).resolve().parents[3].parent / "shared" / "ros-msgs"
TF_MESSAGE_MSG = "geometry_msgs/TransformStamped[] transforms\n"  # ros2/geometry2, tf2_msgs/msg/TFMessage.msg


def upstream(package: str, names: list[str]) -> dict[str, str]:
    folder = UPSTREAM / package / "msg"
    if not UPSTREAM.parent.is_dir():
        pytest.skip(f"the upstream .msg files come from ../shared/ros-msgs, and {UPSTREAM.parent} is absent")
    assert folder.is_dir(), f"the upstream definitions are missing: {folder}"
    return {name: (folder / f"{name}.msg").read_text() for name in names}


@pytest.mark.parametrize(
    ("package", "names", "depends", "checked"),
    [
        (
            "vision_msgs",
            [
                "ObjectHypothesis",
                "ObjectHypothesisWithPose",
                "BoundingBox3D",
                "Detection3D",
                "Detection3DArray",
            ],
            ("std_msgs", "geometry_msgs", "builtin_interfaces"),
            DETECTION_3D_ARRAY,
        ),
        (
            "rmf_obstacle_msgs",
            ["BoundingBox3D", "Obstacle", "Obstacles"],
            ("std_msgs", "geometry_msgs", "builtin_interfaces"),
            OBSTACLES,
        ),
        ("rmf_door_msgs", ["DoorMode", "DoorState"], ("builtin_interfaces",), DOOR_STATE),
        (
            "rmf_building_map_msgs",
            [
                "Param",
                "GraphNode",
                "GraphEdge",
                "Graph",
                "AffineImage",
                "Place",
                "Door",
                "Level",
                "Lift",
                "BuildingMap",
            ],
            (),
            BUILDING_MAP,
        ),
    ],
)
def test_hashes_of_the_registered_interfaces_equal_what_rosidl_generates_from_upstream(
    package: str, names: list[str], depends: tuple[str, ...], checked: str, tmp_path: Path
) -> None:
    generated = generated_package_hashes(package, upstream(package, names), tmp_path, depends)
    for type_name, expected in generated.items():
        assert type_hash(type_name) == expected, type_name
    assert checked in generated


def test_tf_message_hash_equals_what_rosidl_generates(tmp_path: Path) -> None:
    generated = generated_package_hashes(
        "tf2_msgs",
        {"TFMessage": TF_MESSAGE_MSG},
        tmp_path,
        ("std_msgs", "geometry_msgs", "builtin_interfaces"),
    )
    assert type_hash(TF_MESSAGE) == generated[TF_MESSAGE]


def test_diagnostic_array_hash_equals_what_the_wheel_ships() -> None:
    assert type_hash(DIAGNOSTIC_ARRAY) == shipped_hash(DIAGNOSTIC_ARRAY)
