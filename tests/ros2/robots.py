"""A stand-in ROS 2 robot for the tests of ``plant = "ros2"``: its messages built and read by
rosbags (an independent CDR implementation with the ROS 2 Jazzy types), never by cdus.ros2."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import zenoh
import zenoh.ext as ze
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


class FakeRobot:
    """A holonomic robot on its own Zenoh session: it integrates the (world-frame) Twist it hears
    on ``cmd_key`` and publishes its Odometry on ``odom_key`` every ``period`` s of wall clock,
    until :meth:`stop` (``silent``: it stops publishing but keeps running)."""

    def __init__(self, session, odom_key: str, cmd_key: str, start=(0.0, 0.0), period: float = 0.05):
        self.session, self.period = session, period
        self.q = list(start)
        self.v = (0.0, 0.0, 0.0)
        self.twists = 0
        self.attachments: list[tuple[int, int, bytes]] = []  # (sequence, source time ns, GID) as Zenoh reads them
        self.silent = False
        self._stop = threading.Event()
        self.pub = session.declare_publisher(odom_key)
        self.sub = session.declare_subscriber(cmd_key, self._on_twist)
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _on_twist(self, sample) -> None:
        self.v = read_twist(sample.payload.to_bytes())
        if sample.attachment is not None:
            self.attachments.append(ze.z_deserialize(tuple[ze.Int64, ze.Int64, bytes],
                                                     zenoh.ZBytes(sample.attachment.to_bytes())))
        self.twists += 1

    def _run(self) -> None:
        last = time.monotonic()
        while not self._stop.wait(self.period):
            now = time.monotonic()
            dt, last = now - last, now
            self.q = [x + dt * v for x, v in zip(self.q, self.v)]
            yaw = math.atan2(self.v[1], self.v[0]) if any(self.v[:2]) else 0.0
            speed = math.hypot(self.v[0], self.v[1])
            if not self.silent:
                self.pub.put(odometry_bytes(self.q, yaw, (speed, 0.0, 0.0), time.time()))

    def start(self) -> "FakeRobot":
        self.thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self.thread.join(timeout=5)
        self.sub.undeclare()
        self.pub.undeclare()
