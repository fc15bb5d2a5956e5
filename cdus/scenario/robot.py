"""Is a vehicle's ``ros2`` table valid? Where a ``plant = "ros2"`` vehicle hears and drives its robot.

A vehicle with ``plant = "ros2"`` (docs/ros2.md, "A ROS 2 robot as one of the vehicles") is a
real robot: its agent reads the robot's ``nav_msgs/msg/Odometry`` on ``ros2.odom`` and sends its
guidance as ``geometry_msgs/msg/Twist`` on ``ros2.cmd_vel``, in the domain and distribution of
``[ros2]``; odometry older than ``ros2.timeout`` seconds (wall clock) makes the vehicle hold.
Only the realtime clock can drive a robot: :func:`clock_problem` says why a lockstep run is
refused.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

from cdus.scenario.checks import Problems
from cdus.scenario.ros2 import NAMESPACE_RE, ros_name

ROBOT_PLANT = "ros2"
ROBOT_KEYS = ("odom", "cmd_vel", "timeout")
DEFAULT_TIMEOUT = 0.5  # s of wall clock without odometry before the vehicle holds
MAX_TIMEOUT = 60.0


@dataclass(frozen=True)
class RobotSpec:
    """The validated ``ros2`` table of a ``plant = "ros2"`` vehicle."""

    odom: str  # fully qualified topic: /usv1/odom
    cmd_vel: str  # fully qualified topic: /usv1/cmd_vel
    timeout: float = DEFAULT_TIMEOUT


def robot_table(p: Problems, raw: Any, field: str, plant: str | None, vid: str | None) -> RobotSpec | None:
    """``ros2 = { odom = "/usv1/odom", cmd_vel = "/usv1/cmd_vel", timeout = 0.5 }`` of one vehicle
    (``field``: its name in the file). Only a ``plant = "ros2"`` vehicle takes it; the topics
    default to ``/<vehicle>/odom`` and ``/<vehicle>/cmd_vel``."""
    if plant != ROBOT_PLANT:
        if raw is not None and plant is not None:
            p.add(field, f'only used by plant = "{ROBOT_PLANT}" (a real robot); remove it')
        return None
    table = p.table({} if raw is None else raw, field, 'ros2 = { odom = "/usv1/odom" }')
    if table is None or vid is None:
        return None
    p.unknown_keys(table, ROBOT_KEYS, field)
    name = ros_name(vid)
    topics = []
    for key, default in (("odom", f"/{name}/odom"), ("cmd_vel", f"/{name}/cmd_vel")):
        topic = p.string(table.get(key, default), f"{field}.{key}")
        if topic is not None and (topic == "/" or not NAMESPACE_RE.match(topic)):
            p.add(f"{field}.{key}", f"must be a fully qualified ROS 2 topic such as {default!r} (a leading /, "
                                    f"names of letters, digits and _ starting with a letter), got {topic!r}")
            topic = None
        topics.append(topic)
    timeout = p.number(table.get("timeout", DEFAULT_TIMEOUT), f"{field}.timeout", gt=0, le=MAX_TIMEOUT,
                       unit=" s without odometry before the vehicle holds")
    if None in topics or timeout is None:
        return None
    return RobotSpec(topics[0], topics[1], float(timeout))


def topic_clashes(p: Problems, vehicles: Sequence[Any], ros2: Any) -> None:
    """Two robots on one odometry or one command topic (each would take the other's odometry, or
    one robot both vehicles' commands, and the router lets both robots publish it), or a robot's
    odometry on a topic the fleet's own ROS 2 face publishes (``[ros2] enabled``: the bridge's
    Odometry of ``<namespace>/<vehicle>/odom``, which the vehicle would take for its robot's): a
    problem naming the field, with the fix. ``vehicles``: the scenario's specs (None: not valid)."""
    ns = ros2.namespace.strip("/")
    bridge = {"/" + "/".join(x for x in (ns, ros_name(v.id), "odom") if x): v.id
              for v in vehicles if v is not None} if ros2.enabled else {}
    taken: dict[tuple[str, str], str] = {}
    for i, v in enumerate(vehicles):
        if v is None or v.robot is None:
            continue
        for key in ("odom", "cmd_vel"):
            topic, field = getattr(v.robot, key), f"vehicle[{i}] (id \"{v.id}\").ros2.{key}"
            other = taken.setdefault((key, topic), v.id)
            if other != v.id:
                p.add(field, f"{topic!r} is also the {key} topic of robot {other!r}: give each robot its own "
                             f"(the default is '/{ros_name(v.id)}/{key}')")
        if v.robot.odom in bridge:
            p.add(f"vehicle[{i}] (id \"{v.id}\").ros2.odom",
                  f"{v.robot.odom!r} is where cdus publishes the odometry of vehicle {bridge[v.robot.odom]!r} "
                  f"([ros2] enabled, namespace {ros2.namespace!r}), which the vehicle would take for its robot's: "
                  f"give the robot a topic of its own (e.g. '/{ros_name(v.id)}/robot/odom') or [ros2] another "
                  f"namespace")


def clock_problem(scenario: Any, clock: str) -> str | None:
    """Why a run on ``clock`` (``realtime``, ``lockstep``, ``inproc``) cannot drive this
    scenario's robots, or None: only a realtime run moves in real time, as a robot does."""
    if clock == "realtime":
        return None
    for v in scenario.vehicles:
        if v.plant == ROBOT_PLANT:
            what = "cdus sim (the inproc clock)" if clock == "inproc" else f"the {clock} clock"
            return (f"vehicle {v.id!r} has plant = \"{ROBOT_PLANT}\", a real robot that moves in real time, and "
                    f"{what} steps as fast as the machine allows: run it with cdus launch --clock realtime")
    return None


def robots(scenario: Any) -> Mapping[str, RobotSpec]:
    """The robot vehicles of ``scenario`` by id."""
    return {v.id: v.robot for v in scenario.vehicles if v.robot is not None}
