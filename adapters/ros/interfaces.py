"""ROS 2 interfaces the daemon subscribes to that rosbags' type stores lack, registered from their
upstream ``.msg`` definitions: ``vision_msgs/msg/Detection3DArray`` (and the messages it is made of),
``rmf_obstacle_msgs/msg/Obstacles`` and ``rmf_door_msgs/msg/DoorState``; and the one it publishes,
``rmf_building_map_msgs/msg/BuildingMap`` (:mod:`adapters.ros.building_map_msgs`).

The texts are the upstream files byte for byte (``../shared/ros-msgs/``, ros-perception/vision_msgs @
e77fa2d9, open-rmf/rmf_internal_msgs @ 3d4df023, Apache-2.0), so the RIHS01 type hashes rosbags computes
from them equal those of a ROS 2 installation (the tests check them against rosidl's own generators).
``tf2_msgs/msg/TFMessage``, ``sensor_msgs/msg/CameraInfo`` and ``diagnostic_msgs/msg/DiagnosticArray``
are in rosbags' stores already.

Example::

    store = get_typestore(Stores.ROS2_HUMBLE)
    register_interfaces(store)
    store.hash_rihs01(DETECTION_3D_ARRAY)    # "RIHS01_..."
"""

from __future__ import annotations

from typing import Any

from rosbags.typesys import get_types_from_msg

from adapters.ros.building_map_msgs import BUILDING_MAP_INTERFACES

__all__ = [
    "CAMERA_INFO",
    "DETECTION_3D_ARRAY",
    "DIAGNOSTIC_ARRAY",
    "DOOR_STATE",
    "INTERFACES",
    "OBSTACLES",
    "TF_MESSAGE",
    "register_interfaces",
]

DETECTION_3D_ARRAY = "vision_msgs/msg/Detection3DArray"
OBSTACLES = "rmf_obstacle_msgs/msg/Obstacles"
DOOR_STATE = "rmf_door_msgs/msg/DoorState"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"

INTERFACES: dict[str, str] = {
    "vision_msgs/msg/ObjectHypothesis": """\
# An object hypothesis that contains no pose information.
# If you would like to define an array of ObjectHypothesis messages,
#   please see the Classification message type.

# The unique ID of the object class. To get additional information about
#   this ID, such as its human-readable class name, listeners should perform a
#   lookup in a metadata database. See vision_msgs/VisionInfo.msg for more detail.
string class_id

# The probability or confidence value of the detected object. By convention,
#   this value should lie in the range [0-1].
float64 score
""",
    "vision_msgs/msg/ObjectHypothesisWithPose": """\
# An object hypothesis that contains pose information.
# If you would like to define an array of ObjectHypothesisWithPose messages,
#   please see the Detection2D or Detection3D message types.

# The object hypothesis (ID and score).
ObjectHypothesis hypothesis

# The 6D pose of the object hypothesis. This pose should be
#   defined as the pose of some fixed reference point on the object, such as
#   the geometric center of the bounding box, the center of mass of the
#   object or the origin of a reference mesh of the object.
# Note that this pose is not stamped; frame information can be defined by
#   parent messages.
# Also note that different classes predicted for the same input data may have
#   different predicted 6D poses.
geometry_msgs/PoseWithCovariance pose
""",
    "vision_msgs/msg/BoundingBox3D": """\
# A 3D bounding box that can be positioned and rotated about its center (6 DOF)
# Dimensions of this box are in meters, and as such, it may be migrated to
#   another package, such as geometry_msgs, in the future.

# The 3D position and orientation of the bounding box center
geometry_msgs/Pose center

# The total size of the bounding box, in meters, surrounding the object's center
#   pose.
geometry_msgs/Vector3 size
""",
    "vision_msgs/msg/Detection3D": """\
# Defines a 3D detection result.
#
# This extends a basic 3D classification by including the pose of the
# detected object.

std_msgs/Header header

# Class probabilities. Does not have to include hypotheses for all possible
#   object ids, the scores for any ids not listed are assumed to be 0.
ObjectHypothesisWithPose[] results

# 3D bounding box surrounding the object.
BoundingBox3D bbox

# ID used for consistency across multiple detection messages. Detections
# of the same object in different detection messages should have the same id.
# This field may be empty.
string id

# Source data that generated this classification are not a part of the message.
# If you need to access them, use an exact or approximate time synchronizer in
# your code, as this message's header should match the header of the source
# data.
""",
    "vision_msgs/msg/Detection3DArray": """\
# A list of 3D detections, for a multi-object 3D detector.

std_msgs/Header header

# A list of the detected proposals. A multi-proposal detector might generate
#   this list with many candidate detections generated from a single input.
Detection3D[] detections
""",
    "rmf_obstacle_msgs/msg/BoundingBox3D": """\
# A 3D bounding box

# The 3D position and orientation of the bounding box center
geometry_msgs/Pose center

# The total size of the bounding box, in meters, surrounding the object's center
geometry_msgs/Vector3 size
""",
    "rmf_obstacle_msgs/msg/Obstacle": """\
# All measurements should be w.r.t. header.frame_id

# Standard header
std_msgs/Header header

# An id for this specific message. This will be used for deletion.
int32 id

# Unique identifier of the publisher of this message.
string source

# The level on which this obstacle exists
string level_name

# A classification label for the detected obstacle. (human, chair, etc)
string classification

# Bounding box of the obstacle
BoundingBox3D bbox

# 3D obstacle data that can be deserialized into an octree.
# Resolution (in m) of the smallest octree node.
float64 data_resolution

# Binary serialization of the obstacle octree
int8[] data

# The expected lifetime of the obstacle
builtin_interfaces/Duration lifetime

# Whether to add or delete the obstacle of the id provided
int32 action
int32 ACTION_ADD=1 # or modify
int32 ACTION_DELETE=2
int32 ACTION_DELETEALL=3
""",
    "rmf_obstacle_msgs/msg/Obstacles": """\
# Standard header
std_msgs/Header header
Obstacle[] obstacles
""",
    "rmf_door_msgs/msg/DoorMode": """\
# The DoorMode message captures the "mode" of an automatic door controller.
# Most door controllers default to running in "closed" mode, and transition
# through some sort of "moving" mode until reaching the "open" mode.

uint32 value

# "value" must be one of the following enumerations:
uint32 MODE_CLOSED=0
uint32 MODE_MOVING=1
uint32 MODE_OPEN=2
uint32 MODE_OFFLINE=3
uint32 MODE_UNKNOWN=4
""",
    "rmf_door_msgs/msg/DoorState": """\
builtin_interfaces/Time door_time
string door_name
DoorMode current_mode
""",
}
"""Upstream ``.msg`` text of every registered type, dependencies before the types that use them."""


INTERFACES.update(BUILDING_MAP_INTERFACES)  # rmf_building_map_msgs (adapters/ros/building_map_msgs.py)


def register_interfaces(store: Any) -> None:
    """Register :data:`INTERFACES` in a rosbags type store (names inside a package resolve to it)."""
    for name, text in INTERFACES.items():
        store.register(get_types_from_msg(text, name))
