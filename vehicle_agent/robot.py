"""How does an agent drive a real robot? A ``plant = "ros2"`` vehicle's agent: the robot's odometry
in, its guidance out as a Twist, over the fleet's own Zenoh session (docs/ros2.md, "A ROS 2 robot
as one of the vehicles").

:class:`RobotAgent` is an :class:`vehicle_agent.agent.Agent` whose vehicle is measured, not
simulated (cdus.core.robot). On its session it subscribes to the robot's
``nav_msgs/msg/Odometry`` at rmw_zenoh's key (a ring of the newest few samples: only the newest
pose matters) and publishes ``geometry_msgs/msg/Twist`` with rmw_zenoh's attachment and a
publisher liveliness token (a node ``cdus_<vehicle>`` of its own). At every tick it takes the
newest valid pose as the vehicle's state, steps the tick as any vehicle (ω with the fleet, DGVF
guidance) and sends the command the plant was asked to fly. A malformed payload is counted by
reason (``odom_<reason>``: cdus.ros2.robot.ODOM_REASONS) and dropped.

Without odometry for longer than ``ros2.timeout`` s (wall clock; none yet counts as none) the
vehicle holds: it logs one line, sends zero velocity every tick and does not step, so it
broadcasts no ω and its neighbours' stale-neighbour machinery handles it as a silent vehicle.
When odometry comes back it logs one line and rejoins the run at the current tick from the
measured pose (cdus.core.node.VehicleNode.rejoin), ω near where it was. Each spell (the wait for
the first odometry included) goes to the world in the agent's counters as an
:class:`cdus.wire.stats.OdometryGap` (the newest ODOM_GAPS, sent at once when one begins or
ends), which the world shows as the events ``odometry_stale`` and ``odometry_back``. The realtime clock only
(cdus.scenario.robot.clock_problem refuses a lockstep one).
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import replace
from typing import Any

import zenoh

from cdus.core.robot import RobotState
from cdus.ros2 import fleet as rf
from cdus.ros2.publisher import Publisher
from cdus.ros2.rmw import topic_key
from cdus.ros2.robot import ODOM, TWIST, RobotPose, read_odometry, twist
from cdus.scenario.robot import clock_problem
from cdus.wire.rejected import Rejected
from cdus.wire.stats import AgentStats, OdometryGap
from vehicle_agent.agent import Agent
from vehicle_agent.report import Report

ODOM_RING = 8  # odometry samples kept between two ticks (the newest valid one is taken)
ODOM_GAPS = 8  # the newest spells without odometry each report carries (cdus.wire.stats.MAX_ODOMETRY_GAPS)


class RobotReport(Report):
    """A robot's reports: every vehicle's, and its newest spells without odometry in its counters."""

    def stats(self, final: bool = False) -> AgentStats:
        return replace(super().stats(final), odometry_gaps=tuple(self.agent.gaps))


class RobotAgent(Agent):
    """The agent of a ``plant = "ros2"`` vehicle (see the module's docstring)."""

    def __init__(self, *args: Any, **kwargs: Any):
        super().__init__(*args, **kwargs)
        if (why := clock_problem(self.scenario, self.loop.name)) is not None:
            raise ValueError(f"--clock: {why}")
        spec = self.scenario.vehicle(self.id)
        self.robot = spec.robot
        self.dim = spec.dim
        self.ros = self.scenario.ros2
        self.odom_sub: Any = None
        self.cmd: Publisher | None = None
        self.node_token: Any = None
        self.pose: RobotPose | None = None
        self.heard = 0.0  # time.monotonic() of the newest valid odometry
        self.holding = True  # until the first odometry
        self.holds = 0  # times the vehicle began to hold (the first wait included)
        self.odom_taken = 0
        self.gaps: deque[OdometryGap] = deque(maxlen=ODOM_GAPS)  # newest last; the last open while holding
        self.report = RobotReport(self)

    # ------------------------------------------------------------------ zenoh wiring
    def open(self) -> None:
        super().open()
        s, r, ros = self.session, self.robot, self.ros
        key = topic_key(ros.domain_id, r.odom, ODOM, ros.distro)
        self.odom_sub = s.declare_subscriber(key, zenoh.handlers.RingChannel(ODOM_RING))
        node = rf.robot_node(ros.domain_id, str(s.info.zid()), self.id)
        self.node_token = s.liveliness().declare_token(node.token())
        topic = rf.Topic(r.cmd_vel, TWIST, rf.DATA_QOS, self.id, "cmd_vel")
        self.cmd = Publisher(s, node, rf.ROBOT_CMD_ENTITY, topic,
                             topic_key(ros.domain_id, r.cmd_vel, TWIST, ros.distro), ros.distro)
        self.log(f"robot: odometry from {r.odom}, commands (world-frame Twist) to {r.cmd_vel}, domain "
                 f"{ros.domain_id}; holding until its odometry comes (timeout {r.timeout:g} s)")

    def close(self) -> None:
        if self.session is not None:
            try:
                if self.cmd is not None:
                    self.cmd.publish(twist(None))  # leave the robot stopped
                    self.cmd.close()
                if self.node_token is not None:
                    self.node_token.undeclare()
                if self.odom_sub is not None:
                    self.odom_sub.undeclare()
            except zenoh.ZError as e:
                self.log(f"while closing the robot's topics: {e}")
        self.cmd = self.node_token = self.odom_sub = None
        self.log(f"robot: {self.odom_taken} odometry messages taken, held {self.holds} times")
        super().close()

    # ------------------------------------------------------------------ the tick
    def take_odometry(self) -> None:
        """The newest valid pose of what arrived; each malformed payload counted and dropped."""
        if self.odom_sub is None:
            return
        while (sample := self.odom_sub.try_recv()) is not None:
            self.feed_odometry(sample.payload.to_bytes())

    def feed_odometry(self, data: bytes, now: float | None = None) -> None:
        """One odometry payload (the public door of the tests): taken, or counted by reason."""
        pose = read_odometry(data, self.dim)
        if isinstance(pose, Rejected):
            self.intake.reject(self.robot.odom, f"odom_{pose.reason}")
            return
        self.pose = pose
        self.heard = time.monotonic() if now is None else now
        self.odom_taken += 1

    def step(self, n: int) -> None:
        self.take_odometry()
        age = time.monotonic() - self.heard
        if self.pose is None or age > self.robot.timeout:
            if not self.holding:
                self.holding = True
                self.holds += 1
                self.log(f"odometry stale: none from {self.robot.odom} for {age:.2f} s (timeout "
                         f"{self.robot.timeout:g} s): holding at tick {n}, zero velocity sent, no ω broadcast")
                self._gap(OdometryGap(n * self.period))
            elif self.holds == 0:
                self.holds = 1
                self._gap(OdometryGap(n * self.period))
            self._send(None)
            return
        p, node = self.pose, self.node
        v = node.vehicle
        if self.holding:
            self.holding = False
            node.rejoin(n, p.q, p.heading, v.omega)
            self.log(f"odometry from {self.robot.odom}: following at tick {n} from {tuple(round(x, 2) for x in p.q)}")
            if self.gaps and self.gaps[-1].back is None:
                self._gap(replace(self.gaps.pop(), back=n * self.period))
        v.state = RobotState(p.q, p.v, p.heading)
        v.plant.command = None
        super().step(n)
        self._send(v.plant.command)

    def _gap(self, gap: OdometryGap) -> None:
        """A spell without odometry began or ended: to the world at once (the counters of a
        holding vehicle go nowhere else: it does not step)."""
        self.gaps.append(gap)
        self.report.publish_stats()

    def _send(self, u: Any) -> None:
        if self.cmd is not None:
            self.cmd.publish(twist(u))
