"""Paths: closed-form f', f'' against finite differences, periods, construction errors."""

import math

import pytest

from cdus.core.paths import PathError, for_dimension, nearest_omega, turning_point
from cdus.scenario.paths import make_path

TAU = 2.0 * math.pi

# Every family make_path builds, each with beta != 1 so the scaling enters every term.
SPECS = {
    "circle_2d": {"family": "circle", "center": [-40, 50], "radius": 10, "beta": 0.7},
    "circle_3d": {"family": "circle", "center": [-40, 50, 20], "radius": 10, "beta": -1.3},
    "ellipse_rotated": {"family": "ellipse", "center": [1, -2], "a": 6, "b": 2.5,
                        "rotation": 0.6, "beta": 1.7},
    "ellipse_3d": {"family": "ellipse", "center": [1, -2, 5], "a": 6, "b": 2.5,
                   "rotation": -1.1, "beta": 0.4},
    "self_intersecting": {"family": "self_intersecting", "d": 7, "center": [3, -1, 20],
                          "beta": 0.8},
    "lissajous_2d": {"family": "lissajous", "center": [0, 1], "amplitude": [5, 3],
                     "frequency": [2, 3], "phase": [0.3, -0.2], "beta": 1.2},
    "lissajous_3d": {"family": "lissajous", "center": [0, 1, 10], "amplitude": [5, 3, 2],
                     "frequency": [2, 3, 1.5], "phase": [0.3, -0.2, 1.0], "beta": 0.9},
    "trefoil": {"family": "trefoil", "center": [0, 0, 15], "scale": 2.0, "height": 1.5,
                "beta": 1.4},
    "line_2d": {"family": "line", "origin": [1, 2], "heading": [3, 4], "beta": 2.5},
    "line_3d": {"family": "line", "origin": [1, 2, 3], "heading": [1, -2, 2], "beta": 0.5},
}

OMEGAS = (-3.7, -0.4, 0.0, 0.9, 2.3, 11.1)


def _central(fun, w, h):
    plus, minus = fun(w + h), fun(w - h)
    return tuple((a - b) / (2 * h) for a, b in zip(plus, minus))


def _close(got, want, rel=1e-6, scale=1.0):
    """|got - want| <= rel * max(|want|, scale), componentwise."""
    return all(abs(g - x) <= rel * max(abs(x), scale) for g, x in zip(got, want))


@pytest.mark.parametrize("name", sorted(SPECS))
def test_derivatives_match_central_differences(name):
    path = make_path(SPECS[name])
    h = 1e-5
    for w in OMEGAS:
        f, f1, f2 = path.eval(w)
        assert len(f) == len(f1) == len(f2) == path.dim
        fd1 = _central(lambda x: path.eval(x)[0], w, h)
        fd2 = _central(lambda x: path.eval(x)[1], w, h)
        # the scale floor keeps components that pass through 0 from demanding
        # an absolute accuracy finite differences cannot give
        s1 = max(1.0, max(abs(x) for x in f1))
        s2 = max(1.0, max(abs(x) for x in f2))
        assert _close(f1, fd1, scale=s1), (name, w, f1, fd1)
        assert _close(f2, fd2, scale=s2), (name, w, f2, fd2)


def test_finite_difference_check_can_fail():
    """The derivative check above is sharp enough to notice a wrong beta factor."""
    path = make_path(SPECS["circle_2d"])
    wrong = make_path({**SPECS["circle_2d"], "beta": 0.7 * (1 + 1e-4)})
    w, h = 0.9, 1e-5
    fd1 = _central(lambda x: path.eval(x)[0], w, h)
    assert not _close(wrong.eval(w)[1], fd1, scale=10.0)


@pytest.mark.parametrize(
    "spec, period",
    [
        ({"family": "circle", "center": [0, 0], "radius": 3}, TAU),
        ({"family": "circle", "center": [0, 0], "radius": 3, "beta": 0.5}, TAU / 0.5),
        ({"family": "circle", "center": [0, 0], "radius": 3, "beta": -4.0}, TAU / 4.0),
        ({"family": "ellipse", "center": [0, 0], "a": 2, "b": 1, "beta": 2.0}, TAU / 2.0),
        ({"family": "self_intersecting"}, 4 * math.pi),
        ({"family": "self_intersecting", "d": -14, "beta": 2.0}, 2 * math.pi),
        ({"family": "lissajous", "center": [0, 0, 0], "amplitude": [1, 1, 1],
          "frequency": [2, 3, 1.5]}, 4 * math.pi),
        ({"family": "lissajous", "center": [0, 0], "amplitude": [1, 1],
          "frequency": [2, 3]}, TAU),
        ({"family": "trefoil", "center": [0, 0, 0], "beta": 0.25}, 4 * TAU),
        ({"family": "line", "origin": [0, 0], "heading": [1, 0]}, None),
    ],
)
def test_period(spec, period):
    path = make_path(spec)
    if period is None:
        assert path.period is None
        return
    assert path.period == pytest.approx(period, rel=1e-12)
    for w in OMEGAS:
        f, f1, f2 = path.eval(w)
        g, g1, g2 = path.eval(w + path.period)
        for a, b in zip(f + f1 + f2, g + g1 + g2):
            assert a == pytest.approx(b, abs=1e-9)


def test_period_is_the_smallest():
    """Half the Lissajous period is not a period (the curve is not traced twice)."""
    path = make_path({"family": "lissajous", "center": [0, 0, 0], "amplitude": [1, 1, 1],
                      "frequency": [2, 3, 1.5]})
    f, _, _ = path.eval(0.3)
    g, _, _ = path.eval(0.3 + path.period / 2)
    assert max(abs(a - b) for a, b in zip(f, g)) > 0.1


def test_irrational_frequencies_have_no_period():
    path = make_path({"family": "lissajous", "center": [0, 0], "amplitude": [1, 1],
                      "frequency": [1.0, math.sqrt(2)]})
    assert path.period is None


@pytest.mark.parametrize("family, extra", [
    ("circle", {"center": [-40, 50], "radius": 10}),
    ("circle", {"center": [0, 0, 20], "radius": 4}),
    ("line", {"origin": [0, 0], "heading": [3, -4]}),
])
def test_speed_sets_on_path_speed(family, extra):
    path = make_path({"family": family, "speed": 1.5, **extra})
    for w in OMEGAS:
        _, f1, _ = path.eval(w)
        assert math.hypot(*f1) == pytest.approx(1.5, rel=1e-12)


def test_speed_on_circle_is_beta_times_radius():
    path = make_path({"family": "circle", "center": [0, 0], "radius": 10, "speed": 2.0})
    assert path.beta == pytest.approx(0.2)


def test_direction_default_and_override():
    spec = {"family": "circle", "center": [0, 0], "radius": 1}
    assert make_path(spec).direction == -1.0
    assert make_path({**spec, "direction": 1}).direction == 1.0
    for name, s in SPECS.items():
        assert make_path(s).direction == -1.0, name


@pytest.mark.parametrize("spec, field", [
    ({"family": "spiral", "center": [0, 0]}, "family"),
    ({"center": [0, 0], "radius": 1}, "family"),
    ({"family": "circle", "center": [0, 0]}, "radius"),
    ({"family": "circle", "center": [0, 0], "radius": -2}, "radius"),
    ({"family": "circle", "center": [0, 0], "radius": 0}, "radius"),
    ({"family": "circle", "center": [0, 0], "radius": True}, "radius"),
    ({"family": "circle", "center": [0, 0], "radius": 1, "beta": False}, "beta"),
    ({"family": "circle", "center": [0, True], "radius": 1}, "center"),
    ({"family": "circle", "center": [0, 0, 0, 0], "radius": 1}, "center"),
    ({"family": "circle", "center": [0], "radius": 1}, "center"),
    ({"family": "circle", "center": [0, 0], "radius": "10"}, "radius"),
    ({"family": "circle", "center": [0, 0], "radius": float("nan")}, "radius"),
    ({"family": "circle", "center": [0, 0], "radius": 1, "radious": 2}, "radious"),
    ({"family": "circle", "center": [0, 0], "radius": 1, "speed": 2, "beta": 0.5}, "speed"),
    ({"family": "ellipse", "center": [0, 0], "a": 1, "b": 1, "speed": 2}, "speed"),
    ({"family": "circle", "center": [0, 0], "radius": 1, "direction": 0}, "direction"),
    ({"family": "circle", "center": [0, 0], "radius": 1, "direction": 0.5}, "direction"),
    ({"family": "circle", "center": [0, 0], "radius": 1, "beta": 0}, "beta"),
    ({"family": "self_intersecting", "center": [0, 0]}, "center"),
    ({"family": "lissajous", "center": [0, 0, 0], "amplitude": [1, 1],
      "frequency": [1, 2, 3]}, "amplitude"),
    ({"family": "trefoil", "center": [0, 0]}, "center"),
    ({"family": "line", "origin": [0, 0], "heading": [0, 0]}, "heading"),
    ({"family": "line", "origin": [0, 0], "heading": [1, 0, 0]}, "heading"),
])
def test_path_errors_name_the_field(spec, field):
    with pytest.raises(PathError) as info:
        make_path(spec)
    assert info.value.field == field
    assert str(info.value).startswith(f"{field}: ")


def test_unknown_family_lists_the_valid_ones():
    with pytest.raises(PathError) as info:
        make_path({"family": "spiral"})
    for family in ("circle", "ellipse", "self_intersecting", "lissajous", "trefoil", "line"):
        assert family in info.value.message


def test_path_error_is_a_value_error():
    with pytest.raises(ValueError):
        make_path({"family": "circle", "center": [0, 0], "radius": -1})


def test_for_dimension_usv_takes_x_y_of_a_3d_path():
    path3 = make_path(SPECS["self_intersecting"])
    planar = for_dimension(path3, 2)
    assert planar.dim == 2
    assert planar.period == path3.period
    assert planar.direction == path3.direction
    for w in OMEGAS:
        full = path3.eval(w)
        flat = planar.eval(w)
        for a, b in zip(full, flat):
            assert b == a[:2]


def test_for_dimension_same_dimension_is_identity():
    path = make_path(SPECS["circle_2d"])
    assert for_dimension(path, 2) is path


def test_for_dimension_uav_on_planar_path_raises():
    with pytest.raises(PathError) as info:
        for_dimension(make_path(SPECS["circle_2d"]), 3)
    assert info.value.field == "path"


@pytest.mark.parametrize("hint", [0.0, 5.0, -20.0, 100.0])
def test_nearest_omega_on_a_circle(hint):
    path = make_path({"family": "circle", "center": [-40, 50], "radius": 10})
    angle = 2.0  # the point sits outside the circle at polar angle 2 rad
    q = (-40 + 13 * math.cos(angle), 50 + 13 * math.sin(angle))
    w = nearest_omega(path, q, hint)
    assert abs(w - hint) <= path.period
    # same angle as q, modulo 2π
    assert math.remainder(w - angle, TAU) == pytest.approx(0.0, abs=1e-9)
    f, _, _ = path.eval(w)
    assert math.dist(f, q) == pytest.approx(3.0, abs=1e-9)


def test_nearest_omega_on_a_circle_with_beta():
    path = make_path({"family": "circle", "center": [0, 0], "radius": 2, "beta": 0.5})
    q = (0.0, -1.0)  # inside, nearest point at polar angle -π/2: βω = -π/2 mod 2π
    w = nearest_omega(path, q, hint=1.0)
    assert abs(w - 1.0) <= path.period
    f, _, _ = path.eval(w)
    assert f == pytest.approx((0.0, -2.0), abs=1e-9)


@pytest.mark.parametrize("hint", [0.0, -50.0, 37.5])
def test_nearest_omega_on_a_line(hint):
    path = make_path({"family": "line", "origin": [1, 2, 3], "heading": [1, -2, 2], "beta": 0.5})
    q = (4.0, -1.0, 9.0)
    w = nearest_omega(path, q, hint)
    f, f1, _ = path.eval(w)
    # the error is perpendicular to the line
    assert sum((a - b) * d for a, b, d in zip(q, f, f1)) == pytest.approx(0.0, abs=1e-9)
    # projection: ω = (q - p0)·u / β with u = (1, -2, 2)/3
    assert w == pytest.approx((3 * 1 + -3 * -2 + 6 * 2) / 3 / 0.5, abs=1e-9)


def test_nearest_omega_on_self_intersecting_stays_within_a_period_of_the_hint():
    path = make_path({"family": "self_intersecting", "d": 0})
    target = 1.3
    q, _, _ = path.eval(target)
    for hint in (-30.0, 0.0, 2.0, 40.0):
        w = nearest_omega(path, q, hint)
        assert abs(w - hint) <= path.period
        assert math.remainder(w - target, path.period) == pytest.approx(0.0, abs=1e-7)


@pytest.mark.parametrize("frequency, phase, turns", [
    ([1, 2], [0, 0], True),  # the default phases: a parabola traced back and forth
    ([1, 2], [math.pi / 2, 0], True),  # x = -sin, y = 1 - 2x²: the same
    ([1, 2], [0, math.pi / 2], False),  # a figure-eight
    ([1, 1], [0, math.pi], True),  # a segment
    ([1, 1], [0, math.pi / 2], False),  # an ellipse
    ([2, 3], [1.0, 1.5], True),  # both axes turn at ω = -0.5/β
    ([2, 3], [0.3, -0.2], False),
    ([1, math.sqrt(2)], [0, 0], True),  # no period, still turns at 0
    ([1, math.sqrt(2)], [0.3, 0.1], False),
])
def test_a_lissajous_turns_back_where_every_moving_axis_stops_at_once(frequency, phase, turns):
    path = make_path({"family": "lissajous", "center": [0, 0], "amplitude": [20, 10], "frequency": frequency,
                      "phase": phase, "beta": 0.37})
    w = turning_point(path)
    assert (w is not None) == turns
    if turns:  # f' vanishes there and the curve is the same either side: vehicles meet on it
        _, f1, _ = path.eval(w)
        assert max(map(abs, f1)) < 1e-7
        for tau in (0.1, 0.7, 2.3):
            f, _, _ = path.eval(w + tau)
            g, _, _ = path.eval(w - tau)
            assert max(abs(a - b) for a, b in zip(f, g)) < 1e-7


def test_only_a_lissajous_turns_back_and_a_boat_sees_its_x_y():
    assert turning_point(make_path({"family": "circle", "center": [0, 0], "radius": 3})) is None
    assert turning_point(make_path({"family": "self_intersecting"})) is None
    assert turning_point(for_dimension(make_path({"family": "self_intersecting"}), 2)) is None
    lifted = make_path({"family": "lissajous", "center": [0, 0, 5], "amplitude": [20, 10, 2],
                        "frequency": [1, 2, 1], "phase": [0, 0, 1.0]})
    assert turning_point(lifted) is None and turning_point(for_dimension(lifted, 2)) == 0.0
