"""Which gains can the discrete controller take at its rate? Bounds on k, c and the regulator gains.

Pure functions, no I/O: the scenario's validation ([gains], a vehicle's gains and
regulator_gains) and the run-time gains command (cdus.commands.gains.Gains.for_vehicle, the ground
station) ask the same question. docs/config.md, "[gains]", states the bounds for users.

**Path gain k, ideal plant.** The ideal plant holds the velocity reference
a = s f'(ω) - K Φ over the control period T, so across the path the error moves as
Φ⊥ ← (1 - k_j T) Φ⊥ (ω absorbs the along-path part, the drift s f' moves f(ω) with q). It
contracts only when |1 - k_j T| < 1, i.e. **k_j T < 2**. Measured on lake_circle at
50 Hz (T = 20 ms): k = 99 keeps |Φ| at 0.21 m, k = 101 diverges to 3.8e9 m in 20 s; at
10 Hz k = 19 runs and k = 21 diverges.

**Path gain k, dynamic plants** (usv_3dof, uav_double_integrator). Their regulators
re-evaluate a at every physics step h = 1/physics with ω extrapolated, so the same
argument holds at h: **k_j h < 2**. Measured on lake_circle_dynamic (physics 200 Hz):
k = 396 runs, k = 404 diverges (DivergedError at 1.4 s).

**Regulator gains** (b; b_u, b_r, k_psi; b1, b2, b3): each is the rate of a
first-order error loop stepped at h (exact or Heun steps with the input held), which
contracts when |1 - b h| < 1 (Heun: |1 - bh + (bh)²/2| < 1): **b h < 2**.

**Coordination gain c.** A vehicle integrates its own ω implicitly (docs/control.md §2), so
with its neighbours' values held (policy hold or timeout) the consensus is stable for any
c: the step moves ω_i a fraction of the way to its neighbours' weighted mean. With
``extrapolate`` the neighbours' values move along their last rates; on a bipartite graph
(any even ring, any pair) the disagreement mode of the pure consensus then has the
iteration matrix [[a, b], [a - 1, b]] (a = 2e - 1, b = -(1 - β), e = exp(-cWT),
β = (1 - e)/(cWT)), stable by Jury's test only when **c W T < 1**, W = Σ_k a_ik the
vehicle's weight sum. The link policy can change at run time (``cdus gs link``), so this
bound holds for every policy. Measured on lake_circle (W = 2, 50 Hz: bound c < 25) with
extrapolate: c = 50 still settles (the path term damps the mode), c = 100 diverges
(ω spread 5e37 rad in 20 s); the bound is the proof's, with that margin.
"""

from __future__ import annotations

import math
from typing import Iterable, Sequence

from cdus.wire.bounds import finite as _number

#: Plants whose regulator re-evaluates the guidance at every physics step.
DYNAMIC_PLANTS = ("usv_3dof", "uav_double_integrator")
#: k_j · T < K_LIMIT (T: the period the guidance is held over); b · h < REGULATOR_LIMIT.
K_LIMIT = 2.0
REGULATOR_LIMIT = 2.0
#: c · W · T < C_LIMIT (W: the vehicle's weight sum, T: the control period).
C_LIMIT = 1.0


def k_bound(plant: str, control_hz: float, physics_hz: float | None = None) -> float:
    """The largest path gain k (exclusive) the plant can take: 2 × the rate the guidance
    is evaluated at (the control rate for the ideal plant, the physics rate otherwise)."""
    rate = physics_hz if plant in DYNAMIC_PLANTS and physics_hz is not None else control_hz
    return K_LIMIT * rate


def c_bound(control_hz: float, weight_sum: float) -> float:
    """The largest coordination gain c (exclusive): 1 / (W T) = control rate / W (inf without neighbours)."""
    return math.inf if weight_sum <= 0 else C_LIMIT * control_hz / weight_sum


def regulator_bound(physics_hz: float) -> float:
    """The largest regulator gain (exclusive): 2 × the physics rate."""
    return REGULATOR_LIMIT * physics_hz


def gains_problem_for_rate(k: float | Sequence[float] | None, c: float | None, control_hz: float, *,
                           plant: str = "ideal", physics_hz: float | None = None,
                           weight_sum: float = 0.0) -> str | None:
    """None if path gain ``k`` (a number or one per axis) and coordination gain ``c`` are
    within what the discrete controller takes at ``control_hz`` (and ``physics_hz`` for a
    dynamic plant) for a vehicle whose edge weights sum to ``weight_sum``; else one
    sentence naming the gain, the limit and why. ``None`` for k or c: not checked.
    Finiteness and positivity are the caller's type checks; non-finite values are refused
    here too."""
    problems = []
    if k is not None:
        ks = list(k) if isinstance(k, (list, tuple)) else [k]
        bound = k_bound(plant, control_hz, physics_hz)
        worst = max((x for x in ks if _number(x)), default=None)
        if any(not _number(x) for x in ks):
            problems.append("k must be finite")
        elif worst is not None and worst >= bound:
            where = ("the physics rate" if plant in DYNAMIC_PLANTS and physics_hz is not None
                     else "the control rate")
            rate = physics_hz if where == "the physics rate" else control_hz
            problems.append(f"k = {worst:g} is too large for {where} of {rate:g} Hz: the path error contracts "
                            f"only when k < 2 × {rate:g} = {bound:g} (k·T < 2, T = 1/{rate:g} s); lower k or "
                            f"raise the rate")
    if c is not None:
        if not _number(c):
            problems.append("c must be finite")
        else:
            bound = c_bound(control_hz, weight_sum)
            if c >= bound:
                problems.append(f"c = {c:g} is too large for the control rate of {control_hz:g} Hz with edge "
                                f"weights summing to {weight_sum:g}: the consensus is stable under every "
                                f"stale-neighbour policy only when c < rate / Σa_ik = {bound:g} (c·Σa_ik·T < 1); "
                                f"lower c or raise rates.control")
    return "; ".join(problems) or None


def regulator_gains_problem(gains: Iterable[tuple[str, float]], physics_hz: float) -> str | None:
    """None if every regulator gain is below 2 × the physics rate, else a sentence naming the first that is not."""
    bound = regulator_bound(physics_hz)
    for name, value in gains:
        if not _number(value):
            return f"{name} must be finite"
        if value >= bound:
            return (f"{name} = {value:g} is too large for the physics rate of {physics_hz:g} Hz: the regulator's "
                    f"error loop contracts only when {name} < 2 × {physics_hz:g} = {bound:g}; lower it or raise "
                    f"rates.physics")
    return None
