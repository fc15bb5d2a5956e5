"""What is a vehicle whose plant is a real robot? A plant that does not move by itself.

``plant = "ros2"`` (issue 29, docs/ros2.md): the vehicle's state is the robot's measured pose,
which its agent (vehicle_agent.robot) writes from the robot's odometry before each tick; the
guidance runs on it as on any vehicle. The plant is velocity-level: what
:meth:`cdus.core.vehicle.Vehicle.advance` asks it to fly over the period (the clipped DGVF
velocity, with the safety filter's correction) is kept as :attr:`RobotPlant.command`, the
world-frame velocity the agent sends to the robot, and the state stays the measured one (the
robot moves, not the model). Pure: no clock, no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from cdus.core.paths import Vec
from cdus.core.safety import Point


@dataclass(frozen=True)
class RobotState:
    """The robot as measured: position, world-frame velocity, heading (from its orientation)."""

    q: Vec
    v: Vec
    psi: float


class RobotPlant:
    """``ros2``: the measured robot; :attr:`command` is the last velocity it was asked to fly
    (None before the first tick)."""

    name = "ros2"
    velocity_level = True
    exact_when_held = True

    def __init__(self) -> None:
        self.command: Vec | None = None

    def start(self, q: Vec, heading: float) -> RobotState:
        return RobotState(tuple(q), (0.0,) * len(q), heading)

    def at_rest(self, state: RobotState, q: Vec, heading: float | None) -> RobotState:
        return RobotState(tuple(q), (0.0,) * len(q), state.psi if heading is None else heading)

    def step(self, state: RobotState, u: Vec, d: Vec, h: float) -> RobotState:
        """Keep ``u`` as the command; the state stays the measured one until the next odometry."""
        self.command = tuple(u)
        return state

    def velocity(self, state: RobotState) -> Vec:
        return state.v

    def heading(self, state: RobotState) -> float:
        return state.psi

    def finite(self, state: RobotState) -> bool:
        return math.isfinite(sum(state.q) + sum(state.v) + state.psi)

    def point(self, state: Any, d: Vec, limits: Any) -> Point:
        raise TypeError("the ros2 plant is filtered at the velocity level, not by the dynamic filter")
