"""cdus.ros2.cdr and cdus.ros2.fleet: every message the fleet publishes, decoded by rosbags
(an independent CDR implementation with the ROS 2 Jazzy type definitions built in)."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given, settings, strategies as st
from rosbags.typesys import Stores, get_typestore

from cdus.ros2 import cdr, fleet
from cdus.ros2.types import TYPES
from cdus.scenario.ros2 import Ros2Spec

STORE = get_typestore(Stores.ROS2_JAZZY)
finite = st.floats(-1e6, 1e6, allow_nan=False)
times = st.floats(0.0, 1e7, allow_nan=False)
ids = st.text(st.sampled_from("abcxyz019_-"), min_size=1, max_size=8).filter(lambda s: not s[0].isdigit())


def decode(type_name: str, data: bytes):
    return STORE.deserialize_cdr(data, type_name)


def test_every_type_is_in_rosbags_with_our_fields():
    for name, fields in TYPES.items():
        assert [f for f, _ in fields] == list(STORE.types[name].__dataclass_fields__)[:len(fields)]


@settings(max_examples=60, deadline=None)
@given(t=times, vid=ids, q=st.tuples(finite, finite, finite), heading=st.floats(-7, 7), speed=finite)
def test_pose_and_odometry_decode(t, vid, q, heading, speed):
    p = decode(fleet.POSE, cdr.encode(fleet.POSE, fleet.pose(t, q, heading, "world")))
    assert (p.pose.position.x, p.pose.position.y, p.pose.position.z) == q
    assert p.header.frame_id == "world"
    assert p.header.stamp.sec * 1_000_000_000 + p.header.stamp.nanosec == round(t * 1e9)
    qz, qw = p.pose.orientation.z, p.pose.orientation.w  # the body x axis, rotated, points along the heading
    assert (qw * qw - qz * qz, 2 * qw * qz) == (pytest.approx(math.cos(heading), abs=1e-12),
                                                pytest.approx(math.sin(heading), abs=1e-12))
    o = decode(fleet.ODOM, cdr.encode(fleet.ODOM, fleet.odometry(t, vid, q, heading, speed, "map")))
    assert o.child_frame_id == fleet.child_frame(vid) and o.header.frame_id == "map"
    assert o.twist.twist.linear.x == speed and list(o.pose.covariance) == [0.0] * 36
    assert (o.pose.pose.position.x, o.pose.pose.position.y) == q[:2]


@settings(max_examples=40, deadline=None)
@given(t=times, rows=st.lists(st.tuples(ids, st.tuples(finite, finite), st.floats(-4, 4)), max_size=5))
def test_tf_decodes(t, rows):
    m = decode(fleet.TF, cdr.encode(fleet.TF, fleet.transforms(t, rows, "world")))
    assert [tr.child_frame_id for tr in m.transforms] == [fleet.child_frame(v) for v, _, _ in rows]
    assert [(tr.transform.translation.x, tr.transform.translation.y, tr.transform.translation.z)
            for tr in m.transforms] == [(*q, 0.0) for _, q, _ in rows]


@settings(max_examples=40, deadline=None)
@given(t=times, w=finite, points=st.lists(st.tuples(finite, finite, finite), max_size=20))
def test_clock_float_and_path_decode(t, w, points):
    c = decode(fleet.CLOCK, cdr.encode(fleet.CLOCK, fleet.clock(t)))
    assert c.clock.sec * 1_000_000_000 + c.clock.nanosec == round(t * 1e9)
    assert decode(fleet.FLOAT, cdr.encode(fleet.FLOAT, fleet.value(w))).data == w
    p = decode(fleet.PATH, cdr.encode(fleet.PATH, fleet.path(points, "world", t)))
    assert [(x.pose.position.x, x.pose.position.y, x.pose.position.z) for x in p.poses] == points
    assert all(x.pose.orientation.w == 1.0 for x in p.poses)


@settings(max_examples=40, deadline=None)
@given(text=st.text(max_size=200))
def test_strings_decode_with_any_text(text):
    assert decode(fleet.STRING, cdr.encode(fleet.STRING, {"data": text})).data == text


def test_bytes_equal_rosbags_own_serialization():
    msg = fleet.odometry(12.5, "usv1", (1.0, -2.0, 0.0), 0.3, 1.2, "world")
    data = cdr.encode(fleet.ODOM, msg)
    assert STORE.serialize_cdr(decode(fleet.ODOM, data), fleet.ODOM) == data


def test_a_wrong_array_or_type_is_an_error():
    with pytest.raises(ValueError, match="covariance: 3 values for an array of 36"):
        cdr.encode("geometry_msgs/msg/PoseWithCovariance", {"covariance": [0.0] * 3})
    with pytest.raises(KeyError, match="not a type cdus publishes"):
        cdr.encode("sensor_msgs/msg/Imu", {})


def test_the_topics_of_a_fleet():
    names = [(t.name, t.type_name) for t in fleet.topics(Ros2Spec(namespace="/lake"), ["usv-1", "uav1"])]
    assert names[:3] == [("/clock", fleet.CLOCK), ("/tf", fleet.TF), ("/lake/events", fleet.STRING)]
    assert ("/lake/usv_1/odom", fleet.ODOM) in names and ("/lake/uav1/path", fleet.PATH) in names
    assert len(names) == 3 + 2 * 5
    assert [t.qos.transient_local for t in fleet.topics(Ros2Spec(), ["a"]) if t.field == "path"] == [True]
    assert json.loads(json.dumps(fleet.stamp(1.9999999999))) == {"sec": 2, "nanosec": 0}


def test_the_yaw_rate_is_the_wrapped_heading_change():
    assert fleet.yaw_rate(0.1, 1.0, None) == 0.0 and fleet.yaw_rate(0.1, 1.0, (1.0, 0.0)) == 0.0
    assert fleet.yaw_rate(0.3, 1.1, (1.0, 0.2)) == pytest.approx(1.0)
    assert fleet.yaw_rate(-3.1, 1.1, (1.0, 3.1)) == pytest.approx((2 * math.pi - 6.2) / 0.1)  # across ±π
    o = decode(fleet.ODOM, cdr.encode(fleet.ODOM, fleet.odometry(1.0, "a", (0, 0), 0.0, 2.0, "world", -0.5)))
    assert (o.twist.twist.linear.x, o.twist.twist.angular.z) == (2.0, -0.5)
