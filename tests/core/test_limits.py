"""Default limits per plant preset, and that they are what the docstring derives."""

import math

import pytest

from cdus.core.limits import default_limits, usv_limits
from cdus.core.plants import USV_PRESETS, USVState, step_usv


def test_defaults():
    usv = default_limits("usv_3dof")
    assert usv == default_limits("usv_3dof", "cybership2")
    assert (usv.speed, usv.tau_u, usv.yaw_rate, usv.tau_r) == (2.0, 36.9, 0.5, 3.01)
    uav = default_limits("uav_double_integrator")
    assert (uav.speed, uav.accel) == (12.0, 6.0)
    assert default_limits("ideal").speed == math.inf


def test_the_usv_limits_reach_the_speed_and_yaw_rate_with_margin():
    """Full τ_u from rest reaches more than the 2 m/s limit; full τ_r more than 0.5 rad/s."""
    eps = USV_PRESETS["cybership2"]
    lim = usv_limits(eps)
    s = USVState(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    for _ in range(4000):  # 20 s, straight
        s = step_usv(s, lim.tau_u, 0.0, eps, (0.0, 0.0), 0.005)
    assert s.u > lim.speed * 1.05
    s = USVState(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    for _ in range(4000):
        s = step_usv(s, 0.0, lim.tau_r, eps, (0.0, 0.0), 0.005)
    assert s.r > lim.yaw_rate * 1.5


def test_unknown_names():
    with pytest.raises(ValueError, match="unknown usv_3dof preset 'huster'"):
        default_limits("usv_3dof", "huster")
    with pytest.raises(ValueError, match="unknown plant 'boat'"):
        default_limits("boat")
