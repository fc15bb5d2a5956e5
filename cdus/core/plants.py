"""What moves: the vehicle models (docs/control.md §3), as pure step functions.

- ``ideal``: the lower level tracks perfectly (Problem 1 solved): q̇ = a, held over the
  control period.
- ``uav_double_integrator`` (`UAV_kinetic`): q̇ = p, ṗ = τ.
- ``usv_3dof`` (`USV_kinetic`, `USV_kinematic`):
      ẋ = u cos ψ - v sin ψ,  ẏ = u sin ψ + v cos ψ,  ψ̇ = r
      u̇ = ε1 u + ε2 v r + ε3 τ_u,   ṙ = ε4 r + ε5 τ_r,   v̇ = ε6 v + ε7 u r

``d`` everywhere is an additive world-frame velocity disturbance (current, wind).

Each model is also an object (:class:`Plant`: :class:`IdealPlant`, :class:`DoubleIntegrator`,
:class:`USV3DOF`) that a vehicle is built with (cdus.core.models names them), so the physics
loop calls its plant instead of comparing its name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

from cdus.core.paths import Vec
from cdus.core.safety import Point, uav_point, usv_point

# ε1..ε7 of a standard 3-DOF surface-vessel model with CyberShip II-like masses
# (25.8, 33.8, 2.76) and damping (12, 17, 0.5): ε1 = -d11/m11, ε2 = m22/m11,
# ε3 = 1/m11, ε4 = -d33/m33, ε5 = 1/m33, ε6 = -d22/m22, ε7 = -m11/m22 (docs/control.md §3).
# The paper's HUSTER-12C/16 values are not public; this preset is not them.
USV_PRESETS: dict[str, tuple[float, ...]] = {
    "cybership2": (-0.465, 1.310, 0.0388, -0.181, 0.362, -0.503, -0.763),
}


@dataclass(frozen=True)
class PointState:
    """Ideal plant: a position and the velocity it moved with (for heading and telemetry)."""

    q: Vec
    v: Vec


@dataclass(frozen=True)
class UAVState:
    q: Vec  # position (3)
    p: Vec  # velocity (3)


@dataclass(frozen=True)
class USVState:
    x: float
    y: float
    psi: float  # heading
    u: float  # surge
    v: float  # sway
    r: float  # yaw rate

    @property
    def q(self) -> Vec:
        return (self.x, self.y)

    def world_velocity(self) -> Vec:
        c, s = math.cos(self.psi), math.sin(self.psi)
        return (self.u * c - self.v * s, self.u * s + self.v * c)


def step_ideal(state: PointState, a: Vec, d: Vec, h: float) -> PointState:
    """q ← q + h (a + d): the velocity reference is realised exactly."""
    v = tuple(x + y for x, y in zip(a, d))
    return PointState(tuple(qq + h * vv for qq, vv in zip(state.q, v)), v)


def step_uav(state: UAVState, tau: Vec, d: Vec, h: float) -> UAVState:
    """Exact step of q̇ = p + d, ṗ = τ with τ, d held over h."""
    q = tuple(qq + h * (pp + dd) + 0.5 * h * h * tt for qq, pp, dd, tt in zip(state.q, state.p, d, tau))
    p = tuple(pp + h * tt for pp, tt in zip(state.p, tau))
    return UAVState(q, p)


def usv_derivative(s: USVState, tau_u: float, tau_r: float, eps: tuple[float, ...], d: Vec):
    e1, e2, e3, e4, e5, e6, e7 = eps
    c, sn = math.cos(s.psi), math.sin(s.psi)
    return (
        s.u * c - s.v * sn + d[0],
        s.u * sn + s.v * c + d[1],
        s.r,
        e1 * s.u + e2 * s.v * s.r + e3 * tau_u,
        e6 * s.v + e7 * s.u * s.r,
        e4 * s.r + e5 * tau_r,
    )


def step_usv(s: USVState, tau_u: float, tau_r: float, eps: tuple[float, ...], d: Vec, h: float) -> USVState:
    """One Heun (RK2) step of the ε-model with the inputs held over h."""
    k1 = usv_derivative(s, tau_u, tau_r, eps, d)
    mid = USVState(*(x + h * dx for x, dx in zip(_usv_tuple(s), k1)))
    k2 = usv_derivative(mid, tau_u, tau_r, eps, d)
    return USVState(*(x + 0.5 * h * (a + b) for x, a, b in zip(_usv_tuple(s), k1, k2)))


def _usv_tuple(s: USVState) -> tuple[float, ...]:
    return (s.x, s.y, s.psi, s.u, s.v, s.r)


# --------------------------------------------------------------------------- the plants as objects


class Plant(Protocol):
    """A vehicle model as :class:`cdus.core.vehicle.Vehicle` steps it (built once with the
    vehicle by cdus.core.models; its parameters, such as ε, are its own).

    ``velocity_level``: its input is the velocity reference itself (the guidance is flown as
    is, no regulator; the safety filter corrects the reference at the control instant, with the
    contacts where they are now). Otherwise a regulator turns the reference into the plant's
    input at every physics step, and the dynamic filter (cdus.core.safety) acts on that input,
    with the plant seen as :meth:`point`. ``exact_when_held``: one step of a whole control period
    equals its physics steps when the input and the disturbance are held (the ideal plant)."""

    name: str
    velocity_level: bool
    exact_when_held: bool

    def start(self, q: Vec, heading: float) -> Any:
        """The state at rest at ``q`` (facing ``heading`` where the model has a heading)."""

    def at_rest(self, state: Any, q: Vec, heading: float | None) -> Any:
        """``state`` moved to ``q`` at rest (a rejoin); ``heading`` None keeps its heading."""

    def step(self, state: Any, u: Vec, d: Vec, h: float) -> Any:
        """The state after ``h`` s with the input ``u`` and the disturbance ``d`` held."""

    def velocity(self, state: Any) -> Vec:
        """The world-frame velocity of ``state``."""

    def heading(self, state: Any) -> float:
        """Where ``state`` points (rad)."""

    def finite(self, state: Any) -> bool:
        """Is every component of ``state`` finite?"""

    def point(self, state: Any, d: Vec, limits: Any) -> Point:
        """The dynamic safety filter's model of this plant at ``state`` (cdus.core.safety)."""


class _PointMass:
    """What the ideal plant and the double integrator share: a state (q, velocity) at rest
    with zero velocity, heading along the velocity."""

    _state: type

    def start(self, q: Vec, heading: float) -> Any:
        return self._state(tuple(q), (0.0,) * len(q))

    def at_rest(self, state: Any, q: Vec, heading: float | None) -> Any:
        return self._state(q, (0.0,) * len(q))

    def heading(self, state: Any) -> float:
        v = self.velocity(state)
        return math.atan2(v[1], v[0])

    def finite(self, state: Any) -> bool:
        return math.isfinite(sum(state.q) + sum(self.velocity(state)))


@dataclass(frozen=True)
class IdealPlant(_PointMass):
    """``ideal``: q̇ = a + d, the velocity reference realised exactly (:func:`step_ideal`)."""

    name: str = "ideal"
    velocity_level: bool = True
    exact_when_held: bool = True
    _state = PointState

    def step(self, state: PointState, u: Vec, d: Vec, h: float) -> PointState:
        return step_ideal(state, u, d, h)

    def velocity(self, state: PointState) -> Vec:
        return state.v

    def point(self, state: PointState, d: Vec, limits: Any) -> Point:
        raise TypeError("the ideal plant is filtered at the velocity level, not by the dynamic filter")


@dataclass(frozen=True)
class DoubleIntegrator(_PointMass):
    """``uav_double_integrator``: q̇ = p + d, ṗ = τ (:func:`step_uav`)."""

    name: str = "uav_double_integrator"
    velocity_level: bool = False
    exact_when_held: bool = False
    _state = UAVState

    def step(self, state: UAVState, u: Vec, d: Vec, h: float) -> UAVState:
        return step_uav(state, u, d, h)

    def velocity(self, state: UAVState) -> Vec:
        return state.p

    def point(self, state: UAVState, d: Vec, limits: Any) -> Point:
        return uav_point(state.q, state.p, d, limits.accel)


@dataclass(frozen=True)
class USV3DOF:
    """``usv_3dof``: the ε-model of a surface vessel (:func:`step_usv`); ``eps`` is ε1..ε7.
    Its input is (τ_u, τ_r)."""

    eps: tuple[float, ...]
    name: str = "usv_3dof"
    velocity_level: bool = False
    exact_when_held: bool = False

    def start(self, q: Vec, heading: float) -> USVState:
        return USVState(q[0], q[1], heading, 0.0, 0.0, 0.0)

    def at_rest(self, state: USVState, q: Vec, heading: float | None) -> USVState:
        return USVState(q[0], q[1], state.psi if heading is None else heading, 0.0, 0.0, 0.0)

    def step(self, state: USVState, u: Vec, d: Vec, h: float) -> USVState:
        return step_usv(state, u[0], u[1], self.eps, d, h)

    def velocity(self, state: USVState) -> Vec:
        return state.world_velocity()

    def heading(self, state: USVState) -> float:
        return state.psi

    def finite(self, state: USVState) -> bool:
        return math.isfinite(state.x + state.y + state.psi + state.u + state.v + state.r)

    def point(self, state: USVState, d: Vec, limits: Any) -> Point:
        return usv_point(state.x, state.y, state.psi, state.u, state.v, state.r, self.eps, d,
                         limits.tau_u, limits.tau_r, limits.speed)
