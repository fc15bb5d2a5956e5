"""A stand-in ROS 2 robot for the tests of ``plant = "ros2"``, written with zenoh-ros2-sdk
(:class:`SdkRobot`), and Odometry and Twist bytes built and read by rosbags (an independent CDR
implementation with the ROS 2 Jazzy types), never by cdus.ros2."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
from rosbags.typesys import Stores, get_typestore

STORE = get_typestore(Stores.ROS2_JAZZY)
T = STORE.types
ODOM, TWIST = "nav_msgs/msg/Odometry", "geometry_msgs/msg/Twist"


def odometry_bytes(q, yaw: float, body_v=(0.0, 0.0, 0.0), t: float = 0.0, frame: str = "map") -> bytes:
    """rosbags' CDR of an Odometry at ``q`` (2 or 3 values) facing ``yaw``, twist ``body_v`` in
    the body frame."""
    x, y, z = (*q, 0.0)[:3] if len(q) == 2 else q
    vec = T["geometry_msgs/msg/Vector3"]
    msg = T[ODOM](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=int(t), nanosec=int((t % 1) * 1e9)),
                                        frame_id=frame),
        child_frame_id="base_link",
        pose=T["geometry_msgs/msg/PoseWithCovariance"](
            pose=T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=float(z)),
                orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))),
            covariance=np.zeros(36)),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T[TWIST](linear=vec(x=float(body_v[0]), y=float(body_v[1]), z=float(body_v[2])),
                           angular=vec(x=0.0, y=0.0, z=0.0)),
            covariance=np.zeros(36)))
    return bytes(STORE.serialize_cdr(msg, ODOM))


def read_twist(data: bytes) -> tuple[float, float, float]:
    m = STORE.deserialize_cdr(bytes(data), TWIST)
    return (m.linear.x, m.linear.y, m.linear.z)


class SdkRobot:
    """A holonomic robot written with zenoh-ros2-sdk (code nobody here wrote): its ROS2Subscriber
    hears the (world-frame) Twist on ``cmd_vel``, which it integrates, and its ROS2Publisher sends
    its Odometry on ``odom`` every ``period`` s of wall clock, until :meth:`stop` (``silent``: it
    stops publishing but keeps running). The SDK makes the messages, the keys, the type hashes
    (from the .msg files of its registry), the attachments and the graph tokens; it connects to
    the router on 127.0.0.1:``port``. ``attachments``: the Twist's, as the SDK parses them."""

    def __init__(self, port: int, odom: str, cmd_vel: str, start=(0.0, 0.0), period: float = 0.05):
        import zenoh_ros2_sdk as sdk
        from zenoh_ros2_sdk.attachment import Attachment

        self.period = period
        self.q = list(start)
        self.v = (0.0, 0.0, 0.0)
        self.twists = 0
        self.attachments: list[Attachment] = []
        self.silent = False
        self._stop = threading.Event()
        self.pub = sdk.ROS2Publisher(odom, ODOM, node_name="stand_in", domain_id=0, router_port=port)
        self.sub = sdk.ROS2Subscriber(cmd_vel, TWIST, self._on_twist, node_name="stand_in", domain_id=0,
                                      router_port=port)
        zs = self.pub.session_mgr.session  # the SDK's own session: the Twist's attachment, read by the SDK
        self.raw = zs.declare_subscriber(self.sub.keyexpr, lambda s: self.attachments.append(
            Attachment.from_bytes(s.attachment.to_bytes())) if s.attachment is not None else None)
        self.types = self.pub.session_mgr.store.types
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _on_twist(self, msg) -> None:
        self.v = (msg.linear.x, msg.linear.y, msg.linear.z)
        self.twists += 1

    def _odometry(self, yaw: float, speed: float, t: float) -> dict:
        T = self.types
        x, y, z = (*self.q, 0.0)[:3]
        vec = T["geometry_msgs/msg/Vector3"]
        return dict(
            header=T["std_msgs/msg/Header"](
                stamp=T["builtin_interfaces/msg/Time"](sec=int(t), nanosec=int((t % 1) * 1e9)), frame_id="map"),
            child_frame_id="base_link",
            pose=T["geometry_msgs/msg/PoseWithCovariance"](
                pose=T["geometry_msgs/msg/Pose"](
                    position=T["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=float(z)),
                    orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2),
                                                                  w=math.cos(yaw / 2))),
                covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T[TWIST](linear=vec(x=speed, y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=0.0)),
                covariance=np.zeros(36)))

    def _run(self) -> None:
        last = time.monotonic()
        while not self._stop.wait(self.period):
            now = time.monotonic()
            dt, last = now - last, now
            self.q = [x + dt * v for x, v in zip(self.q, self.v)]
            yaw = math.atan2(self.v[1], self.v[0]) if any(self.v[:2]) else 0.0
            if not self.silent:
                self.pub.publish(**self._odometry(yaw, math.hypot(self.v[0], self.v[1]), time.time()))

    def start(self) -> "SdkRobot":
        self.thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self.thread.join(timeout=5)
        self.raw.undeclare()
        self.sub.close()
        self.pub.close()
