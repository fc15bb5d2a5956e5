"""What actuator and speed limits does a plant preset have by default? (docs/safety.md)

The numbers are derived from the models themselves (cdus.core.plants), not from a data
sheet: the presets are generic models, so their limits say what such a vehicle could do,
sized so that the built-in dynamic scenarios are reachable with margin.

``usv_3dof`` / ``cybership2`` (CyberShip II-like masses m11 = 25.8, m33 = 2.76 and damping
d11 = 12, d33 = 0.5, i.e. ε1 = -d11/m11, ε3 = 1/m11, ε4 = -d33/m33, ε5 = 1/m33):

- speed 2.0 m/s: the cap lake_circle_dynamic uses, twice its 1 m/s path speed.
- tau_u: holding 2.0 m/s against the surge damping needs d11 · 2.0 = 24 N; with 0.5 m/s²
  left to accelerate at that speed, τ_u = (-ε1 v + a)/ε3 = (0.465 · 2.0 + 0.5) · 25.8 ≈ 37.
- yaw_rate 0.5 rad/s (29°/s): a small boat's turn; 5x what the 1 m/s, r = 10 m circle needs.
- tau_r: holding 0.5 rad/s needs d33 · 0.5 = 0.25; with 1 rad/s² of yaw acceleration on
  top, τ_r = (-ε4 r + ṙ)/ε5 = (0.181 · 0.5 + 1.0) · 2.76 ≈ 3.0.

``uav_double_integrator`` (a multirotor's translational dynamics):

- speed 12 m/s: a small multirotor's cruise, above the 10 m/s the paper's lake circle asks.
- accel 6 m/s²: the horizontal acceleration of a multirotor tilted ~31° (g tan 31° ≈ 5.9),
  inside the usual 30-35° tilt limit.

``ideal``: no limits (the lower level is assumed perfect).
"""

from __future__ import annotations

from cdus.core.plants import USV_PRESETS
from cdus.core.regulators import NO_LIMITS, Limits

_USV_SPEED = 2.0  # m/s
_USV_SURGE_ACCEL = 0.5  # m/s² left at full speed
_USV_YAW_RATE = 0.5  # rad/s
_USV_YAW_ACCEL = 1.0  # rad/s² left at full yaw rate


def usv_limits(eps: tuple[float, ...], speed: float = _USV_SPEED, yaw_rate: float = _USV_YAW_RATE) -> Limits:
    """Limits of a 3-DOF ε-model sized as in the module docstring: τ_u holds ``speed`` with
    0.5 m/s² to spare, τ_r holds ``yaw_rate`` with 1 rad/s² to spare."""
    e1, _, e3, e4, e5, _, _ = eps
    return Limits(speed=speed,
                  tau_u=round((-e1 * speed + _USV_SURGE_ACCEL) / e3, 1),
                  yaw_rate=yaw_rate,
                  tau_r=round((-e4 * yaw_rate + _USV_YAW_ACCEL) / e5, 2))


PLANT_LIMITS = {
    ("uav_double_integrator", None): Limits(speed=12.0, accel=6.0),
    ("ideal", None): NO_LIMITS,
}


def default_limits(plant: str, preset: str | None = None) -> Limits:
    """The limits a plant (and, for ``usv_3dof``, its ε preset) has when a config gives none."""
    if plant == "usv_3dof":
        name = preset or "cybership2"
        if name not in USV_PRESETS:
            raise ValueError(f"limits: unknown usv_3dof preset {name!r}; choose one of {', '.join(USV_PRESETS)}")
        return usv_limits(USV_PRESETS[name])
    try:
        return PLANT_LIMITS[(plant, None)]
    except KeyError:
        plants = sorted({p for p, _ in PLANT_LIMITS} | {"usv_3dof"})
        raise ValueError(f"limits: unknown plant {plant!r}; choose one of {', '.join(plants)}") from None
