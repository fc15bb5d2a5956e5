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


#: a smallest valid table of each family
TABLES = {"circle": {"center": [0, 0], "radius": 4}, "ellipse": {"center": [0, 0], "a": 2, "b": 1},
          "lissajous": {"center": [0, 0], "amplitude": [2, 1], "frequency": [1, 2], "phase": [0, 1.5708]},
          "self_intersecting": {}, "trefoil": {"center": [0, 0, 5]}, "line": {"origin": [0, 0], "heading": [1, 0]},
          "spline": {"waypoints": [[0, 0], [10, 0], [10, 10]]}}


@pytest.mark.parametrize("name", list(TABLES))
def test_every_family_takes_beta_and_direction_from_its_table(name):
    """(mutmut found the spline's builder could drop `direction` unseen)"""
    assert set(TABLES) == set(REGISTRY)
    path = make_path({"family": name, "beta": 0.5, "direction": 1, **TABLES[name]})
    assert (path.beta, path.direction) == (0.5, 1.0)
    assert make_path({"family": name, **TABLES[name]}).direction == -1.0
