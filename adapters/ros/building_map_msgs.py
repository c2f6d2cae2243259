"""The definitions of Open-RMF's ``rmf_building_map_msgs`` messages (``BuildingMap`` and the messages it
is made of), the upstream ``.msg`` files byte for byte (``../shared/ros-msgs/rmf_building_map_msgs/``,
open-rmf/rmf_building_map_msgs, Apache-2.0), registered with the other interfaces
(:mod:`adapters.ros.interfaces`) so that their RIHS01 type hashes equal a ROS 2 installation's.
"""

from __future__ import annotations

BUILDING_MAP = "rmf_building_map_msgs/msg/BuildingMap"

BUILDING_MAP_INTERFACES: dict[str, str] = {
    "rmf_building_map_msgs/msg/Param": """\
string name

uint32 type
uint32 TYPE_UNDEFINED=0
uint32 TYPE_STRING=1
uint32 TYPE_INT=2
uint32 TYPE_DOUBLE=3
uint32 TYPE_BOOL=4

int32 value_int
float32 value_float
string value_string
bool value_bool
""",
    "rmf_building_map_msgs/msg/GraphNode": """\
float32 x
float32 y
string name
Param[] params
""",
    "rmf_building_map_msgs/msg/GraphEdge": """\
uint32 v1_idx
uint32 v2_idx
Param[] params

# when edge_type is UNIDIRECTIONAL, it means v1 -> v2
# when edge_type is BIDIRECTIONAL, it means v1 <-> v2
uint8 edge_type
uint8 EDGE_TYPE_BIDIRECTIONAL=0
uint8 EDGE_TYPE_UNIDIRECTIONAL=1
""",
    "rmf_building_map_msgs/msg/Graph": """\
string name
GraphNode[] vertices
GraphEdge[] edges
Param[] params
""",
    "rmf_building_map_msgs/msg/AffineImage": """\
string name
float32 x_offset
float32 y_offset
float32 yaw
float32 scale
string encoding
uint8[] data
""",
    "rmf_building_map_msgs/msg/Place": """\
string name
float32 x
float32 y
float32 yaw
float32 position_tolerance
float32 yaw_tolerance
""",
    "rmf_building_map_msgs/msg/Door": """\
string name

# CONVENTIONS
# ===========
# single hinge doors:
#   * hinge is located at (v1_x, v1_y)
#   * door extends till (v2_x, v2_y)
#   * motion_range = door swing range in DEGREES
#   * there are two possible motions: clockwise and anti-clockwise
#     selected by the motion_direction parameter, which is +1 or -1
#
# double hinge doors:
#   * hinges are located at both (v1_x, v1_y) and (v2_x, v2_y)
#   * motion range = door swing ranges in DEGREES (assume symmetric)
#   * same motion-direction selection as single hinge
#
# single sliding doors:
#   * the door slides from (v2_x, v2_y) towards (v1_x, v1_y)
#   * range of motion is entire distance from v2->v1. No need to specify.
#
# double sliding doors:
#   * door panels slide from the centerpoint of v1<->v2 towards v1 and v2
#
# single/double telescoping doors:
#   * common in elevators; same parameters as sliding doors; they just
#     open/close faster and take up less space inside the wall.

float32 v1_x
float32 v1_y

float32 v2_x
float32 v2_y

uint8 door_type
uint8 DOOR_TYPE_UNDEFINED=0
uint8 DOOR_TYPE_SINGLE_SLIDING=1
uint8 DOOR_TYPE_DOUBLE_SLIDING=2
uint8 DOOR_TYPE_SINGLE_TELESCOPE=3
uint8 DOOR_TYPE_DOUBLE_TELESCOPE=4
uint8 DOOR_TYPE_SINGLE_SWING=5
uint8 DOOR_TYPE_DOUBLE_SWING=6

float32 motion_range
int32 motion_direction
""",
    "rmf_building_map_msgs/msg/Level": """\
string name
float32 elevation
AffineImage[] images
Place[] places
Door[] doors
Graph[] nav_graphs
Graph wall_graph
""",
    "rmf_building_map_msgs/msg/Lift": """\
string name
string[] levels
Door[] doors
Graph wall_graph

# (ref_x, ref_y, ref_yaw) is a "reference orientation" of the lift cabin
# which can be used to align floors.
float32 ref_x
float32 ref_y
float32 ref_yaw

# width and depth of the cabin
float32 width
float32 depth""",
    "rmf_building_map_msgs/msg/BuildingMap": """\
string name
Level[] levels
Lift[] lifts
""",
}
"""In dependency order: a message is registered after the ones it uses."""
