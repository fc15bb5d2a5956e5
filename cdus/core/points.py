"""What does the dynamic safety filter see of a vehicle? Its position's second-order dynamics per plant.

p̈ = f + G τ with the inputs' bounds, the braking it counts on and the margin it keeps, for a
UAV (:func:`uav_point`) and a 3-DOF boat (:func:`usv_point`): what cdus.core.safety's
``dynamic_filter`` takes as ``me`` (docs/safety.md, "The filter on the vehicles' dynamics").
Moved out of cdus.core.safety, which re-exports them, when the obstacles' rows made it too long.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

Vec = tuple[float, ...]

# A USV keeps this much (m) beyond R: its sway and yaw, which τ_u does not act on, move the
# hull by up to a few cm while it brakes side-on (tests/core/test_safety_dynamic.py).
USV_MARGIN = 0.1
# The braking (m/s²) a vehicle counts on along the line of sight, by plant: a share of a
# UAV's acceleration bound; for a USV what its surge thrust leaves at full speed
# (docs/safety.md, "The numbers").
UAV_BRAKING_SHARE = 0.6
UAV_NOMINAL_ACCEL = 6.0  # m/s²: a UAV without an acceleration limit is taken as the preset's
USV_BRAKING = 0.3
USV_NOMINAL_ACCEL = 1.5  # m/s²: bound on a boat's acceleration (|ε3| τ_u of the preset)
# Rate (1/s) at which the USV filter lets the surge speed approach ±its limit.
USV_SPEED_RATE = 1.0
# While the filter acts on a boat, its yaw rate is held within ±this (rad/s), approached at
# USV_YAW_RATE_RATE (1/s): turning at speed makes sway (v̇ = ε6 v + ε7 u r), which the
# surge cannot stop, and in a crowd that sway pushed boats into each other.
USV_JAM_YAW_RATE = 0.1
USV_YAW_RATE_RATE = 5.0


@dataclass(frozen=True, slots=True)
class Point:
    """A vehicle as the dynamic filter sees itself: its position p, velocity v over ground,
    p̈ = f + G τ (``G`` by rows: p̈_j = f_j + Σ_m G[j][m] τ_m), the inputs' box
    lo ≤ τ ≤ hi and ball |τ| ≤ ``ball``, the braking ``alpha`` it counts on, ``accel`` a
    bound on |p̈| of such a vehicle (the margin its neighbours give its motion over a
    sample's age) and ``scale``, each input's full-scale value (the QP weighs (τ_m/scale_m)²)."""

    p: Vec
    v: Vec
    f: Vec
    G: tuple[Vec, ...]
    lo: Vec
    hi: Vec
    ball: float
    alpha: float
    accel: float
    scale: Vec
    margin: float = 0.0  # kept beyond R (m)
    yaw: tuple[float, float] | None = None  # a USV's τ_r interval while the filter acts (see usv_point)

def uav_point(q: Vec, p: Vec, d: Vec, accel: float) -> Point:
    """A UAV (q̇ = p + d, ṗ = τ, |τ| ≤ accel): p̈ = τ (d held constant)."""
    dim = len(q)
    a = accel if math.isfinite(accel) else UAV_NOMINAL_ACCEL
    eye = tuple(tuple(1.0 if i == j else 0.0 for j in range(dim)) for i in range(dim))
    inf = (math.inf,) * dim
    return Point(tuple(q), tuple(x + y for x, y in zip(p, d)), (0.0,) * dim, eye,
                 tuple(-x for x in inf), inf, accel, UAV_BRAKING_SHARE * a, a, (a,) * dim)


def usv_point(x: float, y: float, psi: float, u: float, v: float, r: float, eps: tuple[float, ...],
              d: Vec, tau_u: float, tau_r: float, speed: float) -> Point:
    """A 3-DOF boat's position: with ṗ = R(ψ)(u, v) + d (d held constant),

        p̈ = R(ψ) (ε1 u + ε2 v r - r v + ε3 τ_u,  ε6 v + ε7 u r + r u)

    Only τ_u acts at this order (along the heading); τ_r acts a derivative later, through r.
    The box is |τ_u| ≤ tau_u, narrowed so that the surge speed approaches ±``speed`` no faster
    than exponentially (u̇ ≤ USV_SPEED_RATE (speed - u)), and |τ_r| ≤ tau_r (untouched)."""
    e1, e2, e3, e4, e5, e6, e7 = eps
    c, s = math.cos(psi), math.sin(psi)
    vel = (c * u - s * v + d[0], s * u + c * v + d[1])
    fu, fv = e1 * u + e2 * v * r - r * v, e6 * v + e7 * u * r + r * u
    f = (c * fu - s * fv, s * fu + c * fv)
    G = ((c * e3, 0.0), (s * e3, 0.0))
    lo_u, hi_u = -tau_u, tau_u
    if math.isfinite(speed):
        drift = e1 * u + e2 * v * r
        lo_u, hi_u = _narrow(lo_u, hi_u, (-USV_SPEED_RATE * (speed + u) - drift) / e3,
                             (USV_SPEED_RATE * (speed - u) - drift) / e3)
    accel = min(USV_NOMINAL_ACCEL, e3 * tau_u) if math.isfinite(tau_u) else USV_NOMINAL_ACCEL
    scale = (tau_u if math.isfinite(tau_u) else 1.0 / e3, tau_r if math.isfinite(tau_r) else 1.0 / e5)
    yaw = _narrow(-tau_r, tau_r, (-USV_YAW_RATE_RATE * (USV_JAM_YAW_RATE + r) - e4 * r) / e5,
                  (USV_YAW_RATE_RATE * (USV_JAM_YAW_RATE - r) - e4 * r) / e5)
    return Point((x, y), vel, f, G, (lo_u, -tau_r), (hi_u, tau_r), math.inf, USV_BRAKING, accel, scale, USV_MARGIN,
                 yaw)


def _narrow(lo: float, hi: float, a: float, b: float) -> tuple[float, float]:
    """[lo, hi] ∩ [a, b]; if they do not meet, the end of [lo, hi] nearest [a, b]."""
    nlo, nhi = max(lo, a), min(hi, b)
    if nlo <= nhi:
        return nlo, nhi
    edge = hi if a > hi else lo
    return edge, edge
