"""The CBF safety filter: minimal, safe, decentralised, and never stuck."""

import math
import random

import numpy as np
import pytest

from cdus.core.safety import Contact, SafetyParams, barrier, safety_filter

R = 2.0
P = SafetyParams(radius=R, gamma=1.0)


def _kkt_optimal(u_ref, u, q, contacts, params):
    """u is the QP's optimum: feasible, and u - u_ref = Σ λ_k ∇_k with λ ≥ 0 on the active rows."""
    rows = []
    for c in contacts:
        qk, w = (c.q, c.share) if isinstance(c, Contact) else (c, 0.5)
        g = tuple(2.0 * (a - b) for a, b in zip(q, qk))
        rhs = -w * params.gamma * barrier(q, qk, params.radius)
        margin = sum(x * y for x, y in zip(g, u)) - rhs
        assert margin >= -1e-7 * max(1.0, abs(rhs)), (g, rhs, u)
        if margin <= 1e-7 * max(1.0, abs(rhs)):
            rows.append(g)
    diff = np.subtract(u, u_ref)
    if not rows:
        return np.allclose(diff, 0.0, atol=1e-9)
    A = np.array(rows).T
    lam, *_ = np.linalg.lstsq(A, diff, rcond=None)
    return np.allclose(A @ lam, diff, atol=1e-7) and (lam >= -1e-9).all()


def _simulate(positions, goals, params, steps, dt=0.02, speed=1.0, ids=None):
    """Every vehicle flies at ``speed`` towards its goal through its own filter; returns the
    trajectory and the smallest distance between any two vehicles at every step."""
    q = [tuple(p) for p in positions]
    ids = ids or [f"v{i}" for i in range(len(q))]
    traj, mins = [list(q)], []
    for _ in range(steps):
        new = []
        for i, qi in enumerate(q):
            g = tuple(b - a for a, b in zip(qi, goals[i]))
            n = math.sqrt(sum(x * x for x in g))
            u_ref = tuple(speed * x / n for x in g) if n > speed * dt else tuple(x / dt for x in g)
            contacts = [Contact(q[k], ids[k]) for k in range(len(q)) if k != i]
            u = u_ref if params is None else safety_filter(u_ref, qi, contacts, params, me=ids[i])[0]
            assert all(math.isfinite(x) for x in u)
            new.append(tuple(a + dt * b for a, b in zip(qi, u)))
        q = new
        traj.append(list(q))
        mins.append(min(math.dist(q[i], q[k]) for i in range(len(q)) for k in range(i + 1, len(q))))
    return traj, mins


# --------------------------------------------------------------------------- the QP


def test_a_safe_reference_passes_unchanged():
    u, info = safety_filter((1.0, 0.5), (0.0, 0.0), [(10.0, 0.0), (0.0, -9.0)], P)
    assert u == (1.0, 0.5)
    assert not info.intervened and info.method == "pass" and info.active == () and info.satisfied
    assert info.min_h == pytest.approx(81.0 - 4.0)
    u, info = safety_filter((1.0, 0.5), (0.0, 0.0), [], P)
    assert u == (1.0, 0.5) and not info.intervened and info.min_h == math.inf


def test_one_constraint_closed_form():
    """Heading at 1 m/s for a vehicle 3 m ahead (h = 5): its half allows closing at
    γ h / (4 |d|) = 5/12 m/s; the lateral component is kept."""
    u, info = safety_filter((1.0, 0.3), (0.0, 0.0), [(3.0, 0.0)], P)
    assert u == pytest.approx((5.0 / 12.0, 0.3))
    assert info.intervened and info.method == "projection" and info.active == (0,) and info.satisfied


@pytest.mark.parametrize("dim", [2, 3])
def test_random_problems_are_solved_to_optimality(dim):
    """Feasible problems (every contact outside R): u satisfies every half constraint and
    the KKT conditions of min |u - u_ref|², whichever path (pass, projection, QP) found it."""
    rng = random.Random(11 + dim)
    methods = set()
    for _ in range(400):
        q = tuple(rng.uniform(-1, 1) for _ in range(dim))
        contacts, m = [], rng.randint(1, 8)
        while len(contacts) < m:
            qk = tuple(x + rng.uniform(-6, 6) for x in q)
            if math.dist(q, qk) > R * 1.01:
                contacts.append(Contact(qk, share=rng.choice([0.5, 1.0])))
        u_ref = tuple(rng.uniform(-3, 3) for _ in range(dim))
        params = SafetyParams(radius=R, gamma=rng.uniform(0.3, 3), sidestep=0.0)
        u, info = safety_filter(u_ref, q, contacts, params)
        assert info.satisfied and info.slack == 0.0
        assert _kkt_optimal(u_ref, u, q, contacts, params)
        assert info.intervened == (math.dist(u, u_ref) > params.tolerance)
        methods.add(info.method)
    assert methods == {"pass", "projection", "qp"}


def test_the_two_halves_add_up_to_the_pair_constraint():
    """Neither vehicle knows the other's velocity, yet ḣ = 2 (q_i - q_k)ᵀ (u_i - u_k) ≥ -γ h."""
    rng = random.Random(5)
    for _ in range(300):
        qi = (rng.uniform(-5, 5), rng.uniform(-5, 5))
        qk = (rng.uniform(-5, 5), rng.uniform(-5, 5))
        if math.dist(qi, qk) <= R:
            continue
        gamma = rng.uniform(0.2, 4.0)
        params = SafetyParams(radius=R, gamma=gamma)
        ui, _ = safety_filter((rng.uniform(-3, 3), rng.uniform(-3, 3)), qi, [qk], params)
        uk, _ = safety_filter((rng.uniform(-3, 3), rng.uniform(-3, 3)), qk, [qi], params)
        hdot = 2.0 * sum((a - b) * (c - d) for a, b, c, d in zip(qi, qk, ui, uk))
        assert hdot >= -gamma * barrier(qi, qk, R) - 1e-9


def test_a_one_sided_contact_is_taken_whole():
    half, _ = safety_filter((1.0, 0.0), (0.0, 0.0), [Contact((3.0, 0.0), share=0.5)], P)
    whole, _ = safety_filter((1.0, 0.0), (0.0, 0.0), [Contact((3.0, 0.0), share=1.0)], P)
    assert half[0] == pytest.approx(5.0 / 12.0)
    assert whole[0] == pytest.approx(5.0 / 6.0)  # 2 d u ≥ -γ h: the full closing speed


def test_closing_vehicles_never_get_closer_than_R():
    """Four vehicles crossing through the same point, each to the opposite side."""
    starts = [(-10.0, 0.0), (10.0, 0.0), (0.0, -10.0), (0.0, 10.0)]
    goals = [(10.0, 0.0), (-10.0, 0.0), (0.0, 10.0), (0.0, -10.0)]
    traj, mins = _simulate(starts, goals, P, steps=2500)
    assert min(mins) >= R * 0.995
    for q, g in zip(traj[-1], goals):
        assert math.dist(q, g) < 0.05  # everyone got through


def test_without_the_filter_they_would_collide():
    starts = [(-10.0, 0.0), (10.0, 0.0)]
    goals = [(10.0, 0.0), (-10.0, 0.0)]
    _, mins = _simulate(starts, goals, None, steps=1000)
    assert min(mins) < 0.05


# --------------------------------------------------------------------------- infeasible and stuck


def test_two_vehicles_inside_R_separate():
    """Starting 0.4 m apart with R = 2 and references pushing them together."""
    starts = [(0.0, 0.0), (0.4, 0.1)]
    traj, mins = _simulate(starts, [(5.0, 0.1), (-5.0, 0.0)], SafetyParams(radius=R, gamma=1.0, sidestep=0.0),
                           steps=500)
    assert mins[0] < R
    assert mins[-1] >= R * 0.99
    assert all(b >= a - 1e-9 for a, b in zip(mins, mins[1:]))  # inside R, h never decreases


def test_three_vehicles_squeezed_get_out():
    """The middle one is inside R of both others, which push towards it: its constraints
    contradict each other (the QP is infeasible). Nothing raises, nobody freezes, and
    all three end at least R apart."""
    starts = [(-1.0, 0.0), (0.0, 0.0), (1.0, 0.0)]
    contacts = [Contact(starts[0], "v0"), Contact(starts[2], "v2")]
    u, info = safety_filter((0.0, 0.0), starts[1], contacts, SafetyParams(radius=R, sidestep=0.0), me="v1")
    assert info.method == "relaxed" and info.slack > 0 and not info.satisfied
    assert all(math.isfinite(x) for x in u)
    goals = [(3.0, 0.0), (0.0, 0.0), (-3.0, 0.0)]  # the outer ones want to cross the middle
    traj, mins = _simulate(starts, goals, P, steps=1500)
    assert mins[-1] >= R * 0.99
    assert max(math.dist(a, b) for a, b in zip(traj[0], traj[50])) > 0.1  # moving at once


def test_the_squeezed_middle_escapes_sideways():
    """Symmetric squeeze with the reference along the line: the relaxed problem alone
    would hold the middle vehicle at u = 0; the sidestep moves it out across the line."""
    contacts = [(-1.0, 0.0), (1.0, 0.0)]
    u, info = safety_filter((1.0, 0.0), (0.0, 0.0), contacts, P)
    assert info.method == "relaxed" and info.sidestep > 0.9
    assert abs(u[1]) > 0.5 and abs(u[0]) < 1e-6
    frozen, _ = safety_filter((1.0, 0.0), (0.0, 0.0), contacts, SafetyParams(radius=R, sidestep=0.0))
    assert frozen == pytest.approx((0.0, 0.0), abs=1e-6)


@pytest.mark.parametrize("dim", [2, 3])
def test_coincident_vehicles_separate(dim):
    """Same position, same reference (two vehicles given the same start and path): the
    pair direction from the ids sends them opposite ways."""
    q0 = (1.0, 2.0, 3.0)[:dim]
    traj, mins = _simulate([q0, q0], [(20.0,) * dim, (20.0,) * dim], P, steps=400, ids=["usv1", "usv2"])
    assert mins[0] > 0.0
    assert mins[-1] >= R * 0.99
    u, info = safety_filter((0.5,) * dim, q0, [q0], P)  # no ids: along u_ref, no error
    assert all(math.isfinite(x) for x in u) and info.intervened


def test_head_on_vehicles_pass_each_other_to_starboard():
    """Exactly head on, the minimal filter stops both for good (u → 0 while the goals are
    still ahead). With the sidestep they turn right, pass port to port and arrive."""
    starts = [(-10.0, 0.0), (10.0, 0.0)]
    goals = [(10.0, 0.0), (-10.0, 0.0)]
    traj, _ = _simulate(starts, goals, SafetyParams(radius=R, sidestep=0.0), steps=3000)
    assert math.dist(traj[-1][0], goals[0]) > 5.0
    assert math.dist(traj[-1][0], traj[-100][0]) < 1e-3  # frozen
    traj, mins = _simulate(starts, goals, P, steps=3000)
    assert min(mins) >= R * 0.99
    assert all(math.dist(q, g) < 0.05 for q, g in zip(traj[-1], goals))
    assert min(q[0][1] for q in traj) < -0.5  # heading +x, starboard is -y
    assert max(q[1][1] for q in traj) > 0.5


def test_speed_bound():
    params = SafetyParams(radius=R, speed=1.5)
    u, info = safety_filter((3.0, 4.0), (0.0, 0.0), [], params)
    assert u == pytest.approx((0.9, 1.2)) and info.intervened and info.satisfied
    u, info = safety_filter((0.0, 0.0), (0.0, 0.0), [(0.2, 0.0)], params)  # deep inside R
    assert math.hypot(*u) == pytest.approx(1.5) and u[0] < 0 and not info.satisfied


def test_contacts_that_make_no_sense():
    u, info = safety_filter((1.0, 0.0), (0.0, 0.0), [(math.nan, 0.0), (3.0, 0.0)], P)
    assert u == pytest.approx((5.0 / 12.0, 0.0)) and info.active == (1,)
    with pytest.raises(ValueError, match="3 coordinates, the vehicle 2"):
        safety_filter((1.0, 0.0), (0.0, 0.0), [(3.0, 0.0, 1.0)], P)
    with pytest.raises(ValueError, match="finite"):
        safety_filter((math.inf, 0.0), (0.0, 0.0), [(3.0, 0.0)], P)


@pytest.mark.parametrize("field, value", [("radius", 0.0), ("gamma", -1.0), ("speed", math.nan),
                                          ("sidestep", 1.0), ("tolerance", 0)])
def test_bad_parameters_name_the_field(field, value):
    kwargs = {"radius": 2.0, field: value}
    with pytest.raises(ValueError, match=f"safety.{field}"):
        SafetyParams(**kwargs)


# --------------------------------------------------------------------------- hostile inputs (review of issue 16)


def test_huge_values_do_not_raise():
    """(a - b) ** 2 raised OverflowError on a huge u (γ = 1e300 inside R, or a huge u_ref); a radius
    whose square underflows divided by zero at a coincident contact."""
    cs = [Contact((1.0, 0.0), "b"), Contact((-1.0, 0.1), "c")]
    u, info = safety_filter((1.0, 0.0), (0.0, 0.0), cs, SafetyParams(2.0, gamma=1e300), "a")
    assert info.intervened and len(u) == 2
    u, info = safety_filter((1e300, 0.0), (0.0, 0.0), cs, SafetyParams(2.0), "a")
    assert len(u) == 2
    u, info = safety_filter((1.0, 0.0), (5.0, 5.0), [Contact((5.0, 5.0), "b")], SafetyParams(1e-300), "a")
    assert all(math.isfinite(x) for x in u)
    assert barrier((1e300, 0.0), (-1e300, 0.0), 1.0) == math.inf


from hypothesis import given, settings, strategies as st  # noqa: E402


@settings(max_examples=400, deadline=None)
@given(u=st.tuples(st.floats(-1e300, 1e300), st.floats(-1e300, 1e300)),
       q=st.tuples(st.floats(-1e300, 1e300), st.floats(-1e300, 1e300)),
       cs=st.lists(st.builds(Contact, st.tuples(st.floats(), st.floats()), st.sampled_from(("a", "b", None, "me")),
                             st.floats(1e-9, 1.0)), max_size=8),
       gamma=st.floats(1e-300, 1e300), radius=st.floats(1e-300, 1e300))
def test_hostile_contacts_and_parameters_never_raise(u, q, cs, gamma, radius):
    out, info = safety_filter(u, q, cs, SafetyParams(radius, gamma), "me")
    assert len(out) == 2 and info.method in ("pass", "projection", "qp", "relaxed")


def test_the_qp_on_rows_of_1e33_returns_instead_of_freezing():
    """Found by the Hypothesis test above in a full-suite run: two equal rows needing 1.8e33 m/s
    and a reference of 1e300 m/s kept quadprog's compiled loop going for good (no timeout can
    stop it); the QP is now solved scaled to O(1). Run in a child process so that a
    regression fails here instead of hanging the suite."""
    import subprocess
    import sys

    code = ("from cdus.core.safety import _solve\n"
            "n = (-2.881622306653057e-15, -1.0)\n"
            "u, how, _ = _solve((1e300, 0.0), [n, n], [1.7770838288765542e33] * 2, 1e-6)\n"
            "assert how == 'qp' and u[0] == 1e300 and u[1] < -2.88e285, u  # n.u >= 1.8e33 within rounding\n"
            "print('ok')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == "ok", out.stderr
