"""What does a ROS 2 robot say to its vehicle, and what is it told? Its odometry read into a pose,
the guidance command written as a Twist (docs/ros2.md, "A ROS 2 robot as one of the vehicles").

Pure: the agent of a ``plant = "ros2"`` vehicle (vehicle_agent.robot) carries the bytes.

- In: ``nav_msgs/msg/Odometry``. Position from ``pose.pose.position`` (x, y; z too for a drone),
  heading the yaw of ``pose.pose.orientation`` (about z, 0 along x, counter-clockwise), the
  world-frame velocity ``twist.twist.linear`` (x, y) turned by that yaw (REP-105: the twist is
  in the child, body, frame). The frame ids are not checked: the pose must be in the frame the
  scenario's paths are in.
- Out: ``geometry_msgs/msg/Twist`` whose ``linear`` is the guidance's velocity in the **world
  frame** (x, y, and z for a drone), ``angular`` zero: the DGVF velocity of a holonomic vehicle;
  a robot that takes body-frame commands turns it by its own heading (docs/ros2.md).
- To the fleet: a spell without odometry (the agent's :class:`cdus.wire.stats.OdometryGap`, in its
  counters) as the world's events ``odometry_stale`` at its start and ``odometry_back`` at its
  end (:func:`gap_events`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

from cdus.ros2 import cdr
from cdus.wire.bounds import BOUNDS, MAX_LIMIT, within
from cdus.wire.events import FleetEvent
from cdus.wire.rejected import Rejected
from cdus.wire.stats import OdometryGap

ODOM, TWIST = "nav_msgs/msg/Odometry", "geometry_msgs/msg/Twist"
#: why an odometry payload is dropped: longer than MAX_ODOM_BYTES, cdr.decode's reasons, a
#: non-finite value, a position or velocity out of bounds, a zero quaternion
ODOM_REASONS = ("oversized", *cdr.DECODE_REASONS, "nonfinite", "range", "orientation")
#: bytes: an Odometry is 716 with short frame ids; a 20 MB one took 19 ms to decode, 8 a tick
MAX_ODOM_BYTES = 1 << 16
#: a position as a scenario's (paths and starts within ±1,000 km): beyond, the guidance's
#: squared distances overflowed (a pose at x = 1e200 raised OverflowError in the agent's step)
POSITION = BOUNDS["vehicle.start.position"]
VELOCITY = within(MAX_LIMIT)  # m/s, each component of the twist: no vehicle's limits go beyond


@dataclass(frozen=True)
class RobotPose:
    """What a vehicle takes from one odometry message: position, world-frame velocity, heading."""

    q: tuple[float, ...]
    v: tuple[float, ...]
    heading: float
    stamp: float  # s, the message's header stamp


def yaw_of(x: float, y: float, z: float, w: float) -> float:
    """The rotation about z of the quaternion (x, y, z, w) (not necessarily normalised)."""
    return math.atan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)


def read_odometry(data: bytes, dim: int) -> RobotPose | Rejected:
    """The pose in one Odometry payload (``dim`` 2 for a boat, 3 for a drone), or ``Rejected``
    with one of :data:`ODOM_REASONS`. Never raises. The header's stamp is read, not judged: the
    robot's clock need not be the host's (the agent ages odometry by its arrival)."""
    if len(data) > MAX_ODOM_BYTES:
        return Rejected("oversized")
    m = cdr.decode(ODOM, data)
    if isinstance(m, Rejected):
        return m
    p, o = m["pose"]["pose"]["position"], m["pose"]["pose"]["orientation"]
    lin = m["twist"]["twist"]["linear"]
    quat = (o["x"], o["y"], o["z"], o["w"])
    values = (p["x"], p["y"], p["z"], lin["x"], lin["y"], lin["z"], *quat)
    if not all(math.isfinite(x) for x in values):
        return Rejected("nonfinite")
    norm = sum(x * x for x in quat)
    if not norm > 1e-12 or not math.isfinite(norm):
        return Rejected("orientation")
    psi = yaw_of(*quat)
    c, s = math.cos(psi), math.sin(psi)
    v = (lin["x"] * c - lin["y"] * s, lin["x"] * s + lin["y"] * c, lin["z"])
    q = (p["x"], p["y"], p["z"])[:dim]
    if not all(POSITION.holds(x) for x in q) or not all(VELOCITY.holds(lin[k]) for k in "xyz"[:dim]):
        return Rejected("range")
    stamp = m["header"]["stamp"]
    return RobotPose(q, v[:dim], psi, stamp["sec"] + stamp["nanosec"] * 1e-9)


def twist(u: Sequence[float] | None) -> dict:
    """The Twist of a world-frame velocity command ``u`` (None or empty: hold, all zero)."""
    u = tuple(u or ())
    lin = {"x": float(u[0]) if u else 0.0, "y": float(u[1]) if len(u) > 1 else 0.0,
           "z": float(u[2]) if len(u) > 2 else 0.0}
    return {"linear": lin, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}


def gap_events(vid: str, odom: str, timeout: float, gap: OdometryGap) -> list[FleetEvent]:
    """The fleet events of one spell of vehicle ``vid`` without odometry on topic ``odom``: when
    it began and, if it ended, when it ended (kinds ``odometry_stale``, ``odometry_back``)."""
    out = [FleetEvent.of(gap.t, "odometry_stale", f"{vid}: no odometry from {odom} for {timeout:g} s (from "
                         f"t = {gap.t:.2f} s): it holds, zero velocity sent, no ω broadcast", vehicle=vid, origin=vid)]
    if gap.back is not None:
        out.append(FleetEvent.of(gap.back, "odometry_back", f"{vid}: odometry from {odom} back at t = {gap.back:.2f} s "
                                 f"after {gap.back - gap.t:.2f} s without: it follows again", vehicle=vid, origin=vid))
    return out
