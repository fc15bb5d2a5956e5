"""Plant models: exact UAV step, the USV ε-model, the named preset."""

import math

import pytest

from cdus.core.plants import (
    USV_PRESETS, PointState, UAVState, USVState, step_ideal, step_uav, step_usv, usv_derivative,
)

EPS = USV_PRESETS["cybership2"]


def test_step_ideal_moves_with_reference_plus_disturbance():
    st = step_ideal(PointState((1.0, 2.0), (0.0, 0.0)), (3.0, -1.0), (0.5, 0.5), 0.1)
    assert st.q == pytest.approx((1.35, 1.95))
    assert st.v == pytest.approx((3.5, -0.5))


def test_step_uav_is_exact_for_constant_input():
    q0, p0, tau, d = (1.0, -2.0, 20.0), (3.0, 0.5, -1.0), (0.4, -2.0, 9.81), (0.1, 0.0, -0.2)
    st = UAVState(q0, p0)
    h, n = 0.01, 137  # many small steps == one closed-form jump
    for _ in range(n):
        st = step_uav(st, tau, d, h)
    t = h * n
    want_q = tuple(q + t * (p + dd) + 0.5 * t * t * a for q, p, dd, a in zip(q0, p0, d, tau))
    want_p = tuple(p + t * a for p, a in zip(p0, tau))
    assert st.q == pytest.approx(want_q, abs=1e-10)
    assert st.p == pytest.approx(want_p, abs=1e-12)
    one = step_uav(UAVState(q0, p0), tau, d, t)
    assert one.q == pytest.approx(want_q, abs=1e-12)


def test_step_usv_surge_decays_as_exp_eps1_t():
    h = 0.005
    st = USVState(0.0, 0.0, 0.3, 2.0, 0.0, 0.0)
    for _ in range(int(round(1.0 / h))):
        st = step_usv(st, 0.0, 0.0, EPS, (0.0, 0.0), h)
    assert st.u == pytest.approx(2.0 * math.exp(EPS[0] * 1.0), rel=1e-3)
    assert st.v == 0.0 and st.r == 0.0 and st.psi == 0.3


def test_step_usv_straight_motion_along_heading():
    """Thrust balancing drag keeps u constant; the boat moves along ψ, no sway, no turn."""
    psi, u = 2.1, 1.5
    tau_u = -EPS[0] * u / EPS[2]
    st = USVState(1.0, -1.0, psi, u, 0.0, 0.0)
    h, t = 0.01, 4.0
    for _ in range(int(round(t / h))):
        st = step_usv(st, tau_u, 0.0, EPS, (0.0, 0.0), h)
    assert st.u == pytest.approx(u, rel=1e-12)
    assert st.x == pytest.approx(1.0 + u * t * math.cos(psi), abs=1e-9)
    assert st.y == pytest.approx(-1.0 + u * t * math.sin(psi), abs=1e-9)
    assert st.psi == psi and st.v == 0.0 and st.r == 0.0


def test_step_usv_disturbance_is_a_world_frame_drift():
    st = USVState(0.0, 0.0, 0.7, 0.0, 0.0, 0.0)
    for _ in range(100):
        st = step_usv(st, 0.0, 0.0, EPS, (0.3, -0.2), 0.01)
    assert (st.x, st.y) == pytest.approx((0.3, -0.2), abs=1e-12)
    assert st.u == 0.0


def test_step_usv_yaw_rate_response():
    """ṙ = ε4 r + ε5 τ_r: a constant τ_r settles r at -ε5 τ_r / ε4."""
    st = USVState(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    h = 0.01
    for _ in range(int(round(60.0 / h))):
        st = step_usv(st, 0.0, 0.2, EPS, (0.0, 0.0), h)
    assert st.r == pytest.approx(-EPS[4] * 0.2 / EPS[3], rel=1e-4)


def test_usv_derivative_equations():
    s = USVState(1.0, 2.0, 0.4, 1.5, -0.3, 0.2)
    e1, e2, e3, e4, e5, e6, e7 = EPS
    d = usv_derivative(s, 2.0, -1.0, EPS, (0.1, 0.2))
    c, sn = math.cos(0.4), math.sin(0.4)
    assert d == pytest.approx((
        1.5 * c + 0.3 * sn + 0.1,
        1.5 * sn - 0.3 * c + 0.2,
        0.2,
        e1 * 1.5 + e2 * -0.3 * 0.2 + e3 * 2.0,
        e6 * -0.3 + e7 * 1.5 * 0.2,
        e4 * 0.2 + e5 * -1.0,
    ))


def test_world_velocity_rotates_body_velocity():
    s = USVState(0.0, 0.0, math.pi / 2, 2.0, 1.0, 0.0)
    assert s.world_velocity() == pytest.approx((-1.0, 2.0))
    assert s.q == (0.0, 0.0)


def test_cybership2_preset_matches_the_formula():
    m11, m22, m33 = 25.8, 33.8, 2.76
    d11, d22, d33 = 12.0, 17.0, 0.5
    formula = (-d11 / m11, m22 / m11, 1 / m11, -d33 / m33, 1 / m33, -d22 / m22, -m11 / m22)
    preset = USV_PRESETS["cybership2"]
    assert len(preset) == 7
    for name, p, f in zip(("e1", "e2", "e3", "e4", "e5", "e6", "e7"), preset, formula):
        assert abs(p - f) < 5e-4, (name, p, f)  # equal to 3 decimals
    assert 1.0 + preset[6] > 0.0  # the paper's law needs 1 + ε7 > 0 on the path


def test_no_preset_claims_to_be_huster():
    assert not any("huster" in name.lower() for name in USV_PRESETS)
