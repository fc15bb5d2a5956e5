"""cdus.ros2.types and cdus.ros2.rmw against values nobody here computed.

Golden values: the RIHS01 hashes rosidl generates for the ROS 2 interface definitions (as
published with them: std_msgs/String in rmw_zenoh's docs/design.md, the rest in CARLA's ROS 2
bridge table, LibCarla/source/carla/ros2/types/CdrTopicInfo.h, computed there with rosidl in
a ROS 2 container); the key expressions and liveliness tokens of rmw_zenoh's docs/design.md.
Where no published hash was found (std_msgs/Float64, nav_msgs/Path), zenoh-ros2-sdk's own
REP-2011 implementation computes it from the ``.msg`` text of the interface definitions.
"""

from __future__ import annotations

import pytest
from hypothesis import given, strategies as st
import zenoh.ext as zext
from mcap_ros2 import _dynamic as dyn
from zenoh_ros2_sdk import attachment as sdk_attachment, qos as sdk_qos, utils as sdk_utils

from cdus.ros2 import cdr, rmw, types
from tests.ros2.interfaces import MSG_FILES

GOLDEN = {
    "std_msgs/msg/String": "df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
    "std_msgs/msg/Header": "f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01",
    "builtin_interfaces/msg/Time": "b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197",
    "geometry_msgs/msg/Point": "6963084842a9b04494d6b2941d11444708d892da2f4b09843b9c43f42a7f6881",
    "geometry_msgs/msg/Vector3": "cc12fe83e4c02719f1ce8070bfd14aecd40f75a96696a67a2a1f37f7dbb0765d",
    "geometry_msgs/msg/Quaternion": "8a765f66778c8ff7c8ab94afcc590a2ed5325a1d9a076ffff38fbce36f458684",
    "geometry_msgs/msg/Pose": "d501954e9476cea2996984e812054b68026ae0bfae789d9a10b23daf35cc90fa",
    "geometry_msgs/msg/PoseStamped": "10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8",
    "geometry_msgs/msg/PoseWithCovariance": "9a7c0fd234b7f45c6098745ecccd773ca1085670e64107135397aee31c02e1bb",
    "geometry_msgs/msg/Twist": "9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a",
    "geometry_msgs/msg/TwistWithCovariance": "49f574f033f095d8b6cd1beaca5ca7925e296e84af1716d16c89d38b059c8c18",
    "geometry_msgs/msg/Transform": "beb83fbe698636351461f6f35d1abb20010c43d55374d81bd041f1ba2581fddc",
    "geometry_msgs/msg/TransformStamped": "0a241f87d04668d94099cbb5ba11691d5ad32c2f29682e4eb5653424bd275206",
    "nav_msgs/msg/Odometry": "3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
    "tf2_msgs/msg/TFMessage": "e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    "rosgraph_msgs/msg/Clock": "692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564",
}



@pytest.mark.parametrize("type_name", sorted(GOLDEN))
def test_type_hashes_are_rosidls(type_name):
    assert types.type_hash(type_name) == "RIHS01_" + GOLDEN[type_name]


@pytest.mark.parametrize("type_name", ["std_msgs/msg/Float64", "nav_msgs/msg/Path"])
def test_type_hashes_without_a_published_value_agree_with_zenoh_ros2_sdk(type_name, tmp_path):
    deps = {t: text for t, text in MSG_FILES.items() if t != type_name}
    assert sdk_utils.get_type_hash(type_name, msg_definition=MSG_FILES[type_name], dependencies=deps) \
        == types.type_hash(type_name)


def test_every_type_is_checked_against_someone_elses_hash():
    assert set(types.TYPES) == set(GOLDEN) | {"std_msgs/msg/Float64", "nav_msgs/msg/Path"}


def test_keys_and_tokens_are_rmw_zenohs_design_examples():
    assert rmw.topic_key(0, "/chatter", "std_msgs/msg/String") == \
        "0/chatter/std_msgs::msg::dds_::String_/RIHS01_" + GOLDEN["std_msgs/msg/String"]
    assert rmw.topic_key(0, "/robot1/chatter", "std_msgs/msg/String") == \
        "0/robot1/chatter/std_msgs::msg::dds_::String_/RIHS01_" + GOLDEN["std_msgs/msg/String"]
    listener = rmw.Node(2, "aac3178e146ba6f1fc6e6a4085e77f21", "listener")
    assert listener.token() == "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
    talker = rmw.Node(2, "8b20917502ee955ac4476e0266340d5c", "talker")
    assert talker.publisher_token(10, "/chatter", "std_msgs/msg/String", rmw.Qos(depth=7)) == (
        "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/std_msgs::msg::dds_::String_/"
        "RIHS01_" + GOLDEN["std_msgs/msg/String"] + "/::,7:,:,:,,")


def test_humble_keys_carry_no_type_hash():
    assert rmw.topic_key(3, "/cdus/usv1/pose", "geometry_msgs/msg/PoseStamped", "humble") == \
        "3/cdus/usv1/pose/geometry_msgs::msg::dds_::PoseStamped_/TypeHashNotSupported"
    with pytest.raises(ValueError, match="choose one of"):
        rmw.topic_key(0, "/a", "std_msgs/msg/String", "iron")


def test_a_namespaced_node_and_a_latched_publisher():
    node = rmw.Node(0, "ab", "cdus_lake", namespace="/cdus")
    assert node.token() == "@ros2_lv/0/ab/0/0/NN/%/%cdus/cdus_lake"
    token = node.publisher_token(5, "/cdus/usv1/path", "nav_msgs/msg/Path", rmw.Qos(depth=1, transient_local=True))
    assert token.startswith("@ros2_lv/0/ab/0/5/MP/%/%cdus/cdus_lake/%cdus%usv1%path/nav_msgs::msg::dds_::Path_/RIHS01_")
    assert token.endswith("/:1:,1:,:,:,,")
    decoded = sdk_qos.QosProfile.decode(token.rsplit("/", 1)[1])
    assert decoded.durability == sdk_qos.QosDurability.TRANSIENT_LOCAL and decoded.history_depth == 1


def test_the_attachment_is_what_zenohs_serializer_writes():
    gid = rmw.gid("0123abcd", 7)
    ours = rmw.attachment(42, 1_700_000_000_123_456_789, gid)
    theirs = zext.z_serialize((zext.Int64(42), zext.Int64(1_700_000_000_123_456_789), gid)).to_bytes()
    assert ours == theirs
    assert rmw.decode_attachment(ours) == (42, 1_700_000_000_123_456_789, gid)
    att = sdk_attachment.Attachment.from_bytes(ours)
    assert (att.sequence_id, att.gid) == (42, gid)


def test_a_bad_attachment_is_a_reason():
    assert rmw.decode_attachment(b"\x00" * 5) == "size"
    assert rmw.decode_attachment(b"\x00" * 16 + b"\x0f" + b"\x00" * 16) == "gid_size"


def test_definitions_parse_with_mcap_ros2_support():
    for name in types.TYPES:
        decoders = dyn.generate_dynamic(name, types.definition(name))
        assert name in decoders or name.replace("/msg/", "/") in decoders
    dec = dyn.generate_dynamic("rosgraph_msgs/msg/Clock", types.definition("rosgraph_msgs/msg/Clock"))
    out = dec["rosgraph_msgs/msg/Clock"](cdr.encode("rosgraph_msgs/msg/Clock", {"clock": {"sec": 7, "nanosec": 9}}))
    assert (out.clock.sec, out.clock.nanosec) == (7, 9)


@given(data=st.binary(max_size=64))
def test_any_bytes_are_an_attachment_or_a_reason(data):
    out = rmw.decode_attachment(data)
    assert out in ("size", "gid_size") or rmw.attachment(*out) == data


@given(seq=st.integers(-2**63, 2**63 - 1), ts=st.integers(-2**63, 2**63 - 1), g=st.binary(min_size=16, max_size=16))
def test_attachments_round_trip(seq, ts, g):
    assert rmw.decode_attachment(rmw.attachment(seq, ts, g)) == (seq, ts, g)
