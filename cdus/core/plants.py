"""What moves: the vehicle models (docs/control.md §3), as pure step functions.

- ``ideal``: the lower level tracks perfectly (Problem 1 solved): q̇ = a, held over the
  control period.
- ``uav_double_integrator`` (`UAV_kinetic`): q̇ = p, ṗ = τ.
- ``usv_3dof`` (`USV_kinetic`, `USV_kinematic`):
      ẋ = u cos ψ - v sin ψ,  ẏ = u sin ψ + v cos ψ,  ψ̇ = r
      u̇ = ε1 u + ε2 v r + ε3 τ_u,   ṙ = ε4 r + ε5 τ_r,   v̇ = ε6 v + ε7 u r

``d`` everywhere is an additive world-frame velocity disturbance (current, wind).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cdus.core.paths import Vec

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
