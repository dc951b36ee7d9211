"""RIHS01 type hashes and rmw_zenoh keys against published values (rmw_zenoh's docs/design.md and keys seen on
real ROS 2 Jazzy systems), and the attachment layout."""

from __future__ import annotations

import pytest
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore

from mjnav.msgs import UnknownMessageType, typestore
from mjnav.msgs.rihs import dds_type_name, type_description, type_hash
from mjnav.msgs.rmw_zenoh import attachment, data_key, endpoint_token, mangle, node_token, parse_attachment
from mjnav.msgs.topics import TOPICS, Kind, Topic

#: Hashes published by rmw_zenoh's design.md (std_msgs/String) and in public rmw_zenoh keys (Twist, PoseStamped).
PUBLISHED = {
    "std_msgs/msg/String": "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
    "geometry_msgs/msg/Twist": "RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a",
}
CHATTER = Topic("chatter", "std_msgs/msg/String", Kind.SNAPSHOT, "talker", "", "")


@pytest.mark.parametrize(("typename", "expected"), sorted(PUBLISHED.items()))
def test_type_hash_equals_the_published_one(typename: str, expected: str) -> None:
    assert type_hash(typename) == expected


def test_pose_stamped_hash_has_the_published_prefix() -> None:
    # Only the first 16 hex digits are in the public key we found; they still pin nested types and sorting.
    assert type_hash("geometry_msgs/msg/PoseStamped").startswith("RIHS01_10f3786d7d40fd2b")


def test_the_description_lists_every_referenced_type_once_sorted() -> None:
    refs = [d["type_name"] for d in type_description("nav_msgs/msg/Odometry")["referenced_type_descriptions"]]
    assert refs == sorted(set(refs))
    assert "builtin_interfaces/msg/Time" in refs and "geometry_msgs/msg/Quaternion" in refs


def test_unknown_type_is_a_typed_error() -> None:
    with pytest.raises(UnknownMessageType):
        type_hash("nope_msgs/msg/Nothing")


def test_the_bridged_types_are_defined_as_in_jazzy() -> None:
    """The typestore is Humble's; the hashes are only right for Jazzy if every bridged type (and what it nests) has
    the same fields there."""
    ours, jazzy = typestore(), get_typestore(Stores.ROS2_JAZZY)
    pending = [row.msgtype for row in TOPICS.values() if not row.msgtype.startswith("mjnav_msgs/")]
    seen: set[str] = set()
    while pending:
        name = pending.pop()
        if name in seen:
            continue
        seen.add(name)
        fields = ours.fielddefs[name][1]
        assert fields == jazzy.fielddefs[name][1], name
        for _, (node, arg) in fields:
            if node in (Nodetype.ARRAY, Nodetype.SEQUENCE):
                node, arg = arg[0]
            if node is Nodetype.NAME:
                pending.append(arg)
    assert "geometry_msgs/msg/Vector3" in seen


def test_data_key_is_the_design_documents_example() -> None:
    assert data_key(0, CHATTER, "robot1") == (
        "0/robot1/chatter/std_msgs::msg::dds_::String_/"
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
    )
    assert dds_type_name("sensor_msgs/msg/LaserScan") == "sensor_msgs::msg::dds_::LaserScan_"
    with pytest.raises(ValueError, match="domain"):
        data_key(300, CHATTER, "robot1")
    with pytest.raises(ValueError, match="per service"):
        data_key(0, TOPICS["status"], "robot0")


def test_tokens_follow_the_design_document() -> None:
    zid = "8b20917502ee955ac4476e0266340d5c"
    assert node_token(2, zid, 0, "robot1", "talker") == f"@ros2_lv/2/{zid}/0/0/NN/%/%robot1/talker"
    token = endpoint_token(2, zid, 0, 10, "MP", "robot1", "talker", CHATTER)
    assert token == (
        f"@ros2_lv/2/{zid}/0/10/MP/%/%robot1/talker/%robot1%chatter/std_msgs::msg::dds_::String_/"
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18/::,1:,:,:,,"
    )
    assert mangle("") == "%"
    with pytest.raises(ValueError):
        endpoint_token(2, zid, 0, 10, "SS", "robot1", "talker", CHATTER)


def test_attachment_layout() -> None:
    gid = bytes(range(16))
    data = attachment(7, 1_700_000_000_123_456_789, gid)
    assert len(data) == 8 + 8 + 1 + 16
    assert data[:8] == (7).to_bytes(8, "little") and data[16] == 16 and data[17:] == gid
    assert parse_attachment(data) == (7, 1_700_000_000_123_456_789, gid)
    with pytest.raises(ValueError):
        parse_attachment(data[:-1])
    with pytest.raises(ValueError):
        attachment(1, 2, b"short")
