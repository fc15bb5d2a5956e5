"""`cdus launch --ros2`, seen by a ROS 2 client nobody here wrote (zenoh-ros2-sdk).

A secured lockstep fleet (the default) publishes itself; the client, holding the run's
``ros2-client`` credentials, discovers the topics from the bridge's liveliness tokens as
``ros2 topic list`` does, subscribes with the key it computes itself (its own REP-2011 hash of
the interface definitions in tests/ros2/interfaces.py) and decodes poses, odometry and /clock
with rosbags. The run is killed at teardown (its duration is far longer than the test).
"""

from __future__ import annotations

import threading
import time

import pytest
import zenoh
import zenoh.ext
import zenoh_ros2_sdk as sdk
from rosbags.typesys import Stores, get_typestore
from zenoh_ros2_sdk import message_registry

from cdus.ros2.rmw import topic_key
from cdus.wire.transport import Transport, free_tcp_port, zenoh_config
from tests.e2e.conftest import launches, unique_fleet  # noqa: F401 (the fixture)
from tests.ros2.interfaces import write_tree

CONTROL_PERIOD = 1 / 50.0  # lake_circle's control rate


class Inbox:
    def __init__(self):
        self.cond = threading.Condition()
        self.got: dict[str, list] = {}

    def on(self, topic: str):
        def cb(msg):
            with self.cond:
                self.got.setdefault(topic, []).append(msg)
                self.cond.notify_all()
        return cb

    def wait(self, topic: str, n: int, timeout: float = 60.0) -> list:
        deadline = time.monotonic() + timeout
        with self.cond:
            while len(self.got.get(topic, [])) < n:
                assert time.monotonic() < deadline, f"{topic}: {len(self.got.get(topic, []))} of {n} messages"
                self.cond.wait(timeout=0.5)
            return list(self.got[topic])


@pytest.fixture
def ros2_client(tmp_path, monkeypatch):
    """zenoh-ros2-sdk's process-wide session and message registry, set up for one test and torn down."""
    message_registry._registry = message_registry.MessageRegistry(str(write_tree(tmp_path / "msgs")))
    sdk.ZenohSession._instance = None
    yield monkeypatch
    if sdk.ZenohSession._instance is not None:
        sdk.ZenohSession._instance.session.close()
    sdk.ZenohSession._instance = None
    message_registry._registry = None


def test_a_ros2_client_discovers_the_fleet_decodes_pose_odometry_clock_and_the_latched_paths(tmp_path, launches, ros2_client):
    fleet, port, run = unique_fleet(), free_tcp_port(), tmp_path / "run"
    la = launches(["configs/lake_circle.toml", "--ros2", "--duration", "3000", "--rerun", "off",
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run)], fleet)
    hint = la.wait_for("ROS 2 (jazzy)")  # what to tell a ROS 2 machine
    assert f"ZENOH_SESSION_CONFIG_URI={run / 'secure' / 'ros2-client.json5'}" in hint and "ROS_DOMAIN_ID=0" in hint
    la.wait_for(f"fleet '{fleet}' up", timeout=90)
    ros2_client.setenv("ZENOH_SESSION_CONFIG_URI", str(run / "secure" / "ros2-client.json5"))

    topics = dict(sdk.get_topic_names_and_types(domain_id=0, router_port=port, timeout=2.0))
    assert topics["/clock"] == ["rosgraph_msgs/msg/Clock"]
    assert topics["/tf"] == ["tf2_msgs/msg/TFMessage"]
    assert topics["/cdus/usv1/pose"] == ["geometry_msgs/msg/PoseStamped"]
    assert topics["/cdus/uav3/odom"] == ["nav_msgs/msg/Odometry"]
    assert topics["/cdus/usv2/path"] == ["nav_msgs/msg/Path"]
    assert len([t for t in topics if t.startswith("/cdus/")]) == 6 * 5 + 1  # 5 per vehicle, and the events
    info = sdk.get_topic_info("/cdus/usv1/pose", domain_id=0, router_port=port, timeout=2.0, verbose=True)
    assert [(p.node_namespace, p.node_name) for p in info.publishers] == [("/cdus", f"cdus_{fleet}")]

    inbox = Inbox()
    subs = [sdk.ROS2Subscriber(topic, type_name, inbox.on(topic), domain_id=0, router_port=port, qos=qos)
            for topic, type_name, qos in [("/clock", "rosgraph_msgs/msg/Clock", None),
                                          ("/cdus/usv1/pose", "geometry_msgs/msg/PoseStamped", None),
                                          ("/cdus/uav1/odom", "nav_msgs/msg/Odometry", None)]]
    try:
        clocks = inbox.wait("/clock", 50)
        poses = inbox.wait("/cdus/usv1/pose", 2)
        odoms = inbox.wait("/cdus/uav1/odom", 2)
    finally:
        for s in subs:
            s.close()
    ns = [c.clock.sec * 1_000_000_000 + c.clock.nanosec for c in clocks]
    assert all(b > a for a, b in zip(ns, ns[1:])), "/clock went back or repeated"
    assert all(n % round(CONTROL_PERIOD * 1e9) == 0 for n in ns), "a /clock off the control ticks"
    assert ns[-1] - ns[0] >= 49 * CONTROL_PERIOD * 1e9 - 1

    p = poses[-1]
    assert p.header.frame_id == "world"
    assert (p.pose.position.x + 40) ** 2 + (p.pose.position.y - 50) ** 2 < 40 ** 2  # near its circle at (-40, 50)
    assert p.pose.position.z == 0.0  # a boat
    assert (p.header.stamp.sec * 1_000_000_000 + p.header.stamp.nanosec) % round(0.1e9) == 0  # [ros2] rate 10 Hz
    assert p.pose.orientation.z ** 2 + p.pose.orientation.w ** 2 == pytest.approx(1.0)
    o = odoms[-1]
    assert (o.header.frame_id, o.child_frame_id) == ("world", "uav1/base_link")
    assert 1.0 < o.pose.pose.position.z < 21.0  # a UAV in the air, climbing to its 20 m circle
    assert o.twist.twist.linear.x > 0

    # The paths, published once before anyone subscribed, reach a late subscriber as rmw_zenoh
    # subscribes to a transient-local topic: a zenoh-ext AdvancedSubscriber with history and
    # late-publisher detection. (zenoh-ros2-sdk 0.1.8 finds transient-local publishers only on
    # topics of one name chunk: its liveliness pattern does not mangle a namespaced topic's inner
    # slashes, so it is not used for this.)
    key = topic_key(0, "/cdus/usv2/path", "nav_msgs/msg/Path")
    session = zenoh.open(zenoh_config(Transport(mode="client", config_file=str(run / "secure" / "ros2-client.json5"))))
    got: list[bytes] = []
    cond = threading.Condition()

    def on(sample):
        with cond:
            got.append(sample.payload.to_bytes())
            cond.notify_all()

    try:
        sub = zenoh.ext.declare_advanced_subscriber(session, key, on, history=zenoh.ext.HistoryConfig(
            detect_late_publishers=True, max_samples=1))
        with cond:
            assert cond.wait_for(lambda: got, timeout=30), "no cached path"
        sub.undeclare()
    finally:
        session.close()
    path = get_typestore(Stores.ROS2_JAZZY).deserialize_cdr(got[0], "nav_msgs/msg/Path")
    assert len(path.poses) == 401 and path.header.frame_id == "world"  # one period of the circle, closed
    assert all((q.pose.position.x + 40) ** 2 + (q.pose.position.y - 50) ** 2 == pytest.approx(100)
               for q in path.poses)
