"""The registry: every family declared once, with parameters the scenario reads."""

import pytest

from cdus.core.paths import FAMILIES, REGISTRY, Family, Param, register
from cdus.core.paths.circle import Circle
from cdus.scenario.paths import make_path


def test_every_family_is_declared_once_and_summarised():
    assert list(FAMILIES) == list(REGISTRY) == ["circle", "ellipse", "lissajous", "self_intersecting", "trefoil",
                                               "line", "spline"]
    assert FAMILIES["spline"] == REGISTRY["spline"].summary and len(FAMILIES) == 7
    with pytest.raises(ValueError, match="registered twice"):
        register(Family("circle", "again", (), Circle))
    assert REGISTRY["circle"].build is Circle


def test_a_parameter_of_an_unknown_kind_is_a_programming_error():
    with pytest.raises(ValueError, match="kind 'matrix'"):
        Family("x", "", (Param("m", "matrix"),), Circle)


@pytest.mark.parametrize("name", ["circle", "line", "spline"])
def test_speed_sets_beta_for_the_families_that_declare_how(name):
    family = REGISTRY[name]
    assert family.speed is not None
    table = {"circle": {"center": [0, 0], "radius": 4}, "line": {"origin": [0, 0], "heading": [1, 0]},
             "spline": {"waypoints": [[0, 0], [10, 0], [10, 10]]}}[name]
    path = make_path({"family": name, "speed": 2.0, **table})
    assert path.beta == (0.5 if name == "circle" else 2.0)


def test_speed_is_refused_where_a_family_declares_no_constant_speed():
    with pytest.raises(ValueError, match="only circle, line and spline have a constant on-path speed"):
        make_path({"family": "ellipse", "center": [0, 0], "a": 2, "b": 1, "speed": 1})
