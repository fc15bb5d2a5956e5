"""[[obstacle]]: the four shapes, the margin's default, and each bad table naming the field and the fix."""

import math

import pytest

from cdus.core.obstacles import Box, Circle, Cylinder, Polygon
from cdus.scenario.config import ConfigError, parse_scenario

from .common import base, problems


def test_the_four_shapes_and_the_margin_default():
    data = base()
    data["safety"] = {"radius": 3.0}
    data["obstacle"] = [
        {"shape": "circle", "center": [1, 2], "radius": 3, "name": "island"},
        {"shape": "polygon", "vertices": [[0, 0], [0, 1], [1, 1], [1, 0]], "margin": 0.5},
        {"shape": "cylinder", "center": [5, 5], "radius": 1, "z": [0, 30]},
        {"shape": "box", "min": [0, 0, 0], "max": [1, 2, 3], "margin": 0},
    ]
    got = parse_scenario(data).obstacles
    assert got == (Circle((1.0, 2.0), 3.0, 3.0, "island"),
                   Polygon(((1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.0, 0.0)), 0.5, "obstacle[1]"),
                   Cylinder((5.0, 5.0), 1.0, (0.0, 30.0), 3.0, "obstacle[2]"),
                   Box((0.0, 0.0, 0.0), (1.0, 2.0, 3.0), 0.0, "obstacle[3]"))
    assert parse_scenario(base()).obstacles == ()


@pytest.mark.parametrize("table, text", [
    ({"center": [0, 0], "radius": 1}, "obstacle[0].shape: missing; give the shape, one of circle, polygon"),
    ({"shape": "sphere"}, 'obstacle[0].shape: unknown shape "sphere"'),
    ({"shape": "circle", "center": [0, 0]}, "obstacle[0].radius: missing; a circle needs center, radius"),
    ({"shape": "circle", "center": [0, 0], "radius": -1}, "obstacle[0].radius: must be a number > 0"),
    ({"shape": "circle", "center": [0, 0, 1], "radius": 1}, "obstacle[0].center: must be a list of 2 numbers"),
    ({"shape": "circle", "center": [0, 0], "radius": 1, "margin": -1}, "obstacle[0].margin: must be a number >= 0"),
    ({"shape": "circle", "center": [0, 0], "radius": 1, "z": [0, 1]}, "obstacle[0].z: unknown key"),
    ({"shape": "cylinder", "center": [0, 0], "radius": 1, "z": [5, 1]},
     "obstacle[0].z: the floor must be below the ceiling, got [5, 1]"),
    ({"shape": "box", "min": [0, 0, 0], "max": [1, 0, 1]}, "obstacle[0].max: must be above obstacle[0].min on every "
                                                            "axis: y max 0 is not above min 0"),
    ({"shape": "polygon", "vertices": [[0, 0], [4, 0], [1, 1], [0, 4]]},
     "obstacle[0].vertices[2]: turns the other way from the rest: the polygon is not convex"),
    ({"shape": "polygon", "vertices": [[0, 0], [1, 0], [2, 0], [1, 1]]},
     "obstacle[0].vertices[1]: lies on the line through its neighbours"),
    ({"shape": "polygon", "vertices": [[0, 0], [1, "a"], [1, 1]]}, "obstacle[0].vertices[1]: must be a list of 2"),
    ({"shape": "polygon", "vertices": [[0, 0], [1, 0]]}, "obstacle[0].vertices: a polygon needs at least 3 vertices"),
    ({"shape": "polygon", "vertices": [0, 0, 4, 0, 0, 3]},
     "obstacle[0].vertices: must be a list of corners, each a list [x, y], got a flat list of 6 numbers; write e.g. "
     "vertices = [[0.0, 0.0], [4.0, 0.0], [0.0, 3.0]]"),
])
def test_a_bad_obstacle_names_the_field_and_the_fix(table, text):
    data = base()
    data["obstacle"] = [table]
    assert text in problems(data)


def test_a_flat_vertex_list_is_one_problem_not_one_per_number():
    data = base()
    data["obstacle"] = [{"shape": "polygon", "vertices": [0, 0, 4, 0, 0, 3]}]
    with pytest.raises(ConfigError) as info:
        parse_scenario(data)
    assert [field for field, _ in info.value.problems] == ["obstacle[0].vertices"]


def test_two_obstacles_of_one_name_are_refused_naming_both():
    """The metrics' obstacles block and Rerun's labels name an obstacle by its name: two "a"s (or a
    name that is another table's default, obstacle[j]) would be told apart by nothing."""
    circle = {"shape": "circle", "center": [0, 0], "radius": 1}
    data = base()
    data["obstacle"] = [dict(circle, name="a"), dict(circle, center=[5, 5], name="a")]
    assert 'obstacle[1].name: "a" names obstacle[0] too: give each obstacle its own name' in problems(data)
    data["obstacle"] = [dict(circle, name="obstacle[1]"), dict(circle, center=[5, 5])]
    assert 'obstacle[1].name: "obstacle[1]" names obstacle[0] too' in problems(data)
    data["obstacle"] = [dict(circle, name="a"), dict(circle, center=[5, 5], name="b"), dict(circle, center=[9, 9])]
    assert [o.name for o in parse_scenario(data).obstacles] == ["a", "b", "obstacle[2]"]


def test_obstacle_must_be_an_array_of_tables():
    data = base()
    data["obstacle"] = {"shape": "circle"}
    assert "obstacle: must be an array of tables ([[obstacle]] sections" in problems(data)


from hypothesis import given, settings, strategies as st  # noqa: E402

from cdus.scenario.config import ConfigError  # noqa: E402

_value = st.one_of(st.none(), st.booleans(), st.integers(-10, 10), st.floats(allow_nan=True),
                   st.text(max_size=4), st.lists(st.floats(-1e7, 1e7), max_size=4),
                   st.lists(st.lists(st.floats(-10, 10), min_size=2, max_size=3), max_size=5))


@settings(max_examples=300, deadline=None)
@given(shape=st.sampled_from(["circle", "polygon", "cylinder", "box", "cone", 3]),
       table=st.dictionaries(st.sampled_from(["center", "radius", "vertices", "z", "min", "max", "margin", "name",
                                              "colour"]), _value, max_size=5))
def test_any_obstacle_table_is_taken_or_refused_naming_an_obstacle_field(shape, table):
    data = base()
    data["obstacle"] = [{"shape": shape, **table}]
    try:
        got = parse_scenario(data).obstacles
    except ConfigError as e:
        assert e.problems and all(field.startswith("obstacle[0]") or field.endswith("].phase") and
                                  "would start" in why for field, why in e.problems), e.problems
    else:
        assert len(got) == 1 and got[0].shape == shape


@pytest.mark.parametrize("obstacle", [
    {"shape": "circle", "center": [1e6, -1e6], "radius": 1e6, "margin": 1e6},
    {"shape": "circle", "center": [0, 0], "radius": 1e-300, "margin": 0},
    {"shape": "box", "min": [-1e6, -1e6, -1e6], "max": [1e6, 1e6, 0], "margin": 1e6},
    {"shape": "cylinder", "center": [0, 0], "radius": 1e6, "z": [-1e6, 0], "margin": 1e6},
])
def test_obstacles_at_their_bounds_run_to_the_end(obstacle):
    """Every vehicle that sees these starts inside their margin: the filter pushes out within its
    speed bound, never a crash (inside the solid itself it is refused: the next test)."""
    from cdus.sim.fleet import InProcessFleet

    data = base()
    data["scenario"]["duration"] = 1.0
    data["rates"] = {"physics": 20.0, "control": 10.0}
    data["safety"] = {"enabled": True}
    data["defaults"] = {"limits": {"speed": 5.0}}
    data["obstacle"] = [obstacle]
    m = InProcessFleet(parse_scenario(data)).run().metrics
    assert m.completed and m.obstacles.count == 1


def test_the_documented_example_loads_onto_lake_circle_with_every_key_of_the_table():
    """docs/config.md, "[[obstacle]]": the TOML block, pasted under configs/lake_circle.toml, gives
    the four shapes with the filter on; the table's keys are the ones the section takes."""
    import pathlib
    import re
    import tomllib

    from cdus.scenario.obstacles import COMMON_KEYS, SHAPE_KEYS

    root = pathlib.Path(__file__).resolve().parents[2]
    section = (root / "docs" / "config.md").read_text().split("### `[[obstacle]]`")[1].split("\n### ")[0]
    [block] = re.findall(r"```toml\n(.*?)```", section, re.S)
    sc = parse_scenario(tomllib.loads((root / "configs" / "lake_circle.toml").read_text() + "\n" + block))
    assert sc.safety.enabled and [(o.shape, o.name, o.margin) for o in sc.obstacles] == [
        ("circle", "island", 1.0), ("polygon", "pier", 1.0), ("cylinder", "no-fly", 1.0), ("box", "crane", 1.0)]
    documented = set(re.findall(r"^\| `(\w+)`(?:, `(\w+)`)? \|", section, re.M))
    keys = {k for pair in documented for k in pair if k}
    assert keys == set(COMMON_KEYS) | {k for ks in SHAPE_KEYS.values() for k in ks}


@pytest.mark.parametrize("obstacle, speed, field", [
    ({"shape": "circle", "center": [0, 0], "radius": 1e5}, None, 'vehicle[0] (id "usv1").phase'),
    ({"shape": "box", "min": [-1e6, -1e6, -1e6], "max": [1e6, 1e6, 1e6]}, 5.0, 'vehicle[2] (id "uav1").phase'),
    ({"shape": "cylinder", "center": [0, 0], "radius": 1e6, "z": [-1e6, 1e6]}, 5.0, 'vehicle[2] (id "uav1").phase'),
])
def test_a_vehicle_that_would_start_inside_an_obstacle_is_refused_naming_it(obstacle, speed, field):
    """The filter pushed such a vehicle out at gamma x its depth: a boat 1e5 m inside a circle with
    no speed limit left at km/s (|Φ| 143,681 m after 20 s); now the scenario is refused, naming
    the vehicle's field and the fix. A start inside the margin only is taken (the test above)."""
    data = base()
    if speed is not None:
        data["defaults"] = {"limits": {"speed": speed}}
    data["obstacle"] = [obstacle]
    text = problems(data)
    assert f"{field}: vehicle " in text and "would start" in text and "inside obstacle 'obstacle[0]'" in text
    assert "start it outside (start.position, phase or path) or move the [[obstacle]]" in text
    if obstacle["shape"] == "circle":  # a start given: named as such, and one outside is taken
        data["vehicle"][0]["start"] = {"position": [2e5, 0.0]}
        assert "usv1" not in problems(data) and 'vehicle[1] (id "usv2").phase' in problems(data)
        data["vehicle"][0]["start"] = {"position": [0.0, 0.0]}
        assert 'vehicle[0] (id "usv1").start: vehicle usv1 would start 100000 m inside' in problems(data)


def test_more_polygon_vertices_than_the_filter_can_measure_each_step_are_refused():
    """100 polygons of 256 corners each passed (29-66 ms per filter call, against a 20 ms control
    period at 50 Hz); the total is bounded, and at the bound it is taken."""
    def ring(n, cx):
        return [[cx + math.cos(2 * math.pi * k / n), 50 + math.sin(2 * math.pi * k / n)] for k in range(n)]
    data = base()
    data["obstacle"] = [{"shape": "polygon", "vertices": ring(256, 10.0 * j)} for j in range(4)]
    assert len(parse_scenario(data).obstacles) == 4  # 1,024: the bound
    data["obstacle"].append({"shape": "polygon", "vertices": ring(3, 50.0)})
    assert ("obstacle: at most 1024 polygon vertices over all the [[obstacle]] tables (each is an edge every "
            "vehicle's safety filter measures at every step), got 1027: outline the polygons with fewer corners"
            ) in problems(data)
