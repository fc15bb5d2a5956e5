"""How does a plant track the guidance? The lower level: its regulators (Problem 1, docs/control.md §3).

Each regulator is a pure function of the plant state and the guidance reference: the
path, the vehicle's ω and ω̇ (held from the last control instant and extrapolated
linearly), and the gains K. It evaluates a = s f'(ω) - K Φ and its time derivative in
closed form, so the tracking errors vanish exponentially, as Remark 2 needs.

Each is also an object (:class:`Regulator`: :class:`PD`, :class:`Heading`, :class:`Paper`)
built once with the vehicle for its plant (cdus.core.models names them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

from cdus.core.guidance import desired_velocity, desired_velocity_rate
from cdus.core.observer import compensate
from cdus.core.paths import Path, Vec
from cdus.core.plants import UAVState, USVState


@dataclass(frozen=True)
class Limits:
    """Optional actuator and speed limits; ``inf`` means none."""

    speed: float = math.inf  # |velocity reference|, m/s
    accel: float = math.inf  # |τ| of a UAV, m/s²
    tau_u: float = math.inf  # |surge input| of a USV
    tau_r: float = math.inf  # |yaw input| of a USV
    yaw_rate: float = math.inf  # |r reference| of a USV, rad/s


NO_LIMITS = Limits()


def _compensate(a: Vec, d_hat: Vec | None, shift: Vec | None = None) -> Vec:
    """a - d̂ + shift: the estimated disturbance cancelled, the safety filter's correction added."""
    if d_hat is not None:
        a = compensate(a, d_hat)
    if shift is not None:
        a = tuple(x + y for x, y in zip(a, shift))
    return a


def _ground(v: Vec, d_hat: Vec | None) -> Vec:
    """q̇ = v + d: the velocity over ground, as well as the estimate d̂ knows it."""
    return v if d_hat is None else tuple(x + y for x, y in zip(v, d_hat))


def clip_norm(v: Vec, bound: float) -> Vec:
    if bound == math.inf:
        return v
    n = math.sqrt(sum(x * x for x in v))
    if n <= bound:
        return v
    return tuple(x * bound / n for x in v)


def clip(x: float, bound: float) -> float:
    return x if -bound <= x <= bound else math.copysign(bound, x)


def wrap_angle(a: float) -> float:
    """a mapped to [-π, π)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


# --------------------------------------------------------------------------- UAV


@dataclass(frozen=True)
class UAVGains:
    b: float = 3.0  # velocity-error rate b_4 of `regulated_law_UAV`


def uav_pd(state: UAVState, path: Path, w: float, wdot: float, k: Vec, gains: UAVGains,
           limits: Limits = NO_LIMITS, d_hat: Vec | None = None, shift: Vec | None = None) -> Vec:
    """`regulated_law_UAV`: τ = -b (p - p^r) + ṗ^r, ṗ^r = s f''(ω) ω̇ - K (p - f'(ω) ω̇).

    With the speed limit, p^r is clipped (and its feed-forward dropped while clipped).
    With an estimated disturbance ``d_hat`` (cdus.core.observer), p^r = a - d̂, so that
    q̇ = p + d flies a, and ȧ is taken along q̇ = p + d̂. ``shift``: the safety filter's
    correction u - u_ref (cdus.core.safety), held over the control period, added to p^r.
    """
    pr = _compensate(desired_velocity(path, state.q, w, k), d_hat, shift)
    prdot = desired_velocity_rate(path, state.q, _ground(state.p, d_hat), w, wdot, k)
    clipped = clip_norm(pr, limits.speed)
    if clipped is not pr:
        pr, prdot = clipped, tuple(0.0 for _ in pr)
    tau = tuple(-gains.b * (p - r) + rd for p, r, rd in zip(state.p, pr, prdot))
    return clip_norm(tau, limits.accel)


# --------------------------------------------------------------------------- USV, heading mode


@dataclass(frozen=True)
class HeadingGains:
    b_u: float = 1.0  # surge-speed error rate
    b_r: float = 5.0  # yaw-rate error rate
    k_psi: float = 1.5  # heading error rate


def usv_heading(state: USVState, path: Path, w: float, wdot: float, k: Vec, eps: tuple[float, ...],
                gains: HeadingGains, limits: Limits = NO_LIMITS,
                d_hat: Vec | None = None, shift: Vec | None = None) -> tuple[float, float]:
    """Heading-mode USV regulator (docs/control.md §3, the recommended default).

    Tracks the heading ψ_d = atan2(a_y, a_x) and the surge speed u_d = |a| cos(ψ - ψ_d)
    (|a| projected on the heading, not below 0); sway is left to damping and the GVF's
    -KΦ term corrects the crab angle. ψ̇_d and u̇_d come from ȧ in closed form:
        r_ref = ψ̇_d - k_ψ (ψ - ψ_d),          τ_r = (-ε4 r - b_r (r - r_ref)) / ε5
        τ_u = (u̇_d - ε1 u - ε2 v r - b_u (u - u_d)) / ε3
    With an estimated current ``d_hat``, the hull is steered to fly a - d̂ through the water
    (ȧ taken along the velocity over ground, R(ψ)(u, v) + d̂). ``shift``: as in :func:`uav_pd`.
    """
    e1, e2, e3, e4, e5, _, _ = eps
    q = (state.x, state.y)
    a = _compensate(desired_velocity(path, q, w, k), d_hat, shift)
    adot = desired_velocity_rate(path, q, _ground(state.world_velocity(), d_hat), w, wdot, k)
    a = clip_norm(a, limits.speed)
    ax, ay = a
    n2 = ax * ax + ay * ay
    if n2 < 1e-12:
        return (clip((-e1 * state.u - e2 * state.v * state.r - gains.b_u * state.u) / e3, limits.tau_u),
                clip((-e4 * state.r - gains.b_r * state.r) / e5, limits.tau_r))
    n = math.sqrt(n2)
    psi_d = math.atan2(ay, ax)
    psi_d_dot = (ax * adot[1] - ay * adot[0]) / n2
    err = wrap_angle(state.psi - psi_d)
    r_ref = clip(psi_d_dot - gains.k_psi * err, limits.yaw_rate)
    tau_r = (-e4 * state.r - gains.b_r * (state.r - r_ref)) / e5
    ce = math.cos(err)
    if ce > 0.0:
        u_d = n * ce
        u_d_dot = (ax * adot[0] + ay * adot[1]) / n * ce - n * math.sin(err) * (state.r - psi_d_dot)
    else:
        u_d, u_d_dot = 0.0, 0.0
    tau_u = (u_d_dot - e1 * state.u - e2 * state.v * state.r - gains.b_u * (state.u - u_d)) / e3
    return clip(tau_u, limits.tau_u), clip(tau_r, limits.tau_r)


# --------------------------------------------------------------------------- USV, the paper's


@dataclass(frozen=True)
class PaperGains:
    b1: float = 1.0  # surge
    b2: float = 5.0  # yaw rate
    b3: float = 1.0  # sway


# |ε7 u + u^r| below this is treated as this (sign kept): the law is singular there.
PAPER_SINGULAR_GUARD = 0.05


def usv_paper(state: USVState, path: Path, w: float, wdot: float, k: Vec, eps: tuple[float, ...],
              gains: PaperGains, r_ref_prev: float | None, h: float,
              limits: Limits = NO_LIMITS, d_hat: Vec | None = None,
              shift: Vec | None = None) -> tuple[float, float, float]:
    """`regulated_law_USV` / `regulated_law_USV2` as corrected in docs/control.md §3.

    Body-frame references u^r = a_x cos ψ + a_y sin ψ, v^r = -a_x sin ψ + a_y cos ψ.
    Corrections to the paper: the surge law is τ_u = (u̇^r - ε1 u - ε2 v r - b1 ũ)/ε3
    (the printed one is singular at u^r = 0 and not exponential); r̃ = r - r^r; and
    sway is steered through the yaw rate, with v̇^r = ḃ - r u^r, giving
        r^r = (-ε6 v + ḃ - b3 ṽ) / (ε7 u + u^r),  ḃ = -ȧ_x sin ψ + ȧ_y cos ψ.
    It is singular where ε7 u + u^r = 0 and needs 1 + ε7 > 0 on the path; from many
    starts it ends up sailing stern-first. ṙ^r is a backward difference over the
    physics step (``r_ref_prev``, None on the first step). Returns (τ_u, τ_r, r^r).
    ``d_hat``, ``shift``: as in :func:`usv_heading`.
    """
    e1, e2, e3, e4, e5, e6, e7 = eps
    q = (state.x, state.y)
    a = clip_norm(_compensate(desired_velocity(path, q, w, k), d_hat, shift), limits.speed)
    adot = desired_velocity_rate(path, q, _ground(state.world_velocity(), d_hat), w, wdot, k)
    c, s = math.cos(state.psi), math.sin(state.psi)
    ur = a[0] * c + a[1] * s
    vr = -a[0] * s + a[1] * c
    bdot = -adot[0] * s + adot[1] * c
    ur_dot = adot[0] * c + adot[1] * s + state.r * vr
    tau_u = (ur_dot - e1 * state.u - e2 * state.v * state.r - gains.b1 * (state.u - ur)) / e3
    den = e7 * state.u + ur
    if abs(den) < PAPER_SINGULAR_GUARD:
        den = math.copysign(PAPER_SINGULAR_GUARD, den if den != 0.0 else 1.0)
    r_ref = clip((-e6 * state.v + bdot - gains.b3 * (state.v - vr)) / den, limits.yaw_rate)
    r_ref_dot = 0.0 if r_ref_prev is None else (r_ref - r_ref_prev) / h
    tau_r = (-e4 * state.r - gains.b2 * (state.r - r_ref) + r_ref_dot) / e5
    return clip(tau_u, limits.tau_u), clip(tau_r, limits.tau_r), r_ref


# --------------------------------------------------------------------------- the regulators as objects


class Regulator(Protocol):
    """A regulator as :class:`cdus.core.vehicle.Vehicle` calls it at every physics step (built
    once with the vehicle, for its plant, by cdus.core.models): the plant's input that tracks
    the guidance at ``state``, the path and ω (``w``, ``wdot``), the gains ``k``, the limits,
    the estimated disturbance ``d_hat`` and the safety filter's ``shift``, over a step of ``h``
    s. A regulator may keep state between steps (the paper's keeps r^r)."""

    name: str

    def command(self, state: Any, path: Path, w: float, wdot: float, k: Vec, limits: Limits,
                d_hat: Vec | None, shift: Vec | None, h: float) -> Vec:
        """The plant's input for the next ``h`` s."""


@dataclass(frozen=True)
class PD:
    """``pd`` of ``uav_double_integrator``: :func:`uav_pd`."""

    gains: UAVGains
    name: str = "pd"

    def command(self, state, path, w, wdot, k, limits, d_hat, shift, h) -> Vec:
        return uav_pd(state, path, w, wdot, k, self.gains, limits, d_hat, shift)


@dataclass(frozen=True)
class Heading:
    """``heading`` of ``usv_3dof``: :func:`usv_heading` (the default)."""

    eps: tuple[float, ...]
    gains: HeadingGains
    name: str = "heading"

    def command(self, state, path, w, wdot, k, limits, d_hat, shift, h) -> Vec:
        return usv_heading(state, path, w, wdot, k, self.eps, self.gains, limits, d_hat, shift)


@dataclass
class Paper:
    """``paper`` of ``usv_3dof``: :func:`usv_paper`, keeping r^r of the step before for ṙ^r
    (it is kept over a rejoin too, as it always was)."""

    eps: tuple[float, ...]
    gains: PaperGains
    name: str = "paper"
    r_ref_prev: float | None = None

    def command(self, state, path, w, wdot, k, limits, d_hat, shift, h) -> Vec:
        tu, tr, self.r_ref_prev = usv_paper(state, path, w, wdot, k, self.eps, self.gains, self.r_ref_prev, h,
                                            limits, d_hat, shift)
        return tu, tr
