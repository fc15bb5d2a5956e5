"""What does the fleet look like in ROS 2? Its topics, frames and messages (docs/ros2.md).

Pure: the bridge (:mod:`cdus.ros2.bridge`) publishes these messages from the fleet's telemetry
as it runs, the MCAP export (:mod:`cdus.ros2.export`) writes the same from a run's trace.

Per vehicle ``<v>`` (its id as a ROS name, :func:`cdus.scenario.ros2.ros_name`), under the
namespace ``<ns>`` of ``[ros2]``:

    <ns>/<v>/pose        geometry_msgs/msg/PoseStamped  in the world frame
    <ns>/<v>/odom        nav_msgs/msg/Odometry          pose in the world frame, twist in <v>/base_link
    <ns>/<v>/omega       std_msgs/msg/Float64           ω, the vehicle's coordination state
    <ns>/<v>/omega_rate  std_msgs/msg/Float64           ω̇
    <ns>/<v>/path        nav_msgs/msg/Path              the prescribed path (transient local)

For the fleet: ``/tf`` (tf2_msgs/msg/TFMessage: ``<world frame>`` -> ``<v>/base_link``),
``/clock`` (rosgraph_msgs/msg/Clock, the simulated time) and ``<ns>/events``
(std_msgs/msg/String, each fleet event as JSON).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

from cdus.ros2.rmw import Node, Qos, topic_key
from cdus.scenario.robot import robots
from cdus.scenario.ros2 import Ros2Spec, ros_name
from cdus.wire.access import RobotGrant, Ros2Grant

POSE, ODOM, FLOAT, PATH = ("geometry_msgs/msg/PoseStamped", "nav_msgs/msg/Odometry", "std_msgs/msg/Float64",
                           "nav_msgs/msg/Path")
TF, CLOCK, STRING = "tf2_msgs/msg/TFMessage", "rosgraph_msgs/msg/Clock", "std_msgs/msg/String"
BASE_LINK = "base_link"
DATA_QOS = Qos(depth=10)
LATCHED_QOS = Qos(depth=1, transient_local=True)  # a late subscriber (RViz opened later) still gets the paths
CLOCK_QOS = Qos(depth=1)


@dataclass(frozen=True)
class Topic:
    """One publisher of the fleet's ROS 2 node."""

    name: str  # fully qualified: /cdus/usv1/pose
    type_name: str
    qos: Qos
    vehicle: str | None = None  # the vehicle id it is about, None for the fleet's
    field: str = ""  # which of the vehicle's: pose, odom, omega, omega_rate, path


VEHICLE_TOPICS = (("pose", POSE, DATA_QOS), ("odom", ODOM, DATA_QOS), ("omega", FLOAT, DATA_QOS),
                  ("omega_rate", FLOAT, DATA_QOS), ("path", PATH, LATCHED_QOS))


def _join(ns: str, *names: str) -> str:
    return "/" + "/".join(p for p in (ns.strip("/"), *names) if p)


def topics(spec: Ros2Spec, ids: Sequence[str]) -> list[Topic]:
    """Every topic the fleet publishes, the fleet's first (/clock, /tf, events), then each vehicle's."""
    out = [Topic("/clock", CLOCK, CLOCK_QOS, field="clock"), Topic("/tf", TF, DATA_QOS, field="tf"),
           Topic(_join(spec.namespace, "events"), STRING, DATA_QOS, field="events")]
    for vid in ids:
        out += [Topic(_join(spec.namespace, ros_name(vid), f), t, q, vid, f) for f, t, q in VEHICLE_TOPICS]
    return out


def key(spec: Ros2Spec, topic: Topic) -> str:
    """The Zenoh key ``topic``'s data goes to."""
    return topic_key(spec.domain_id, topic.name, topic.type_name, spec.distro)


def grant(spec: Ros2Spec, ids: Sequence[str]) -> Ros2Grant:
    """What a secured fleet's access-control list lets the ROS 2 side use (cdus.wire.access)."""
    return Ros2Grant(spec.domain_id, tuple(key(spec, t) for t in topics(spec, ids)))


#: a robot vehicle's ROS node (vehicle_agent.robot): its name and its command publisher's entity id
ROBOT_CMD_ENTITY = 1
TWIST = "geometry_msgs/msg/Twist"


def robot_node(domain: int, zid: str, vid: str) -> Node:
    """The ROS node of a ``plant = "ros2"`` vehicle's agent: ``cdus_<vehicle>`` in the root namespace."""
    return Node(domain, zid, "cdus_" + ros_name(vid), "/")


def robot_grants(scenario: Any) -> tuple[RobotGrant, ...]:
    """What a secured fleet's access-control list lets each robot and its vehicle use (cdus.wire.access)."""
    ros = scenario.ros2
    out = []
    for vid, r in robots(scenario).items():
        node = robot_node(ros.domain_id, "*", vid)
        tokens = (node.token(), node.publisher_token(ROBOT_CMD_ENTITY, r.cmd_vel, TWIST, DATA_QOS, ros.distro))
        out.append(RobotGrant(vid, topic_key(ros.domain_id, r.odom, ODOM, ros.distro),
                              topic_key(ros.domain_id, r.cmd_vel, TWIST, ros.distro), tokens,
                              f"@ros2_lv/{ros.domain_id}/**"))
    return tuple(out)


def node_name(fleet: str) -> str:
    """The bridge's ROS node name: ``cdus_<fleet>`` (``-`` as ``_``)."""
    return "cdus_" + fleet.replace("-", "_")


def child_frame(vid: str) -> str:
    return f"{ros_name(vid)}/{BASE_LINK}"


def stamp(t: float) -> dict:
    """builtin_interfaces/msg/Time of ``t`` simulated seconds (nanoseconds rounded)."""
    ns = max(0, round(t * 1e9))
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def yaw(heading: float) -> dict:
    """The quaternion of a rotation by ``heading`` about z (ENU: 0 along x, counter-clockwise)."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(heading / 2.0), "w": math.cos(heading / 2.0)}


def _point(q: Sequence[float]) -> dict:
    return {"x": float(q[0]), "y": float(q[1]), "z": float(q[2]) if len(q) > 2 else 0.0}


def pose(t: float, q: Sequence[float], heading: float, frame: str) -> dict:
    return {"header": {"stamp": stamp(t), "frame_id": frame},
            "pose": {"position": _point(q), "orientation": yaw(heading)}}


def odometry(t: float, vid: str, q: Sequence[float], heading: float, speed: float, frame: str,
             yaw_rate: float = 0.0) -> dict:
    """Pose in ``frame``; twist in the vehicle's frame: its speed along its heading (linear.x) and
    its yaw rate (angular.z, :func:`yaw_rate`). Covariances zero: the emulator's state is exact."""
    return {"header": {"stamp": stamp(t), "frame_id": frame}, "child_frame_id": child_frame(vid),
            "pose": {"pose": {"position": _point(q), "orientation": yaw(heading)}},
            "twist": {"twist": {"linear": {"x": float(speed)}, "angular": {"z": float(yaw_rate)}}}}


def yaw_rate(heading: float, t: float, before: tuple[float, float] | None) -> float:
    """The heading's rate since ``before`` = (its time, its heading), the difference wrapped to
    (-π, π]; 0 without an earlier row or time (telemetry carries headings, no rates)."""
    if before is None or t <= before[0]:
        return 0.0
    d = math.remainder(heading - before[1], 2 * math.pi)
    return d / (t - before[0])


def transforms(t: float, rows: Iterable[tuple[str, Sequence[float], float]], frame: str) -> dict:
    """/tf: one transform ``frame`` -> ``<v>/base_link`` per (vehicle id, position, heading)."""
    return {"transforms": [{"header": {"stamp": stamp(t), "frame_id": frame}, "child_frame_id": child_frame(vid),
                            "transform": {"translation": _point(q), "rotation": yaw(h)}}
                           for vid, q, h in rows]}


def value(x: float) -> dict:
    return {"data": float(x)}


def clock(t: float) -> dict:
    return {"clock": stamp(t)}


def path(points: Any, frame: str, t: float = 0.0) -> dict:
    """nav_msgs/msg/Path of [M, 3] points (orientation identity: a path has no heading)."""
    head = {"stamp": stamp(t), "frame_id": frame}
    return {"header": head, "poses": [{"header": head, "pose": {"position": _point(p), "orientation": {"w": 1.0}}}
                                      for p in points]}


def vehicle_messages(vid: str, t: float, q: Sequence[float], heading: float, speed: float, omega: float,
                     omega_rate: float, frame: str, rate_of_yaw: float = 0.0) -> list[tuple[tuple[str | None, str], dict]]:
    """What one telemetry row of vehicle ``vid`` publishes: ((vehicle or None, field), message)
    for its pose, odometry, ω, ω̇ and its /tf transform; the bridge and the MCAP export alike."""
    return [((vid, "pose"), pose(t, q, heading, frame)),
            ((vid, "odom"), odometry(t, vid, q, heading, speed, frame, rate_of_yaw)),
            ((vid, "omega"), value(omega)), ((vid, "omega_rate"), value(omega_rate)),
            ((None, "tf"), transforms(t, [(vid, q, heading)], frame))]


def every(spec: Ros2Spec, control_rate: float) -> int:
    """Control ticks between two publications of the per-vehicle topics and /tf (at least 1)."""
    return max(1, round(control_rate / spec.rate))
