"""What is the velocity disturbance pushing a vehicle? An extended-state observer (ESO) estimates
it (docs/safety.md).

Every plant here moves its position as q̇ = v + d, where v is what the model knows (the
ideal plant's command a, the UAV's velocity state p, the USV's hull velocity turned to
the world frame R(ψ)(u, v)) and d the unknown additive world-frame disturbance (water
current, wind; cdus.core.disturbance). Extending the state with d (ḋ ≈ 0) gives, per
axis, the second-order observer

    q̂̇ = v + d̂ + l1 (q - q̂),     d̂̇ = l2 (q - q̂),

here in discrete form, one update per step h from the measured position q and the mean
known velocity over the step just ended:

    q̂⁻ = q̂ + h (v + d̂),   e = q - q̂⁻,   q̂ = q̂⁻ + L1 e,   d̂ = d̂ + L2 e,
    L1 = 1 - p²,  L2 = (1 - p)² / h,  p = exp(-ω_o h),

which puts both error eigenvalues at p, the exact image of a double pole at -ω_o (the
bandwidth): a constant d is learnt with error ∝ (1 + ω_o t) e^{-ω_o t}, at any step h
(the gains follow h). The estimation error does not depend on how d̂ is used, so
compensating with it (the regulator flies a - d̂) cannot destabilise the observer.

Tuning: ω_o well above the guidance's own rate (k, about 1.5/s) so d̂ is there before
the path error builds up, and well below the measurement rate; gusts slower than
1/ω_o are followed, faster ones are averaged out. The default 2 rad/s learns a
constant wind to 2% in about 3 s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cdus.core.paths import Vec
from cdus.core.plants import PointState, UAVState, USVState

DEFAULT_BANDWIDTH = 2.0  # rad/s


@dataclass(frozen=True)
class ESO:
    """The observer's state: estimated position q̂ and disturbance d̂, and its bandwidth ω_o.

    Immutable: :meth:`update` returns the next state.
    """

    q_hat: Vec
    d_hat: Vec
    bandwidth: float = DEFAULT_BANDWIDTH

    @staticmethod
    def start(q: Vec, bandwidth: float = DEFAULT_BANDWIDTH) -> "ESO":
        """An observer at the measured position ``q``, knowing no disturbance yet."""
        if not (bandwidth > 0 and math.isfinite(bandwidth)):
            raise ValueError(f"observer.bandwidth: must be a finite number > 0 rad/s, got {bandwidth!r}")
        return ESO(tuple(float(x) for x in q), (0.0,) * len(q), float(bandwidth))

    def update(self, q: Vec, v: Vec, h: float) -> "ESO":
        """The state after a step of ``h`` s: ``q`` measured now, ``v`` the mean known velocity
        over the step (see :func:`known_velocity`)."""
        p = math.exp(-self.bandwidth * h)
        l1 = 1.0 - p * p
        l2 = (1.0 - p) ** 2 / h
        qh, dh = [], []
        for qm, qe, de, ve in zip(q, self.q_hat, self.d_hat, v):
            pred = qe + h * (ve + de)
            e = qm - pred
            qh.append(pred + l1 * e)
            dh.append(de + l2 * e)
        return ESO(tuple(qh), tuple(dh), self.bandwidth)


def known_velocity(before: PointState | UAVState | USVState, after: PointState | UAVState | USVState,
                   command: Vec | None = None) -> Vec:
    """The mean velocity a plant's model knows over the step from ``before`` to ``after``.

    - ideal plant: the velocity it was commanded (``command``; its state's v includes d);
    - UAV double integrator: (p_before + p_after)/2, exact for τ held over the step;
    - USV 3-DOF: the mean of R(ψ)(u, v) at both ends (Heun's step, to O(h²)).
    """
    if isinstance(before, USVState):
        a, b = before.world_velocity(), after.world_velocity()
        return tuple(0.5 * (x + y) for x, y in zip(a, b))
    if isinstance(before, UAVState):
        return tuple(0.5 * (x + y) for x, y in zip(before.p, after.p))
    if command is None:
        raise ValueError("observer: the ideal plant's known velocity is its command; pass command=a")
    return tuple(command)


def compensate(a: Vec, d_hat: Vec) -> Vec:
    """The velocity reference that cancels the estimated disturbance: a - d̂."""
    return tuple(x - y for x, y in zip(a, d_hat))
