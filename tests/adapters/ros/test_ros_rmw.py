"""rmw_zenoh and bridge wire facts: type hashes, data keys, the attachment and liveliness tokens."""

from __future__ import annotations

import pytest
import zenoh.ext

from adapters.ros.cdr import OCCUPANCY_GRID, OCCUPANCY_GRID_UPDATE
from adapters.ros.rmw_zenoh import (
    LATCHED_QOS,
    RosNode,
    RosTopic,
    attachment,
    gid_of,
    parse_attachment,
    parse_token,
    resolve_name,
    type_hash,
)
from twin.errors import MapError

# From DESIGN.md ("ROS 2 robots, unchanged"), taken there from the rmw_zenoh sources.
GRID_HASH = "RIHS01_8d348150c12913a31ee0ec170fbf25089e4745d17035792a1ba94d6f0bc0cfc7"
UPDATE_HASH = "RIHS01_c4095b0be2e4363f8978a1570e0293ee093436f1e1c61d99b48502ac317025e8"


def test_type_hashes_computed_from_the_definitions_match_the_published_ones() -> None:
    assert type_hash(OCCUPANCY_GRID) == GRID_HASH
    assert type_hash(OCCUPANCY_GRID_UPDATE) == UPDATE_HASH


def test_data_and_bridge_keys_follow_rmw_zenoh_and_the_bridge() -> None:
    topic = RosTopic(0, "/robot1", "map", OCCUPANCY_GRID)
    assert topic.data_key == f"0/robot1/map/nav_msgs::msg::dds_::OccupancyGrid_/{GRID_HASH}"
    assert topic.bridge_key == "robot1/map"
    updates = RosTopic(3, "/a/b", "map_updates", OCCUPANCY_GRID_UPDATE)
    assert updates.data_key == f"3/a/b/map_updates/map_msgs::msg::dds_::OccupancyGridUpdate_/{UPDATE_HASH}"


def test_the_attachment_is_zenoh_ext_serialised_and_33_bytes() -> None:
    gid = gid_of("some token")
    raw = attachment(7, 1_700_000_000_123_456_789, gid)
    oracle = zenoh.ext.z_serialize((zenoh.ext.Int64(7), zenoh.ext.Int64(1_700_000_000_123_456_789), gid))
    assert raw == oracle.to_bytes()
    assert len(raw) == 33
    assert parse_attachment(raw) == (7, 1_700_000_000_123_456_789, gid)
    with pytest.raises(MapError, match="33 bytes"):
        parse_attachment(raw[:-1])


def test_liveliness_tokens_parse_back_as_rmw_zenohs_graph_cache_reads_them() -> None:
    node = RosNode(0, "/robot1", "twin_map_server", "c0cc4f280ec42d6af1cb5f30a742b91c", 0)
    assert node.node_token() == "@ros2_lv/0/c0cc4f280ec42d6af1cb5f30a742b91c/0/0/NN/%/%robot1/twin_map_server"
    pub = node.publisher_token(RosTopic(0, "/robot1", "map", OCCUPANCY_GRID), 1, LATCHED_QOS)
    assert pub.endswith(
        f"/MP/%/%robot1/twin_map_server/%robot1%map/nav_msgs::msg::dds_::OccupancyGrid_/{GRID_HASH}/:1:,1:,:,:,,"
    )
    parsed = parse_token(pub)
    assert (parsed.kind, parsed.namespace, parsed.node, parsed.topic) == (
        "MP",
        "/robot1",
        "twin_map_server",
        "/robot1/map",
    )
    assert parsed.type_name == "nav_msgs::msg::dds_::OccupancyGrid_" and parsed.type_hash == GRID_HASH
    assert parsed.qos == {"reliability": None, "durability": 1, "history": None, "depth": 1}
    with pytest.raises(MapError, match="Not an rmw_zenoh liveliness token"):
        parse_token("@ros2_lv/0/x")


def test_a_relative_name_goes_under_the_namespace_and_an_absolute_one_stays() -> None:
    assert RosTopic(0, *resolve_name("/robot1", "tf"), OCCUPANCY_GRID).bridge_key == "robot1/tf"
    assert RosTopic(0, *resolve_name("/robot1", "/tf"), OCCUPANCY_GRID).bridge_key == "tf"
    assert RosTopic(2, *resolve_name("/robot1", "/tf"), OCCUPANCY_GRID).data_key.startswith("2/tf/nav_msgs::")
