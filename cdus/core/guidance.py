"""Where should a vehicle go, and how fast should its ω run? The upper level: DGVF guidance
(`control_law_USV`, `control_law_UAV`, docs/control.md §2).

    a_i   = s f_i'(ω_i) - K_i Φ_i                       desired world-frame velocity
    u_i^ω = s + Φ_iᵀ K_i f_i'(ω_i) - c_i Σ_k a_ik (ω_i - ω_k - Δ_ik)
    ω̇_i  = u_i^ω,      Φ_i = q_i - f_i(ω_i)

with s = -1 the paper's (-1)^3. The USV and UAV laws are the same law in 2 and 3
dimensions; the USV's body-frame split of ``a`` lives in the regulators.

The ω dynamics are stiff (tangential rate k(1 + |f'|²), 151.5/s on the lake circle), so
ω is integrated here with internal substeps of a linearly implicit (Rosenbrock-Euler)
scheme, holding the measured position over the control period (docs/control.md §2, "integrate ω
inside the controller"). The scheme is A-stable along the path direction, so it is
stable at every control rate; its fixed point is the exact equilibrium of u^ω.

Saturation (``speed_limit`` v_max, docs/safety.md). A vehicle that cannot fly |a| flies
σa with σ = min(1, v_max/|a|). The guidance then scales its whole guiding vector, the
velocity part a and the ω part s + Φᵀ K f' (drift included) by the same σ, so ω
advances at the pace the vehicle actually makes. Scaling a vector field by a positive
function is a change of time along its integral curves: the curves towards the path, and
the path as the limit set, are unchanged. The consensus term is not scaled: it is the
coordination input, not the vehicle's vector field, and scaling it would slow the
coordination of every saturated vehicle by σ (measured in docs/safety.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

from cdus.core.paths import Path, Vec

# Largest internal ω substep. The substep only sets accuracy (the scheme is stable for
# any step); 5 ms keeps the mean ω̇ within 0.5% of the exact law on the lake circle.
MAX_SUBSTEP = 0.005


@dataclass(frozen=True)
class Consensus:
    """The coupling term's inputs over one control period, linear in time.

    Σ_k a_ik (ω_i - ω_k(t) - Δ_ik) = W ω_i - (B0 + B1 (t - t0)), with W = Σ a_ik and
    B(t) = Σ a_ik (ω_k(t) + Δ_ik). B1 is non-zero only when neighbours are extrapolated.
    """

    W: float = 0.0
    B0: float = 0.0
    B1: float = 0.0

    @staticmethod
    def from_terms(terms: Sequence[tuple[float, float, float, float]]) -> "Consensus":
        """``terms``: (a_ik, ω_k at the period start, ω̇_k used for extrapolation, Δ_ik)."""
        W = B0 = B1 = 0.0
        for a, wk, rk, d in terms:
            W += a
            B0 += a * (wk + d)
            B1 += a * rk
        return Consensus(W, B0, B1)


def path_error(path: Path, q: Vec, w: float) -> Vec:
    """Φ = q - f(ω) (`err_phi_USV`, `err_phi_UAV`)."""
    f, _, _ = path.eval(w)
    return tuple(a - b for a, b in zip(q, f))


def speed_scale(a: Vec, speed_limit: float) -> float:
    """σ = min(1, v_max / |a|): the factor that brings the velocity reference within the limit."""
    if speed_limit == math.inf:
        return 1.0
    n = math.sqrt(sum(x * x for x in a))
    return 1.0 if n <= speed_limit else speed_limit / n


def desired_velocity(path: Path, q: Vec, w: float, k: Vec, speed_limit: float = math.inf) -> Vec:
    """a = s f'(ω) - K Φ: the velocity reference (`control_law_UAV`'s p^r), times σ."""
    f, f1, _ = path.eval(w)
    s = path.direction
    a = tuple(s * d - kk * (qq - ff) for d, kk, qq, ff in zip(f1, k, q, f))
    sigma = speed_scale(a, speed_limit)
    return a if sigma == 1.0 else tuple(sigma * x for x in a)


def desired_velocity_rate(path: Path, q: Vec, qdot: Vec, w: float, wdot: float, k: Vec) -> Vec:
    """ȧ = s f''(ω) ω̇ - K (q̇ - f'(ω) ω̇), in closed form (no finite differences)."""
    _, f1, f2 = path.eval(w)
    s = path.direction
    return tuple(s * dd * wdot - kk * (v - d * wdot) for d, dd, kk, v in zip(f1, f2, k, qdot))


def omega_law(path: Path, q: Vec, w: float, k: Vec, c: float, coupling: float,
              speed_limit: float = math.inf) -> float:
    """u^ω at one instant, given ``coupling`` = Σ a_ik (ω_i - ω_k - Δ_ik).

    With ``speed_limit``: σ (s + Φᵀ K f') - c · coupling, σ = min(1, v_max/|a|).
    """
    f, f1, _ = path.eval(w)
    s = path.direction
    sigma = 1.0
    if speed_limit != math.inf:
        sigma = speed_scale(tuple(s * d - kk * (qq - ff) for d, kk, qq, ff in zip(f1, k, q, f)), speed_limit)
    return sigma * (s + sum(kk * (qq - ff) * d for kk, qq, ff, d in zip(k, q, f, f1))) - c * coupling


def integrate_omega(path: Path, q: Vec, w: float, k: Vec, c: float, cons: Consensus,
                    period: float, speed_limit: float = math.inf) -> float:
    """ω after one control period of length ``period``, with q held.

    Linearly implicit Euler on ω̇ = g(ω): ω += h g / (1 - h min(g', 0)), where
    g' = Σ_j k_j (Φ_j f''_j - f'_j²) - c W in closed form. Where g' > 0 the direction
    is genuinely unstable (the far side of a curved path) and the step is explicit.

    With ``speed_limit``, σ = min(1, v_max/|a(q, ω)|) is evaluated at every substep
    (a changes with ω even with q held) and multiplies the path-following part of g and
    of g' (σ is frozen within a substep: it only lowers the stiffness, so the step stays
    stable); the consensus part is not scaled. The default (no limit) is the paper's law.
    """
    n = max(1, math.ceil(period / MAX_SUBSTEP - 1e-9))
    h = period / n
    s = path.direction
    c_w = c * cons.W
    b0, b1 = cons.B0, cons.B1
    ev = path.eval
    planar = len(q) == 2
    if planar:
        qx, qy = q
        kx, ky = k
    else:
        qx, qy, qz = q
        kx, ky, kz = k
    limited = speed_limit != math.inf
    vmax2 = speed_limit * speed_limit
    for j in range(n):
        f, d, dd = ev(w)
        ex, ey = qx - f[0], qy - f[1]
        g = s + kx * ex * d[0] + ky * ey * d[1]
        dg = kx * (ex * dd[0] - d[0] * d[0]) + ky * (ey * dd[1] - d[1] * d[1])
        if not planar:
            ez = qz - f[2]
            g += kz * ez * d[2]
            dg += kz * (ez * dd[2] - d[2] * d[2])
        if limited:
            ax, ay = s * d[0] - kx * ex, s * d[1] - ky * ey
            a2 = ax * ax + ay * ay
            if not planar:
                az = s * d[2] - kz * ez
                a2 += az * az
            if a2 > vmax2:
                sigma = speed_limit / math.sqrt(a2)
                g *= sigma
                dg *= sigma
        dg -= c_w
        g -= c_w * w - c * (b0 + b1 * (j * h))
        if dg < 0.0:
            w += h * g / (1.0 - h * dg)
        else:
            w += h * g
    return w
