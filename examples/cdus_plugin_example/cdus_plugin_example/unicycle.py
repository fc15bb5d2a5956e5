"""What is a unicycle boat? ẋ = v cos ψ, ẏ = v sin ψ, ψ̇ = r, its turn rate |r| at most a limit,
and the heading regulator that steers it along the guidance.

A vehicle model for cdus is a plant (the state, its step, its velocity and heading) and its
regulators (the plant's input that tracks the DGVF's velocity reference a = s f'(ω) - KΦ at
every physics step), declared in one :class:`cdus.core.models.PlantModel`: :data:`UNICYCLE`,
the object the ``cdus.plants`` entry point ``unicycle`` names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cdus.core.guidance import desired_velocity
from cdus.core.models import PlantModel, RegulatorModel

Vec = tuple[float, ...]


@dataclass(frozen=True)
class UnicycleState:
    q: Vec  # position (x, y), m: every plant's state has q
    psi: float  # heading, rad
    v: float  # forward speed it moved with over the last step, m/s


@dataclass(frozen=True)
class Unicycle:
    """The input is (v, r): forward speed in [0, top_speed] and turn rate within ±turn_rate,
    held over a step and integrated exactly along the arc; ``d`` (a current) adds to ẋ, ẏ."""

    turn_rate: float = 0.8  # rad/s
    top_speed: float = 3.0  # m/s
    name: str = "unicycle"
    velocity_level: bool = False  # its input is (v, r), not the velocity reference: a regulator gives it
    exact_when_held: bool = False

    def start(self, q: Vec, heading: float) -> UnicycleState:
        return UnicycleState(tuple(q), heading, 0.0)

    def at_rest(self, state: UnicycleState, q: Vec, heading: float | None) -> UnicycleState:
        return UnicycleState(tuple(q), state.psi if heading is None else heading, 0.0)

    def step(self, state: UnicycleState, u: Vec, d: Vec, h: float) -> UnicycleState:
        v = min(max(u[0], 0.0), self.top_speed)
        r = min(max(u[1], -self.turn_rate), self.turn_rate)
        psi = state.psi + r * h
        if abs(r) > 1e-9:  # along the arc of radius v / r
            dx = v / r * (math.sin(psi) - math.sin(state.psi))
            dy = v / r * (math.cos(state.psi) - math.cos(psi))
        else:
            dx, dy = v * h * math.cos(state.psi), v * h * math.sin(state.psi)
        x, y = state.q
        return UnicycleState((x + dx + h * d[0], y + dy + h * d[1]), psi, v)

    def velocity(self, state: UnicycleState) -> Vec:
        return (state.v * math.cos(state.psi), state.v * math.sin(state.psi))

    def heading(self, state: UnicycleState) -> float:
        return state.psi

    def finite(self, state: UnicycleState) -> bool:
        return math.isfinite(state.q[0] + state.q[1] + state.psi + state.v)


@dataclass(frozen=True)
class HeadingGains:
    k_psi: float = 2.0  # heading error rate, 1/s (a scenario's regulator_gains = { k_psi = ... })


@dataclass(frozen=True)
class HeadingRate:
    """Steer towards the reference's direction ψ_d = atan2(a_y, a_x) at r = k_ψ (ψ_d - ψ), at the
    reference's speed |a| projected on the heading (never backwards)."""

    gains: HeadingGains
    name: str = "heading"

    def command(self, state, path, w, wdot, k, limits, d_hat, shift, h) -> Vec:
        a = desired_velocity(path, state.q, w, k)
        if shift is not None:  # the safety filter's correction (none without [safety])
            a = tuple(x + y for x, y in zip(a, shift))
        err = math.remainder(math.atan2(a[1], a[0]) - state.psi, 2.0 * math.pi)
        speed = min(math.hypot(a[0], a[1]), limits.speed) * max(0.0, math.cos(err))
        return speed, self.gains.k_psi * err


#: the model as a scenario names it: plant = "unicycle", regulator = "heading" (the default),
#: regulator_gains = { k_psi = 2.0 }
UNICYCLE = PlantModel(("usv",), lambda params: Unicycle(), {
    "heading": RegulatorModel(HeadingGains, lambda plant, gains: HeadingRate(gains)),
})
