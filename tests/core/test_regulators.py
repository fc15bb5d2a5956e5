"""Lower-level regulators: exponential UAV tracking, USV heading mode, the paper's USV law."""

import math
import random

import pytest

from cdus.core import regulators as reg
from cdus.core.guidance import Consensus, desired_velocity, integrate_omega
from cdus.core.paths import nearest_omega
from cdus.scenario.paths import make_path
from cdus.core.plants import USV_PRESETS, UAVState, USVState, step_uav, step_usv

EPS = USV_PRESETS["cybership2"]


# --------------------------------------------------------------------------- helpers


def test_wrap_angle_range_and_congruence():
    rng = random.Random(3)
    values = [rng.uniform(-1e3, 1e3) for _ in range(2000)] + [0.0, math.pi, -math.pi, 3 * math.pi]
    for a in values:
        w = reg.wrap_angle(a)
        assert -math.pi <= w < math.pi
        assert math.remainder(a - w, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
    assert reg.wrap_angle(math.pi) == -math.pi
    assert reg.wrap_angle(0.25) == 0.25


def test_clip_norm():
    v = (3.0, 4.0)
    assert reg.clip_norm(v, math.inf) is v
    assert reg.clip_norm(v, 5.0) is v
    assert reg.clip_norm(v, 6.0) == v
    c = reg.clip_norm(v, 2.5)
    assert c == pytest.approx((1.5, 2.0))
    c3 = reg.clip_norm((0.0, -10.0, 0.0), 1.0)
    assert c3 == pytest.approx((0.0, -1.0, 0.0))


def test_clip_scalar():
    assert reg.clip(0.5, 1.0) == 0.5
    assert reg.clip(-3.0, 1.0) == -1.0
    assert reg.clip(3.0, 1.0) == 1.0
    assert reg.clip(1e9, math.inf) == 1e9


# --------------------------------------------------------------------------- UAV


@pytest.mark.parametrize("spec", [
    {"family": "circle", "center": [0, 0, 20], "radius": 10, "speed": 2.0},
    {"family": "circle", "center": [-40, 50, 20], "radius": 10},  # the paper's 10 m/s circle
])
@pytest.mark.parametrize("b", [2.0, 3.0])
def test_uav_pd_velocity_error_decays_like_exp_minus_b_t(spec, b):
    """`regulated_law_UAV`: d/dt (p - p^r) = -b (p - p^r), with ω advancing at ω̇ = -1."""
    path = make_path(spec)
    k = (1.5, 1.5, 1.5)
    gains = reg.UAVGains(b=b)
    h = 0.005
    w0 = 0.5
    f, _, _ = path.eval(w0)
    st = UAVState((f[0] + 1.0, f[1] - 2.0, f[2] + 0.5), (4.0, -3.0, 1.0))

    def error(s, w):
        return math.dist(s.p, desired_velocity(path, s.q, w, k))

    e0 = error(st, w0)
    steps = int(round(1.0 / h))
    for i in range(steps):
        tau = reg.uav_pd(st, path, w0 - i * h, -1.0, k, gains)
        st = step_uav(st, tau, (0.0, 0.0, 0.0), h)
    e1 = error(st, w0 - steps * h)
    assert e1 / e0 == pytest.approx(math.exp(-b), rel=0.10)


def test_uav_pd_limits():
    path = make_path({"family": "circle", "center": [0, 0, 20], "radius": 10})
    k = (1.5, 1.5, 1.5)
    st = UAVState((30.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    tau = reg.uav_pd(st, path, 0.0, -1.0, k, reg.UAVGains(), reg.Limits(speed=3.0, accel=2.0))
    assert math.hypot(*tau) == pytest.approx(2.0)
    # with only the speed limit, τ = -b (p - p^r) with p^r clipped to 3 m/s, no feed-forward
    tau = reg.uav_pd(st, path, 0.0, -1.0, k, reg.UAVGains(b=3.0), reg.Limits(speed=3.0))
    assert math.hypot(*tau) == pytest.approx(3.0 * 3.0)


# --------------------------------------------------------------------------- USV, heading mode


def _run_usv_on_line(k, psi0, limits, regulator="heading", duration=60.0):
    """Line along -x at 1 m/s (s = -1), boat 5 m off it. 50 Hz control with ω integrated
    by integrate_omega (q held), ω̇ reported as the mean over the period; 200 Hz physics."""
    path = make_path({"family": "line", "origin": [0, 0], "heading": [1, 0], "speed": 1.0})
    st = USVState(0.0, 5.0, psi0, 0.0, 0.0, 0.0)
    w = nearest_omega(path, st.q, 0.0)
    wd = -1.0
    T, n = 0.02, 4
    h = T / n
    r_prev = None
    ws = []
    for i in range(int(round(duration / T))):
        if i:
            w_new = integrate_omega(path, st.q, w, k, 0.0, Consensus(), T)
            wd = (w_new - w) / T
            w = w_new
        ws.append(w)
        for j in range(n):
            wj = w + wd * j * h
            if regulator == "heading":
                tu, tr = reg.usv_heading(st, path, wj, wd, k, EPS, reg.HeadingGains(), limits)
            else:
                tu, tr, r_prev = reg.usv_paper(st, path, wj, wd, k, EPS, reg.PaperGains(), r_prev, h,
                                               limits)
            assert math.isfinite(tu) and math.isfinite(tr)
            st = step_usv(st, tu, tr, EPS, (0.0, 0.0), h)
    f, _, _ = path.eval(w)
    return st, math.dist(st.q, f), (ws[-1] - ws[-1 - int(round(10.0 / T))]) / 10.0


@pytest.mark.parametrize("k, limits", [
    ((1.5, 1.5), reg.Limits(speed=2.0)),  # the paper's gain, a 2 m/s cruise limit
    ((0.5, 0.5), reg.NO_LIMITS),
])
@pytest.mark.parametrize("psi0", [math.pi / 2, -math.pi / 2])  # pointing away from / toward the line
def test_usv_heading_converges_to_a_line(k, limits, psi0):
    st, phi, rate = _run_usv_on_line(k, psi0, limits)
    assert phi < 0.2
    assert rate == pytest.approx(-1.0, abs=0.01)
    assert abs(reg.wrap_angle(st.psi - math.pi)) < 0.01  # heading along the travel direction -x
    assert st.u == pytest.approx(1.0, abs=0.01)
    assert abs(st.y) < 0.01


@pytest.mark.parametrize("psi0, u_final", [(-math.pi / 2, 1.0), (math.pi / 2, -1.0)])
def test_usv_paper_on_a_line_tracks_but_may_sail_stern_first(psi0, u_final):
    """Where the paper's regulator fails (docs/control.md §3): from 5 m off the line it tracks the
    path either way, but from the start pointing away it ends sailing stern-first."""
    st, phi, rate = _run_usv_on_line((1.5, 1.5), psi0, reg.Limits(speed=2.0), regulator="paper")
    assert phi < 0.2
    assert rate == pytest.approx(-1.0, abs=0.01)
    assert st.u == pytest.approx(u_final, abs=0.01)


def test_usv_heading_steady_state_inputs():
    """On the line, on heading, at the reference speed: no yaw input, thrust balances drag."""
    path = make_path({"family": "line", "origin": [0, 0], "heading": [1, 0], "speed": 1.0})
    st = USVState(0.0, 0.0, math.pi, 1.0, 0.0, 0.0)
    tu, tr = reg.usv_heading(st, path, 0.0, -1.0, (1.5, 1.5), EPS, reg.HeadingGains())
    assert tr == pytest.approx(0.0, abs=1e-12)
    assert tu == pytest.approx(-EPS[0] * 1.0 / EPS[2], rel=1e-12)


def test_usv_heading_brakes_when_pointing_backwards():
    """Heading error beyond 90°: the surge reference is 0, so the thrust brakes."""
    path = make_path({"family": "line", "origin": [0, 0], "heading": [1, 0], "speed": 1.0})
    st = USVState(0.0, 0.0, 0.0, 1.0, 0.0, 0.0)  # travel is -x, the boat heads +x
    tu, tr = reg.usv_heading(st, path, 0.0, -1.0, (1.5, 1.5), EPS, reg.HeadingGains())
    assert tu < 0.0
    assert tr != 0.0


def test_usv_heading_limits_clip_the_inputs():
    path = make_path({"family": "line", "origin": [0, 0], "heading": [1, 0], "speed": 1.0})
    st = USVState(0.0, 5.0, math.pi / 2, 0.0, 0.0, 0.0)
    lim = reg.Limits(tau_u=3.0, tau_r=0.5)
    tu, tr = reg.usv_heading(st, path, 0.0, -1.0, (1.5, 1.5), EPS, reg.HeadingGains(), lim)
    assert abs(tu) <= 3.0 and abs(tr) <= 0.5


# --------------------------------------------------------------------------- USV, the paper's


def test_usv_paper_runs_from_a_benign_start():
    """On the path, heading along it, u = 1: 20 s without NaN, finite torques, still on the
    path and sailing bow-first (from other starts it ends stern-first: docs/control.md §3)."""
    path = make_path({"family": "circle", "center": [0, 0], "radius": 10, "speed": 1.0})
    k = (1.5, 1.5)
    w = 0.3
    f, f1, _ = path.eval(w)
    st = USVState(f[0], f[1], math.atan2(-f1[1], -f1[0]), 1.0, 0.0, 0.0)
    T, n = 0.02, 4
    h = T / n
    wd, r_prev = -1.0, None
    for i in range(int(round(20.0 / T))):
        if i:
            w_new = integrate_omega(path, st.q, w, k, 0.0, Consensus(), T)
            wd = (w_new - w) / T
            w = w_new
        for j in range(n):
            tu, tr, r_prev = reg.usv_paper(st, path, w + wd * j * h, wd, k, EPS, reg.PaperGains(),
                                           r_prev, h)
            assert math.isfinite(tu) and math.isfinite(tr) and math.isfinite(r_prev)
            st = step_usv(st, tu, tr, EPS, (0.0, 0.0), h)
    assert all(math.isfinite(x) for x in (st.x, st.y, st.psi, st.u, st.v, st.r))
    f, _, _ = path.eval(w)
    assert math.dist(st.q, f) < 0.1
    assert st.u > 0.5


def _singular_state(v):
    """Line heading -x at β = -ε7 = 0.763: on it, heading +x (the travel direction), u = 1,
    so u^r = 0.763 and ε7 u + u^r = 0 exactly."""
    beta = -EPS[6]
    path = make_path({"family": "line", "origin": [0, 0], "heading": [-1, 0], "beta": beta})
    return path, USVState(0.0, 0.0, 0.0, 1.0, v, 0.0)


def test_usv_paper_singular_guard_is_applied():
    path, st = _singular_state(v=0.1)
    k = (1.0, 1.0)
    tu, tr, r_ref = reg.usv_paper(st, path, 0.0, -1.0, k, EPS, reg.PaperGains(b3=1.0), None, 0.005)
    e6 = EPS[5]
    # a = s f' = (β, 0), so v^r = 0 and ḃ = ȧ_y = -k (q̇_y - f'_y ω̇) = -k v
    bdot = -k[1] * st.v
    numerator = -e6 * st.v + bdot - 1.0 * (st.v - 0.0)
    ur = desired_velocity(path, st.q, 0.0, k)[0]  # heading 0: u^r = a_x
    assert EPS[6] * st.u + ur == 0.0
    assert r_ref == pytest.approx(numerator / reg.PAPER_SINGULAR_GUARD, rel=1e-12)
    assert math.isfinite(tu) and math.isfinite(tr)


@pytest.mark.parametrize("den", [0.01, -0.01, 0.2])
def test_usv_paper_guard_keeps_the_sign_and_only_acts_near_zero(den):
    """Shift u so that ε7 u + u^r = den; the guard replaces |den| < 0.05 by ±0.05."""
    path, st0 = _singular_state(v=0.1)
    u = 1.0 + den / EPS[6]  # ε7 u + 0.763 = den  <=> u = (den - 0.763)/ε7 = 1 + den/ε7
    st = USVState(0.0, 0.0, 0.0, u, 0.1, 0.0)
    k = (1.0, 1.0)
    _, _, r_ref = reg.usv_paper(st, path, 0.0, -1.0, k, EPS, reg.PaperGains(b3=1.0), None, 0.005)
    # q̇ = (u, v), f' ω̇ = (β, 0): ḃ = -k v, v^r = 0
    numerator = -EPS[5] * 0.1 - k[1] * 0.1 - 1.0 * 0.1
    used = den if abs(den) >= reg.PAPER_SINGULAR_GUARD else math.copysign(reg.PAPER_SINGULAR_GUARD, den)
    assert r_ref == pytest.approx(numerator / used, rel=1e-9)


# --------------------------------------------------------------------------- disturbance compensation


def test_uav_pd_with_an_estimated_wind_flies_a_minus_d_hat():
    """p^r = a - d̂, and ȧ is taken along the velocity over ground q̇ = p + d̂."""
    from cdus.core.guidance import desired_velocity_rate
    path = make_path({"family": "circle", "center": [0, 0, 20], "radius": 10, "beta": 0.1})
    k = (1.5, 1.5, 1.5)
    st = UAVState((9.0, 1.0, 19.5), (0.2, 0.8, 0.0))
    d_hat = (0.5, -0.3, 0.1)
    gains = reg.UAVGains(b=3.0)
    a = desired_velocity(path, st.q, 0.2, k)
    adot = desired_velocity_rate(path, st.q, tuple(p + d for p, d in zip(st.p, d_hat)), 0.2, -1.0, k)
    want = tuple(-3.0 * (p - (x - d)) + r for p, x, d, r in zip(st.p, a, d_hat, adot))
    assert reg.uav_pd(st, path, 0.2, -1.0, k, gains, d_hat=d_hat) == pytest.approx(want)
    assert reg.uav_pd(st, path, 0.2, -1.0, k, gains, d_hat=(0.0, 0.0, 0.0)) == \
        pytest.approx(reg.uav_pd(st, path, 0.2, -1.0, k, gains))


def test_usv_heading_with_an_estimated_current_steers_for_a_minus_d_hat():
    """A boat on the path heading along it: with a current from ahead, the heading stays
    and the surge reference grows by the current (b_u 0.3 in τ_u ε3); its feed-forward
    u̇_d grows by k 0.3 too, because ȧ is taken along the velocity over ground, which the
    current slows by 0.3 m/s (ȧ = -f''ω̇ - K(q̇ - f'ω̇) changes by -K δq̇)."""
    path = make_path({"family": "circle", "center": [0, 0], "radius": 10, "beta": 0.1})
    k = (1.5, 1.5)
    w = 0.0
    f, f1, _ = path.eval(w)
    psi = math.atan2(-f1[1], -f1[0])  # along s f' = -f'
    st = USVState(f[0], f[1], psi, 1.0, 0.0, 0.0)
    ahead = (math.cos(psi), math.sin(psi))
    d_hat = (-0.3 * ahead[0], -0.3 * ahead[1])  # 0.3 m/s against the boat
    tu0, _ = reg.usv_heading(st, path, w, -1.0, k, EPS, reg.HeadingGains())
    tu1, _ = reg.usv_heading(st, path, w, -1.0, k, EPS, reg.HeadingGains(), d_hat=d_hat)
    assert tu1 - tu0 == pytest.approx((reg.HeadingGains().b_u + k[0]) * 0.3 / EPS[2], rel=1e-6)
