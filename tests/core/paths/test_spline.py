"""The spline family: through its waypoints, f' and f'' against finite differences, a tangent that
never vanishes, ω at the speed asked, and every refused waypoint list naming the waypoint."""

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cdus.core.paths import PathError, Spline, for_dimension, nearest_omega, spline
from cdus.core.paths.spline import MAX_SPEED, MIN_SPEED
from cdus.scenario.paths import make_path

SQUARE = ((0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0))


def _norm(v):
    return math.sqrt(sum(x * x for x in v))


def _central(fun, w, h):
    plus, minus = fun(w + h), fun(w - h)
    return tuple((a - b) / (2 * h) for a, b in zip(plus, minus))


def _check_curve(s: Spline, beta: float) -> None:
    """Through its waypoints, f' and f'' agree with central differences, |f₀'| within the checks'."""
    for t, p in zip(s.knots, s.waypoints):
        f = s.eval(t / beta)[0]
        assert all(abs(a - b) <= 1e-9 * (1 + abs(b)) for a, b in zip(f, p)), (t, f, p)
    h = 1e-5 / abs(beta)
    lo = s.knots[0] / beta - (5.0 if not s.closed else 0.0)
    hi = s.knots[-1] / beta + (5.0 if not s.closed else 0.0)
    for k in range(41):
        w = lo + (hi - lo) * (k + 0.37) / 41
        f, f1, f2 = s.eval(w)
        d1 = _central(lambda x: s.eval(x)[0], w, h)
        d2 = _central(lambda x: s.eval(x)[1], w, h)
        scale1, scale2 = abs(beta) * (1 + _norm(f1)), beta * beta * (1 + _norm(f2))
        assert all(abs(a - b) <= 1e-5 * scale1 for a, b in zip(f1, d1)), (w, f1, d1)
        assert all(abs(a - b) <= 1e-3 * scale2 for a, b in zip(f2, d2)), (w, f2, d2)
        assert MIN_SPEED * abs(beta) - 1e-12 <= _norm(f1) <= MAX_SPEED * abs(beta) + 1e-12


coord = st.floats(-50.0, 50.0, allow_nan=False)


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(coord, coord), min_size=2, max_size=9), st.booleans(),
       st.sampled_from([1.0, -0.7, 2.5]))
def test_any_waypoint_list_is_a_smooth_curve_through_them_or_a_refusal_naming_a_waypoint(pts, closed, beta):
    try:
        s = spline(tuple(pts), closed, beta)
    except PathError as e:
        assert e.field == "waypoints"
        assert "waypoint" in e.message and ("needs at least" in e.message or "[" in e.message), e.message
        return
    _check_curve(s, beta)


@st.composite
def loops(draw):
    """A loop round a centre, unevenly spaced and jittered: mostly accepted (2-D or 3-D)."""
    n = draw(st.integers(3, 12))
    cuts = sorted(draw(st.lists(st.floats(0.0, 1.0), min_size=n, max_size=n, unique=True)))
    r = draw(st.floats(5.0, 100.0))
    dim = draw(st.sampled_from([2, 3]))
    pts = []
    for c in cuts:
        a = 2 * math.pi * c
        rr = r * draw(st.floats(0.8, 1.2))
        p = (rr * math.cos(a), rr * math.sin(a)) + ((draw(st.floats(0.0, 10.0)),) if dim == 3 else ())
        pts.append(p)
    return tuple(pts)


@settings(max_examples=150, deadline=None)
@given(loops(), st.sampled_from([1.0, -1.3]))
def test_a_loop_through_waypoints_passes_through_them_with_derivatives_matching_finite_differences(pts, beta):
    try:
        s = spline(pts, True, beta)
    except PathError as e:  # very uneven spacing: refused by name
        assert e.field == "waypoints" and "waypoint" in e.message
        return
    _check_curve(s, beta)
    assert s.period == pytest.approx(s.knots[-1] / abs(beta))
    # nearest_omega finds the ω of a point of the curve (within a period of the hint)
    for k in range(5):
        w = s.period * (k + 0.3) / 5
        q = s.eval(w)[0]
        got = nearest_omega(s, q)
        assert _norm([a - b for a, b in zip(s.eval(got)[0], q)]) < 1e-6


def test_the_parameter_is_near_arc_length_so_speed_sets_the_speed_on_the_path():
    s = make_path({"family": "spline", "waypoints": [list(p) for p in SQUARE], "speed": 1.5})
    n = 2000
    speeds = [_norm(s.eval(s.period * (i + 0.5) / n)[1]) for i in range(n)]
    assert s.beta == 1.5
    assert 0.96 * 1.5 < min(speeds) and max(speeds) < 1.03 * 1.5
    assert sum(speeds) * s.period / n == pytest.approx(s.knots[-1], rel=1e-4)  # the lap length: the knots' span
    assert s.knots[-1] == pytest.approx(43.81, abs=0.01)  # docs/config.md's figure


def test_an_open_spline_runs_straight_on_beyond_its_ends_and_nearest_omega_finds_its_body():
    s = spline(((0.0, 0.0), (10.0, 0.0), (20.0, 5.0)), closed=False)
    assert s.period is None and s.span == (0.0, s.knots[-1])
    f, f1, f2 = s.eval(-3.0)
    assert f2 == (0.0, 0.0)
    f0, f01, _ = s.eval(0.0)
    assert f == pytest.approx(tuple(a - 3.0 * b for a, b in zip(f0, f01)))
    end = s.eval(s.knots[-1])
    assert s.eval(s.knots[-1] + 2.0)[0] == pytest.approx(tuple(a + 2.0 * b for a, b in zip(end[0], end[1])))
    w = nearest_omega(s, (15.0, 10.0), hint=-100.0)  # the hint is far off: the body is sampled
    assert 0.0 < w < s.knots[-1]
    assert nearest_omega(s, s.eval(12.3)[0]) == pytest.approx(12.3, abs=1e-9)


def test_a_3d_center_lifts_2d_waypoints_and_a_boat_follows_their_x_y():
    air = make_path({"family": "spline", "waypoints": [list(p) for p in SQUARE], "center": [5, -5, 15]})
    water = make_path({"family": "spline", "waypoints": [list(p) for p in SQUARE], "center": [5, -5]})
    assert air.dim == 3 and water.dim == 2
    for w in (0.0, 3.3, 17.0, 40.1):
        a, b = air.eval(w), for_dimension(air, 2).eval(w)
        assert a[0][2] == 15.0 and a[1][2] == 0.0 and a[2][2] == 0.0
        assert b == water.eval(w)  # the same numbers to the bit: a drone above its boat


@pytest.mark.parametrize("spec, field, words", [
    ({"waypoints": [[0, 0], [10, 0]]}, "waypoints", ["at least 3 waypoints, got 2", "closed = false"]),
    ({"waypoints": [[0, 0]], "closed": False}, "waypoints", ["at least 2 waypoints, got 1"]),
    ({"waypoints": [[0, 0], [10, 0], [10, 0], [0, 10]]}, "waypoints",
     ["waypoint 2 [10, 0] repeats waypoint 1 [10, 0]", "drop one of them"]),
    ({"waypoints": [[0, 0], [10, 0], [10, 10], [0, 0]]}, "waypoints",
     ["waypoint 3 [0, 0] repeats waypoint 0 [0, 0]", "joins its last waypoint to its first itself: drop waypoint 3"]),
    ({"waypoints": [[0, 0], [10, 0], [0, 0.5], [-5, 8]]}, "waypoints",
     ["waypoint 1 [10, 0]: the path turns back by 177°", "cusp", "round the turn"]),
    ({"waypoints": [[20, -1], [13, -1], [6, -14], [5, 15], [1, 10]]}, "waypoints",
     ["between waypoint 0 [20, -1] and waypoint 1 [13, -1]", "falls to 0.45 of the speed asked",
      "space them more evenly"]),
    ({"waypoints": [[0, 0], [10, 0], [5, float("nan")]]}, "waypoints[2]", ["finite numbers", "nan"]),
    ({"waypoints": [[0, 0], [10, 0], [5, 1e7]]}, "waypoints[2]", ["<= 1e+06", "1e+07"]),
    ({"waypoints": [[0, 0], [10, 0], [5, 5, 5]]}, "waypoints[2]", ["has 3 coordinates, waypoint 0 has 2"]),
    ({"waypoints": [[0, 0], [10, 0], [5, True]]}, "waypoints[2]", ["finite numbers"]),
    ({"waypoints": "a list"}, "waypoints", ["must be a list of 1 to"]),
    ({"waypoints": [[0, 0], [10, 0], [5, 5]], "closed": 1}, "closed", ["true or false"]),
    ({"waypoints": [[0, 0, 0], [10, 0, 0], [5, 5, 0]], "center": [1, 2]}, "center", ["has 2 coordinates"]),
])
def test_a_refused_waypoint_list_names_the_waypoint_and_the_fix(spec, field, words):
    with pytest.raises(PathError) as e:
        make_path({"family": "spline", **spec})
    assert e.value.field == field
    for w in words:
        assert w in e.value.message, (w, e.value.message)


def test_the_lake_survey_lanes_keep_their_speed_and_straight_legs():
    """configs/lake_survey.toml's lane: the speeds docs/config.md quotes, legs straight within 0.3 m."""
    import tomllib
    import pathlib

    cfg = tomllib.loads((pathlib.Path(__file__).parents[3] / "configs" / "lake_survey.toml").read_text())
    s = make_path(cfg["defaults"]["path"])
    n = 4000
    speeds = [_norm(s.eval(s.period * (i + 0.5) / n)[1]) / 1.5 for i in range(n)]
    assert (f"{min(speeds):.2f}", f"{max(speeds):.2f}", f"{s.knots[-1]:.1f}") == ("0.96", "1.03", "332.7")
    leg = [s.eval(s.period * i / n)[0] for i in range(n)]
    assert max(abs(p[0]) for p in leg if 0 <= p[1] <= 60 and p[0] < 5) < 0.31


def test_nearest_omega_on_an_open_spline_finds_the_nearest_leg_not_the_one_nearest_the_hint():
    """Newton from the hint alone stops on the first leg's local minimum (9 m off); the body's
    samples find the last leg (1.6 m off)."""
    s = spline(((0.0, 0.0), (20.0, 0.0), (20.0, 10.0), (0.0, 10.0)), closed=False)
    w = nearest_omega(s, (2.0, 9.0), hint=0.0)
    assert _norm([a - b for a, b in zip(s.eval(w)[0], (2.0, 9.0))]) < 2.0
    assert s.knots[2] < w < s.knots[3]


def test_an_open_spline_bends_from_its_first_waypoint_on():
    """(mutmut: running straight on up to t = 1 instead of t = 0 went unseen) the curve leaves
    its start along the segment's polynomial: f'' grows from 0 (the natural end) at once."""
    s = spline(((0.0, 0.0), (10.0, 0.0), (20.0, 10.0)), closed=False, beta=2.0)
    _, _, f2 = s.eval(0.25)  # t = βω = 0.5, inside the first segment
    a, b, c, d = s.segments[0]
    assert f2 == tuple(4.0 * (2.0 * c_ + 6.0 * 0.5 * d_) for c_, d_ in zip(c, d))
    assert _norm(f2) > 0.0


def test_a_planar_spline_for_a_drone_is_refused_with_the_spline_s_fix():
    # a 2-D spline given to a drone (config or `cdus gs path`) said "give the center/origin a z
    # component" only: a spline has no origin and need not have a center; its fix is its waypoints' z
    flat = spline(((0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)))
    with pytest.raises(PathError) as info:
        for_dimension(flat, 3)
    assert "a spline: give its waypoints a z component" in str(info.value)
