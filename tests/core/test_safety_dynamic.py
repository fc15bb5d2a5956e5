"""The safety filter on the vehicles' dynamics (cdus.core.safety.dynamic_filter): forward
invariance of the pairwise barrier on a grid of relative states and headings for each plant
model with its preset limits, simulated with the plants' own step functions; starts that
cannot be made safe handled without an exception or a freeze; random states (Hypothesis):
no exception, inputs within their bounds."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cdus.core.limits import default_limits
from cdus.core.plants import USV_PRESETS, UAVState, USVState, step_uav, step_usv
from cdus.core.regulators import wrap_angle
from cdus.core.safety import (
    PASS, Point, SafetyParams, Track, USV_BRAKING, UAV_BRAKING_SHARE, dynamic_filter, pair_demand, uav_point,
    usv_point,
)

R = 2.0
P = SafetyParams(radius=R, gamma=1.0)
EPS = USV_PRESETS["cybership2"]
USV_LIM = default_limits("usv_3dof")
UAV_LIM = default_limits("uav_double_integrator")
H = 0.005  # physics step (s): 200 Hz as in the scenarios
TOL = 0.01  # m below R the tests accept (the discretisation of the physics step)


# --------------------------------------------------------------------------- harness


def _uav_me(s: UAVState) -> Point:
    return uav_point(s.q, s.p, (0.0,) * len(s.q), UAV_LIM.accel)


def _usv_me(s: USVState) -> Point:
    return usv_point(s.x, s.y, s.psi, s.u, s.v, s.r, EPS, (0.0, 0.0), USV_LIM.tau_u, USV_LIM.tau_r, USV_LIM.speed)


def _uav_nominal(s: UAVState, target) -> tuple[float, ...]:
    """Full acceleration at the other vehicle: the worst a reference can ask."""
    d = [b - a for a, b in zip(s.q, target)]
    n = math.sqrt(sum(x * x for x in d)) or 1.0
    return tuple(UAV_LIM.accel * x / n for x in d)


def _usv_nominal(s: USVState, target) -> tuple[float, float]:
    """Full ahead and steer at the other boat, at the yaw rate limit."""
    want = math.atan2(target[1] - s.y, target[0] - s.x)
    r_ref = max(-USV_LIM.yaw_rate, min(USV_LIM.yaw_rate, -1.5 * wrap_angle(s.psi - want)))
    tau_r = (-EPS[3] * s.r - 5.0 * (s.r - r_ref)) / EPS[4]
    return USV_LIM.tau_u, max(-USV_LIM.tau_r, min(USV_LIM.tau_r, tau_r))


def _run_pair(kind: str, a, b, seconds: float, cooperative: bool = True, static_b: bool = False,
              hold: int = 1) -> tuple[float, list]:
    """Two vehicles driving at each other through their filters (b static: an obstacle that
    does not react, a runs alone with share 1). ``hold``: the neighbour's state is sampled
    every ``hold`` physics steps and extrapolated at its velocity meanwhile, with the
    margins the vehicle uses (cdus.core.vehicle). Returns the smallest distance and the
    inputs applied."""
    step = {"uav": lambda s, tau: step_uav(s, tau, (0.0,) * len(s.q), H),
            "usv": lambda s, tau: step_usv(s, tau[0], tau[1], EPS, (0.0, 0.0), H)}[kind]
    me_of = _uav_me if kind == "uav" else _usv_me
    nominal = _uav_nominal if kind == "uav" else _usv_nominal
    share = 0.5 if cooperative and not static_b else 1.0
    states = [a, b]
    seen = [None, None]  # (p, v, age) sampled of the other
    dmin = math.dist(a.q, b.q)
    inputs = []
    for n in range(int(seconds / H)):
        points = [me_of(s) for s in states]
        if n % hold == 0:
            seen = [(points[1].p, points[1].v), (points[0].p, points[0].v)]
            age = 0.0
        else:
            age = (n % hold) * H
        taus = []
        for i in (0, 1):
            if i == 1 and static_b:
                taus.append(None)
                continue
            p_o, v_o = seen[i]
            acc = points[i].accel
            track = Track(tuple(x + y * age for x, y in zip(p_o, v_o)), v_o, share,
                          acc * 0.5 * age * age, acc * age, "b" if i == 0 else "a")
            tau, info = dynamic_filter(nominal(states[i], states[1 - i].q), points[i], [track], P,
                                       "a" if i == 0 else "b")
            assert all(math.isfinite(x) for x in tau)
            taus.append(tau)
            inputs.append((points[i], tau))
        states = [step(s, t) if t is not None else s for s, t in zip(states, taus)]
        dmin = min(dmin, math.dist(states[0].q, states[1].q))
    return dmin, inputs


def _within_limits(point: Point, tau) -> bool:
    """Within the actuators' limits: the UAV's |τ| ≤ accel, the USV's |τ_u| ≤ τ_u, |τ_r| ≤ τ_r."""
    if len(tau) == 2:
        return abs(tau[0]) <= USV_LIM.tau_u + 1e-9 and abs(tau[1]) <= USV_LIM.tau_r + 1e-9
    return math.sqrt(sum(t * t for t in tau)) <= UAV_LIM.accel * (1.0 + 1e-9)


def _boundary_distance(closing: float, alpha: float) -> float:
    """The distance at which a pair closing at ``closing`` is on the barrier's boundary h = 0."""
    return R + closing * closing / (2.0 * alpha)


# --------------------------------------------------------------------------- the barrier itself


def test_the_barrier_is_zero_exactly_where_braking_stops_the_pair_at_R():
    for closing in (0.5, 1.0, 3.0):
        d = _boundary_distance(closing, 1.0)
        _, _, h = pair_demand((d, 0.0), (-closing, 0.0), R, 1.0, 1.0, 0.5)
        assert h == pytest.approx(0.0, abs=1e-12)
    _, _, h = pair_demand((3.0, 0.0), (0.0, 0.0), R, 1.0, 1.0, 0.5)
    assert h > 0
    _, _, h = pair_demand((1.0, 0.0), (0.0, 0.0), R, 1.0, 1.0, 0.5)
    assert h < 0  # inside R


def test_a_demand_to_brake_is_taken_whole_a_permission_to_close_only_by_its_share():
    # on the boundary, closing: the barrier demands braking; each vehicle takes all of it
    d = _boundary_distance(2.0, 1.0)
    _, b_half, _ = pair_demand((d, 0.0), (-2.0, 0.0), R, 1.0, 1.0, 0.5)
    _, b_whole, _ = pair_demand((d, 0.0), (-2.0, 0.0), R, 1.0, 1.0, 1.0)
    assert b_half == pytest.approx(b_whole) and b_whole > 0
    # far apart and at rest: a permission; a vehicle uses only its share of it
    _, b_half, _ = pair_demand((20.0, 0.0), (0.0, 0.0), R, 1.0, 1.0, 0.5)
    _, b_whole, _ = pair_demand((20.0, 0.0), (0.0, 0.0), R, 1.0, 1.0, 1.0)
    assert b_whole < b_half < 0 and b_half == pytest.approx(0.5 * b_whole)


def test_a_safe_input_passes_bit_for_bit_and_no_tracks_is_a_pass():
    me = _uav_me(UAVState((0.0, 0.0, 10.0), (1.0, 0.0, 0.0)))
    tau = (0.3, -0.2, 0.1)
    assert dynamic_filter(tau, me, [], P) == (tau, PASS)
    out, info = dynamic_filter(tau, me, [Track((30.0, 0.0, 10.0), (0.0, 0.0, 0.0))], P)
    assert out is tau or out == tau
    assert not info.intervened and info.method == "pass"


def test_closing_too_fast_brakes_within_the_inputs_bounds():
    me = _uav_me(UAVState((0.0, 0.0, 10.0), (8.0, 0.0, 0.0)))
    tau, info = dynamic_filter((6.0, 0.0, 0.0), me, [Track((6.0, 0.0, 10.0), (-8.0, 0.0, 0.0))], P, "a")
    assert info.intervened and info.method == "relaxed"
    assert tau[0] == pytest.approx(-UAV_LIM.accel, rel=1e-6)  # the strongest braking there is
    assert _within_limits(me, tau)


def test_a_boat_brakes_with_its_surge_and_leaves_its_rudder_alone():
    s = USVState(0.0, 0.0, 0.0, 1.5, 0.0, 0.0)
    me = _usv_me(s)
    tau, info = dynamic_filter((USV_LIM.tau_u, 1.0), me, [Track((4.0, 0.0), (-1.5, 0.0))], P, "a")
    assert info.intervened
    assert tau[0] < 0 and tau[1] == 1.0
    assert _within_limits(me, tau)


# --------------------------------------------------------------------------- forward invariance


UAV_CLOSING = (1.0, 4.0, 8.0, 12.0)  # m/s, up to the preset's speed
UAV_ANGLES = (0.0, 30.0, 60.0, 90.0)  # degrees between b's velocity and the line towards a


@pytest.mark.parametrize("closing", UAV_CLOSING)
@pytest.mark.parametrize("angle", UAV_ANGLES)
@pytest.mark.parametrize("elevation", (0.0, 45.0))
def test_uav_pair_started_on_the_boundary_never_comes_within_R(closing, angle, elevation):
    """Both drones at full acceleration towards each other, started where the barrier is 0:
    a at rest-relative speed closing/2 towards b, b at closing/2 at ``angle`` off the line."""
    A = 2.0 * UAV_BRAKING_SHARE * UAV_LIM.accel
    e = math.radians(elevation)
    d0 = _boundary_distance(closing, A) + 0.05
    line = (math.cos(e), 0.0, math.sin(e))
    va = tuple(0.5 * closing * x for x in line)
    th = math.radians(angle)
    vb = (-0.5 * closing * math.cos(th) * math.cos(e), 0.5 * closing * math.sin(th),
          -0.5 * closing * math.cos(th) * math.sin(e))
    a = UAVState((0.0, 0.0, 10.0), va)
    b = UAVState(tuple(x * d0 + y for x, y in zip(line, (0.0, 0.0, 10.0))), vb)
    dmin, inputs = _run_pair("uav", a, b, 4.0)
    assert dmin >= R - TOL, dmin
    assert all(_within_limits(p, t) for p, t in inputs)


USV_SPEEDS = (0.5, 1.0, 1.5, 2.0)
USV_HEADINGS = (0.0, 45.0, 90.0, 135.0, 180.0)  # b's heading relative to the line b -> a


@pytest.mark.parametrize("speed", USV_SPEEDS)
@pytest.mark.parametrize("heading_b", USV_HEADINGS)
@pytest.mark.parametrize("heading_a", (0.0, 45.0, 90.0))
def test_usv_pair_started_on_the_boundary_never_comes_within_R(speed, heading_b, heading_a):
    """Two cybership2 boats at full ahead, each steering at the other at its yaw rate limit,
    started where the barrier is 0 for their closing speed. a sails at ``heading_a`` off
    the line a -> b, b at ``heading_b`` off the line b -> a."""
    A = 2.0 * USV_BRAKING
    ha, hb = math.radians(heading_a), math.radians(heading_b)
    closing = speed * (math.cos(ha) + math.cos(hb))
    d0 = _boundary_distance(max(closing, 0.0), A) + 0.05
    a = USVState(0.0, 0.0, ha, speed, 0.0, 0.0)
    b = USVState(d0, 0.0, math.pi - hb, speed, 0.0, 0.0)
    dmin, inputs = _run_pair("usv", a, b, 15.0)
    assert dmin >= R - TOL, dmin
    assert all(_within_limits(p, t) for p, t in inputs)


@pytest.mark.parametrize("kind,speed", [("uav", 4.0), ("uav", 10.0), ("usv", 1.0), ("usv", 2.0)])
def test_a_vehicle_alone_never_comes_within_R_of_an_obstacle_that_does_not_react(kind, speed):
    """A killed vehicle left where it died: the other takes the whole constraint (share 1)."""
    if kind == "uav":
        alpha = UAV_BRAKING_SHARE * UAV_LIM.accel
        d0 = _boundary_distance(speed, alpha) + 0.05
        a, b = UAVState((0.0, 0.0, 5.0), (speed, 0.0, 0.0)), UAVState((d0, 0.3, 5.0), (0.0, 0.0, 0.0))
    else:
        d0 = _boundary_distance(speed, USV_BRAKING) + 0.05
        a, b = USVState(0.0, 0.0, 0.0, speed, 0.0, 0.0), USVState(d0, 0.3, 1.0, 0.0, 0.0, 0.0)
    dmin, _ = _run_pair(kind, a, b, 15.0, static_b=True)
    assert dmin >= R - TOL, dmin


@pytest.mark.parametrize("kind", ["uav", "usv"])
def test_the_margins_cover_a_neighbour_seen_late(kind):
    """The neighbour sampled every 20 physics steps (10 Hz) and extrapolated in between, with
    the margins on position and velocity: still never within R."""
    if kind == "uav":
        A = 2.0 * UAV_BRAKING_SHARE * UAV_LIM.accel
        a = UAVState((0.0, 0.0, 10.0), (4.0, 0.0, 0.0))
        b = UAVState((_boundary_distance(8.0, A) + 1.0, 0.0, 10.0), (-4.0, 0.0, 0.0))
    else:
        A = 2.0 * USV_BRAKING
        a = USVState(0.0, 0.0, 0.0, 1.5, 0.0, 0.0)
        b = USVState(_boundary_distance(3.0, A) + 0.5, 0.0, math.pi, 1.5, 0.0, 0.0)
    dmin, _ = _run_pair(kind, a, b, 10.0, hold=20)
    assert dmin >= R - TOL, dmin


def test_without_the_filter_the_same_pairs_collide():
    """The grid's nominal inputs do bring the vehicles within R: the tests above test something."""
    a, b = USVState(0.0, 0.0, 0.0, 1.5, 0.0, 0.0), USVState(6.0, 0.0, math.pi, 1.5, 0.0, 0.0)
    dmin = math.inf
    for _ in range(int(6.0 / H)):
        ta, tb = _usv_nominal(a, b.q), _usv_nominal(b, a.q)
        a, b = step_usv(a, *ta, EPS, (0.0, 0.0), H), step_usv(b, *tb, EPS, (0.0, 0.0), H)
        dmin = min(dmin, math.dist(a.q, b.q))
    assert dmin < 0.5
    u, v = UAVState((0.0, 0.0, 10.0), (4.0, 0.0, 0.0)), UAVState((10.0, 0.0, 10.0), (-4.0, 0.0, 0.0))
    dmin = math.inf
    for _ in range(int(3.0 / H)):
        u, v = step_uav(u, _uav_nominal(u, v.q), (0.0,) * 3, H), step_uav(v, _uav_nominal(v, u.q), (0.0,) * 3, H)
        dmin = min(dmin, math.dist(u.q, v.q))
    assert dmin < 0.5


# --------------------------------------------------------------------------- infeasible starts


@pytest.mark.parametrize("kind", ["uav", "usv"])
@pytest.mark.parametrize("gap", [0.0, 0.5, 1.5])
def test_starts_inside_R_get_out_without_an_exception_or_a_freeze(kind, gap):
    """Inside R, closing, even on the same spot: the filter returns inputs within bounds at
    every step and the pair ends up at least R apart."""
    if kind == "uav":
        a, b = UAVState((0.0, 0.0, 10.0), (1.0, 0.0, 0.0)), UAVState((gap, 0.0, 10.0), (-1.0, 0.0, 0.0))
        seconds = 5.0
    else:
        a, b = USVState(0.0, 0.0, 0.0, 0.5, 0.0, 0.0), USVState(gap, 0.0, math.pi, 0.5, 0.0, 0.0)
        seconds = 20.0
    step = (lambda s, t: step_uav(s, t, (0.0,) * 3, H)) if kind == "uav" else \
        (lambda s, t: step_usv(s, t[0], t[1], EPS, (0.0, 0.0), H))
    me_of = _uav_me if kind == "uav" else _usv_me
    # the references keep pushing them together (towards where the other was at the start)
    goals = (b.q, a.q)
    states = [a, b]
    for _ in range(int(seconds / H)):
        pts = [me_of(s) for s in states]
        taus = []
        for i in (0, 1):
            o = pts[1 - i]
            ref = (_uav_nominal if kind == "uav" else _usv_nominal)(states[i], goals[i])
            tau, info = dynamic_filter(ref, pts[i], [Track(o.p, o.v, 0.5, id="ab"[1 - i])], P, "ab"[i])
            assert _within_limits(pts[i], tau) and all(math.isfinite(x) for x in tau)
            taus.append(tau)
        states = [step(s, t) for s, t in zip(states, taus)]
    assert math.dist(states[0].q, states[1].q) >= R - TOL


# --------------------------------------------------------------------------- random states


finite = st.floats(-50.0, 50.0, allow_nan=False)
speed = st.floats(-15.0, 15.0, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(q=st.tuples(finite, finite, finite), p=st.tuples(speed, speed, speed),
       tau=st.tuples(speed, speed, speed),
       others=st.lists(st.tuples(st.tuples(finite, finite, finite), st.tuples(speed, speed, speed),
                                 st.sampled_from((0.5, 1.0)), st.floats(0.0, 2.0), st.floats(0.0, 2.0)),
                       max_size=6))
def test_uav_random_states_never_raise_and_stay_within_the_ball(q, p, tau, others):
    me = _uav_me(UAVState(q, p))
    ref = tuple(x * min(1.0, UAV_LIM.accel / max(1e-9, math.sqrt(sum(y * y for y in tau)))) for x in tau)
    tracks = [Track(qq, vv, w, dp, dv, f"v{k}") for k, (qq, vv, w, dp, dv) in enumerate(others)]
    out, info = dynamic_filter(ref, me, tracks, P, "me")
    assert all(math.isfinite(x) for x in out)
    assert _within_limits(me, out)
    assert info.method in ("pass", "qp", "relaxed")


@settings(max_examples=300, deadline=None)
@given(x=finite, y=finite, psi=st.floats(-10.0, 10.0), u=st.floats(-3.0, 3.0), v=st.floats(-1.0, 1.0),
       r=st.floats(-2.0, 2.0), tu=st.floats(-36.9, 36.9), tr=st.floats(-3.01, 3.01),
       others=st.lists(st.tuples(st.tuples(finite, finite), st.tuples(st.floats(-3, 3), st.floats(-3, 3)),
                                 st.sampled_from((0.5, 1.0)), st.floats(0.0, 1.0), st.floats(0.0, 1.0)),
                       max_size=6))
def test_usv_random_states_never_raise_and_stay_within_the_box(x, y, psi, u, v, r, tu, tr, others):
    me = _usv_me(USVState(x, y, psi, u, v, r))
    tracks = [Track(qq, vv, w, dp, dv, f"v{k}") for k, (qq, vv, w, dp, dv) in enumerate(others)]
    out, info = dynamic_filter((tu, tr), me, tracks, P, "me")
    assert all(math.isfinite(z) for z in out)
    assert _within_limits(me, out)
    if info.method != "pass":  # what the filter chose also keeps the surge speed's approach to its limit
        assert me.lo[0] - 1e-9 <= out[0] <= me.hi[0] + 1e-9


def test_bad_input_names_the_problem():
    me = _uav_me(UAVState((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
    with pytest.raises(ValueError, match="inputs"):
        dynamic_filter((1.0, 0.0), me, [], P)
    with pytest.raises(ValueError, match="finite"):
        dynamic_filter((math.nan, 0.0, 0.0), me, [], P)
    with pytest.raises(ValueError, match="coordinates"):
        dynamic_filter((0.0, 0.0, 0.0), me, [Track((1.0, 1.0), (0.0, 0.0))], P)
    with pytest.raises(ValueError, match="share"):
        dynamic_filter((0.0, 0.0, 0.0), me, [Track((1.0, 1.0, 1.0), (0.0, 0.0, 0.0), 0.0)], P)


# --------------------------------------------------------------------------- in the vehicle


def _boat():
    from cdus.scenario.config import load_scenario
    from cdus.sim.build import build_vehicle

    sc = load_scenario("configs/crossing_dynamic.toml")
    return build_vehicle(sc.vehicle("usv_a1"), sc.rates, sc.seed, sc.safety)


def test_the_vehicle_estimates_a_contacts_velocity_from_its_two_newest_samples():
    from cdus.core.safety import Contact

    v = _boat()
    v.guard((Contact((5.0, 0.0), "x", 0.5),), 0)
    (_, first), = [v._tracks]
    assert first[0][1] is None  # first sighting: no velocity yet
    v.guard((Contact((5.0, 0.0), "x", 0.5),), 0)  # the same sample again: nothing new
    v.guard((Contact((4.5, 0.5), "x", 0.5),), 5)  # 5 ticks = 0.1 s later
    ts, tracks = v._tracks
    assert ts == pytest.approx(0.1)
    assert tracks[0][1] == pytest.approx((-5.0, 5.0)) and tracks[0][2] == pytest.approx(0.1)
    v.guard((), 10)  # out of range for a sample...
    v.guard((Contact((4.0, 1.0), "x", 0.5),), 50)  # ...and back 0.8 s later: too old to difference
    assert v._tracks[1][0][1] is None


def test_the_vehicle_filters_its_inputs_at_every_physics_step():
    """A boat at full speed towards a contact 3 m ahead: its surge input is cut at once."""
    from cdus.core.safety import Contact

    v = _boat()
    v.state = USVState(0.0, 0.0, 0.0, 2.0, 0.0, 0.0)
    ahead = (3.0, 0.0)
    v.guard((Contact(ahead, "x", 0.5),), 0)
    v.guard((Contact(ahead, "x", 0.5),), 5)
    before = v.interventions
    v.advance()
    assert v.interventions == before + 1
    assert v.state.u < 2.0 - 0.02  # braking at more than 1 m/s² over the 20 ms


def test_off_its_path_a_boat_tracks_the_shaped_reference_the_filter_chose():
    """Far from its path |a| = |s f' - KΦ| exceeds the speed limit. The regulators add the
    shaper's correction to the unclipped reference and clip after (a - d̂ + shift), so the
    correction is taken from the unclipped one and the boat tracks the filter's answer. It
    used to be taken from the clipped one: the boat tracked a reference still pointing into
    the contact, and one blocked by a dead boat on its path froze 2.16 m from it for good."""
    from dataclasses import replace

    from cdus.core.guidance import desired_velocity
    from cdus.core.regulators import clip_norm
    from cdus.core.safety import Contact, safety_filter
    from cdus.core.vehicle import SHAPER_MARGIN

    v = _boat()
    v.state = USVState(-6.0, 14.0, 0.0, 0.0, 0.0, 0.0)  # 4 m outside its circle (radius 10)
    raw = desired_velocity(v.path, v.q, v.omega, v.k)
    speed = v.limits.speed
    n = math.hypot(*raw)
    assert n > speed  # the reference is clipped here
    ahead = (Contact(tuple(x + 2.5 * y / n for x, y in zip(v.q, raw)), "x", 1.0),)
    v.guard(ahead, 0)
    assert v._shift is not None
    tracked = clip_norm(tuple(x + y for x, y in zip(raw, v._shift)), speed)
    shaper = replace(v.safety, radius=v.safety.radius * (1.0 + SHAPER_MARGIN))
    u, _ = safety_filter(clip_norm(raw, speed), v.q, ahead, shaper, v.id)
    assert tracked == pytest.approx(u, abs=1e-12)
    assert sum(x * y for x, y in zip(tracked, raw)) < 0.0  # away from the contact, not into it


@pytest.mark.parametrize("boat_speed", [0.0, 1.0, 2.0])
def test_a_drone_diving_at_a_boat_keeps_R_from_it_in_3d(boat_speed):
    """Across domains: the drone sees the boat as a point on the water (x, y, 0) moving at its
    (estimated) velocity, a contact that does not react (share 1), and takes all of it."""
    drone = UAVState((-6.0, 0.0, 6.0), (3.0, 0.0, -3.0))
    boat = (0.0, 0.0, 0.0)
    vb = (-boat_speed, 0.0, 0.0)
    dmin = math.inf
    for n in range(int(6.0 / H)):
        boat_now = tuple(b + v * n * H for b, v in zip(boat, vb))
        me = _uav_me(drone)
        tau, _ = dynamic_filter(_uav_nominal(drone, boat_now), me, [Track(boat_now, vb, 1.0, id="boat")], P, "uav")
        assert _within_limits(me, tau)
        drone = step_uav(drone, tau, (0.0, 0.0, 0.0), H)
        dmin = min(dmin, math.dist(drone.q, tuple(b + v * (n + 1) * H for b, v in zip(boat, vb))))
    assert dmin >= R - TOL, dmin


def test_an_ideal_vehicle_filters_against_where_its_contacts_are_now():
    """The velocity-level filter of an ideal plant sees each contact extrapolated from its
    sample to the present at the velocity estimated from the two newest samples."""
    from cdus.core.safety import Contact
    from cdus.scenario.config import load_scenario
    from cdus.sim.build import build_vehicle

    sc = load_scenario("configs/crossing.toml")
    v = build_vehicle(sc.vehicle("usv_a1"), sc.rates, sc.seed, sc.safety)
    q0 = v.q
    v.guard((Contact((q0[0] + 5.0, q0[1]), "x", 0.5),), 0)
    assert v.last_filter.min_h == pytest.approx(25.0 - R * R)
    v.tick, v.t = 7, 0.14  # sample 5 used 2 ticks late: 0.04 s old
    v.guard((Contact((q0[0] + 4.5, q0[1]), "x", 0.5),), 5)  # closing at 5 m/s
    assert v.last_filter.min_h == pytest.approx(4.3 ** 2 - R * R)


# --------------------------------------------------------------------------- hostile inputs (review of issue 16)

anyf = st.floats(allow_nan=True, allow_infinity=True)
huge = st.floats(-1e300, 1e300)


@pytest.mark.parametrize("track", [
    Track((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1.0, 0.0, 3e307, "a"),  # a margin of 3e307 m/s: NaN out
    Track((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1.0, math.inf, 0.0, "a"),
    Track((3.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.5, math.nan, 0.0, "a"),
])
def test_absurd_track_margins_give_finite_inputs(track):
    me = _uav_me(UAVState((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
    out, info = dynamic_filter((1.0, 0.0, 0.0), me, [track], P, "me")
    assert all(math.isfinite(x) for x in out) and _within_limits(me, out)
    boat = _usv_me(USVState(0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    out, info = dynamic_filter((1.0, 0.1), boat, [Track(track.p[:2], track.v[:2], 1.0, track.dp, track.dv)], P)
    assert all(math.isfinite(x) for x in out) and _within_limits(boat, out)


@settings(max_examples=400, deadline=None)
@given(q=st.tuples(huge, huge, huge), p=st.tuples(speed, speed, speed),
       tracks=st.lists(st.builds(Track, st.tuples(anyf, anyf, anyf), st.tuples(anyf, anyf, anyf),
                                 st.floats(1e-9, 1.0), anyf, anyf, st.sampled_from(("a", "b", None, "me"))),
                       max_size=8))
def test_uav_hostile_tracks_never_raise_and_give_finite_inputs(q, p, tracks):
    me = _uav_me(UAVState(q, p))
    out, info = dynamic_filter((1.0, 0.0, 0.0), me, tracks, P, "me")
    assert all(math.isfinite(x) for x in out) and _within_limits(me, out)


@settings(max_examples=400, deadline=None)
@given(x=huge, y=huge, psi=huge, u=st.floats(-1e3, 1e3),
       tracks=st.lists(st.builds(Track, st.tuples(anyf, anyf), st.tuples(anyf, anyf), st.floats(1e-9, 1.0), anyf,
                                 anyf), max_size=8))
def test_usv_hostile_tracks_never_raise_and_give_finite_inputs(x, y, psi, u, tracks):
    me = _usv_me(USVState(x, y, psi, u, 0.0, 0.0))
    out, info = dynamic_filter((1.0, 0.1), me, tracks, P, "me")
    assert all(math.isfinite(z) for z in out) and _within_limits(me, out)
