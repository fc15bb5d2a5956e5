"""Plug-ins in process (cdus.scenario.plugins): a user's family and plant from a module the
scenario names, or an installed package's entry points, registered where the scenario is read;
each failure (import, shape, name, values, derivatives, a plant's step) a problem naming the
plug-in before anything runs, or, at run time, a diverged vehicle naming it."""

from __future__ import annotations

import math
import textwrap
import uuid

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from cdus.core.models import PLANTS
from cdus.core.paths import REGISTRY
from cdus.core.vehicle import DivergedError
from cdus.scenario import plugins
from cdus.scenario.checks import Problems
from cdus.scenario.config import ConfigError, parse_scenario
from cdus.sim.fleet import InProcessFleet
from tests.plugins.install import EXAMPLE, install_example


@pytest.fixture
def fresh(tmp_path, monkeypatch):
    """This process's registries and plug-ins restored after the test; ``tmp_path`` importable."""
    saved = dict(REGISTRY), dict(PLANTS), dict(plugins.LOADED)
    plugins.entry_points.cache_clear()
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    for table, old in zip((REGISTRY, PLANTS, plugins.LOADED), saved):
        table.clear()
        table.update(old)
    plugins.entry_points.cache_clear()


FAMILY = """
import math
from dataclasses import dataclass
from cdus.core.paths import Family, Param

@dataclass(frozen=True)
class Curve:
    center: tuple
    radius: float
    beta: float = 1.0
    direction: float = -1.0
    dim = 2

    @property
    def period(self):
        return 2 * math.pi / abs(self.beta)

    def eval(self, w):
        b, r = self.beta, self.radius
        c, s = math.cos(b * w), math.sin(b * w)
        f = (self.center[0] + r * c, self.center[1] + r * s)
        f1, f2 = (-r * b * s, r * b * c), (-r * b * b * c, -r * b * b * s)
        {change}
        return f, f1, f2

FAMILY = Family("{name}", "center, radius", (Param("center", "vector", required=True, dims=(2,)),
                Param("radius", "positive", required=True)), Curve)
"""

PLANT = """
import math
from dataclasses import dataclass
from cdus.core.models import PlantModel

@dataclass(frozen=True)
class State:
    q: tuple
    v: tuple
    t: float

class Point:
    name = "point"
    velocity_level = True
    exact_when_held = False

    def start(self, q, heading):
        return State(tuple(q), (0.0,) * len(q), 0.0)

    def at_rest(self, state, q, heading):
        return State(tuple(q), (0.0,) * len(q), state.t)

    def step(self, state, u, d, h):
        t = state.t + h
        {change}
        return State(tuple(a + h * b for a, b in zip(state.q, u)), tuple(u), t)

    def velocity(self, state):
        return state.v

    def heading(self, state):
        return math.atan2(state.v[1], state.v[0])

    def finite(self, state):
        return all(map(math.isfinite, state.q + state.v))

MODEL = PlantModel(("usv",), lambda params: Point())
"""


def module(where, text: str, **fill: str) -> str:
    """A module written into ``where`` (on sys.path) under a name of its own; its name."""
    name = "plug_" + uuid.uuid4().hex[:10]
    for key, value in fill.items():
        text = text.replace("{" + key + "}", value)
    (where / f"{name}.py").write_text(textwrap.dedent(text))
    return name


def scenario(family: str = "circle", plant: str = "ideal", table: dict | None = None, **extra) -> dict:
    """A boat on a circle-like path of ``family`` with ``plant``; ``table``: [plugins]."""
    data = {"scenario": {"name": "t", "duration": 3.0}, "rates": {"control": 10.0},
            "vehicle": [{"id": "b1", "kind": "usv", "plant": plant,
                         "path": {"family": family, "center": [0.0, 0.0], "radius": 5.0}}], **extra}
    if table is not None:
        data["plugins"] = table
    return data


def refusal(data: dict) -> str:
    with pytest.raises(ConfigError) as info:
        parse_scenario(data, "x.toml")
    return str(info.value)


# --------------------------------------------------------------------------- the two doors


def test_the_example_from_the_scenarios_table_runs_as_a_circle_of_its_own(fresh, monkeypatch):
    """[plugins] names the example's objects by module (its directory on sys.path): the scenario
    reads, the boats are unicycles on a Gerono lemniscate, and the fleet runs."""
    monkeypatch.syspath_prepend(str(EXAMPLE))
    text = (EXAMPLE / "fleet.toml").read_text()
    import tomllib
    data = tomllib.loads(text)
    data["plugins"] = {"paths": {"gerono": "cdus_plugin_example.gerono:GERONO"},
                       "plants": {"unicycle": "cdus_plugin_example.unicycle:UNICYCLE"}}
    sc = parse_scenario(data, "fleet.toml", {"scenario.duration": 2.0})
    assert [v.plant for v in sc.vehicles] == ["unicycle", "unicycle", "unicycle", "ideal"]
    result = InProcessFleet(sc).run()
    assert result.metrics.final_path_error is not None
    assert all(math.isfinite(x) for x in result.recorder.view("q").ravel())


def test_an_installed_package_is_found_through_its_entry_points(fresh):
    """No [plugins] table: the names come from the dist-info on sys.path alone."""
    install_example(fresh / "site")
    import sys
    sys.path.insert(0, str(fresh / "site"))
    try:
        plugins.entry_points.cache_clear()
        found = {(kind, name): door for kind, name, _, door in plugins.entry_points()}
        assert found[("paths", "gerono")] == 'entry point cdus.paths "gerono" of package cdus-plugin-example 0.1.0'
        sc = parse_scenario(scenario("gerono", "unicycle") | {"vehicle": [
            {"id": "b1", "kind": "usv", "plant": "unicycle", "regulator_gains": {"k_psi": 1.0},
             "path": {"family": "gerono", "center": [0, 0], "half_width": 8, "half_height": 4, "beta": 0.1}}]})
        assert sc.vehicles[0].regulator == "heading" and sc.vehicles[0].regulator_gains == (("k_psi", 1.0),)
    finally:
        sys.path.remove(str(fresh / "site"))


def test_a_plugin_family_takes_a_parameter_no_built_in_has_within_a_positions_bound(fresh, monkeypatch):
    monkeypatch.syspath_prepend(str(EXAMPLE))
    table = {"paths": {"gerono": "cdus_plugin_example.gerono:GERONO"}}
    path = {"family": "gerono", "center": [0, 0], "half_width": 2e6, "half_height": 4}
    text = refusal(scenario(table=table) | {"vehicle": [{"id": "b1", "kind": "usv", "path": path}]})
    assert "vehicle[0] (id \"b1\").path.half_width: must be a finite number >= -1e+06 and <= 1e+06" in text


# --------------------------------------------------------------------------- refused, named


def test_a_name_no_plugin_gave_says_where_the_plugin_would_have_to_be(fresh):
    """A plug-in installed into another Python than the one running cdus (a virtual environment
    whose `cdus` on PATH is the system's) is just an unknown name: the message says which Python
    runs cdus and the other door, for the plant, the vehicle's path and a path event's (it listed
    the built-in names only)."""
    import sys
    data = scenario()  # the events are read once the vehicles are good
    data["event"] = [{"at": 1.0, "action": "path", "vehicle": "b1",
                      "path": {"family": "limacon", "center": [0.0, 0.0], "radius": 3.0}}]
    text = refusal(scenario("limacon", "laggy")) + "\n" + refusal(data)
    for field, kind in (('vehicle[0] (id "b1").plant', "plants"), ('vehicle[0] (id "b1").path.family', "paths"),
                        ("event[0].path.family", "paths")):
        line = next(x for x in text.splitlines() if x.startswith(f"x.toml: {field}: unknown"))
        assert line.split("; choose one of ")[1].split(" (")[1].startswith(
            f"a plug-in's? install its package into the Python that runs cdus, {sys.executable}, or name it in "
            f"[plugins.{kind}]: docs/plugins.md)"), line


def test_a_plugin_that_raises_on_import_is_named_with_the_fix(fresh):
    name = module(fresh, "raise ImportError('needs scipy')\n")
    text = refusal(scenario("mine", table={"paths": {"mine": f"{name}:FAMILY"}}))
    assert text == (f'x.toml: plugins.paths.mine: plug-in path family "mine" ([plugins.paths] of the scenario: '
                    f'{name}:FAMILY) cannot be loaded: ImportError: needs scipy; fix the module, or remove this line')


def test_a_plugin_family_returning_nan_is_refused_naming_it(fresh):
    name = module(fresh, FAMILY, name="nanny", change="f = (math.nan, f[1])")
    text = refusal(scenario("nanny", table={"paths": {"nanny": f"{name}:FAMILY"}}))
    assert (f'vehicle[0] (id "b1").path: plug-in path family "nanny" ([plugins.paths] of the scenario: '
            f'{name}:FAMILY): its values are not finite numbers at ω = 0: a vehicle cannot follow it') in text


def test_a_plugin_whose_derivative_is_not_the_curves_is_refused_naming_which(fresh):
    name = module(fresh, FAMILY, name="nobeta", change="f1 = (-r * s, r * c)")  # β left out of f'
    data = scenario("nobeta", table={"paths": {"nobeta": f"{name}:FAMILY"}})
    data["vehicle"][0]["path"]["beta"] = 0.5
    text = refusal(data)
    assert 'plug-in path family "nobeta"' in text and "its f' at ω = 0 is (-0, 5), but the central difference " \
                                                         "of f gives (0, 2.5): give the derivative of the curve" in text


def test_a_plugin_whose_tangent_vanishes_is_refused(fresh):
    name = module(fresh, FAMILY, name="still", change="f1 = (0.0, 0.0) if w == 0.0 else f1")
    text = refusal(scenario("still", table={"paths": {"still": f"{name}:FAMILY"}}))
    assert "its tangent f'(ω) vanishes at ω = 0 (the guidance needs |f'| > 0 everywhere)" in text


@pytest.mark.parametrize("kind, taken, ref_text, what", [
    ("paths", "circle", FAMILY, "path family"), ("plants", "ideal", PLANT, "plant")])
def test_a_plugin_cannot_take_a_built_in_name(fresh, kind, taken, ref_text, what):
    name = module(fresh, ref_text, name=taken, change="pass")
    obj = "FAMILY" if kind == "paths" else "MODEL"
    text = refusal(scenario(table={kind: {taken: f"{name}:{obj}"}}))
    assert text == (f'x.toml: plugins.{kind}.{taken}: plug-in {what} "{taken}" ([plugins.{kind}] of the scenario: '
                    f'{name}:{obj}): "{taken}" is a built-in {what} of cdus, which a plug-in cannot replace; give '
                    f'the plug-in another name')


@pytest.mark.parametrize("text, obj, want", [
    (FAMILY, "Curve", "is a type, not a cdus.core.paths.Family; point it at a Family"),
    (FAMILY, "FAMILY", 'its Family is named "other", not "mine"; give both one name'),
    (PLANT, "MODEL", "is a PlantModel, not a cdus.core.paths.Family; point it at a Family"),
])
def test_a_plugin_of_the_wrong_shape_is_refused(fresh, text, obj, want):
    name = module(fresh, text, name="other", change="pass")
    problem = refusal(scenario(table={"paths": {"mine": f"{name}:{obj}"}}))
    assert problem.startswith(f'x.toml: plugins.paths.mine: plug-in path family "mine" ([plugins.paths] of the '
                              f'scenario: {name}:{obj}): {want}')


def test_a_plugin_plant_returning_nan_is_refused_before_the_run(fresh):
    name = module(fresh, PLANT, change="return State((math.nan, 0.0), tuple(u), t)")
    text = refusal(scenario(plant="nanboat", table={"plants": {"nanboat": f"{name}:MODEL"}}))
    assert text == (f'x.toml: vehicle[0] (id "b1").plant: plug-in plant "nanboat" ([plugins.plants] of the '
                    f'scenario: {name}:MODEL): its state is no longer finite after a step of 0.005 s with the input '
                    f'(0, -5): State(q=(nan, 0.0), v=(0.0, -5.0), t=0.005) (probed with this vehicle\'s parameters, '
                    f'before anything started)')


@pytest.mark.parametrize("change, said", [
    ("import numpy; f = numpy.array(f)", "at ω = 0 its f is a numpy.ndarray [5. 0.], not a tuple (make it one: "
                                         "tuple(float(x) for x in ...))"),
    ("f = f + (0.0, 1.0)", "at ω = 0 its f has 4 values, not 2: (5.0, 0.0, 0.0, 1.0)"),
    ("return f, f1", "at ω = 0 it returned 2 values, not the 3 of (f, f', f''): ((5.0, 0.0), (-0.0, 5.0))"),
])
def test_a_plugin_curve_of_the_wrong_shape_is_told_what_is_wrong_in_it(fresh, change, said):
    """A numpy array where a tuple is wanted, a vector of the wrong length, a missing f'': the
    message says which value and what it is (it said 'it returned the list [[...]] ((...))' for
    each, with nothing of which one or why: a numpy array of the right 2 numbers was refused as
    if it were none)."""
    name = module(fresh, FAMILY, name="odd", change=change)
    text = refusal(scenario("odd", table={"paths": {"odd": f"{name}:FAMILY"}}))
    assert text == (f'x.toml: vehicle[0] (id "b1").path: plug-in path family "odd" ([plugins.paths] of the scenario: '
                    f"{name}:FAMILY): its eval(ω) must return (f, f', f''), three tuples of 2 numbers; {said}")


@pytest.mark.parametrize("edit, said", [
    (("    def finite(self, state):", "    def is_finite(self, state):"),
     "its plant (a {name}.Point) has no method finite; give it every method of cdus.core.plants.Plant (start, "
     "at_rest, step, velocity, heading, finite)"),
    (("    velocity_level = True\n", ""), "its plant (a {name}.Point) has no velocity_level = True or False; give it "
                                         "one (docs/plugins.md)"),
    (("    velocity_level = True", "    velocity_level = False"),
     "its plant (a {name}.Point) has velocity_level = False, but its PlantModel has no regulator to turn the "
     "guidance's velocity into its input; set velocity_level = True (it takes the velocity itself), or give the "
     "PlantModel a regulator"),
    (("        return state.v\n", "        import numpy; return numpy.array(state.v)\n"),
     "its velocity is a numpy.ndarray [ 0. <numpy's print>], not a tuple (make it one: tuple(float(x) for x in "
     "...))"),
])
def test_a_plugin_plant_missing_a_part_is_told_which(fresh, edit, said):
    """A plant without finite(), without velocity_level, with velocity_level = False and no
    regulator, or a numpy velocity: each named before the run (the first was 'step raised
    AttributeError', the second and third ran silently as a regulated plant with no regulator,
    the fourth was 'its velocity must be 2 finite numbers, got array([0., -5.])')."""
    name = module(fresh, PLANT.replace(*edit), change="pass")
    text = refusal(scenario(plant="part", table={"plants": {"part": f"{name}:MODEL"}}))
    want = (f'x.toml: vehicle[0] (id "b1").plant: plug-in plant "part" ([plugins.plants] of the scenario: '
            f'{name}:MODEL): ' + said.replace("{name}", name))
    head, _, tail = want.partition(" <numpy's print>")  # the array's numbers as numpy prints them
    assert text.startswith(head) and text.endswith(tail) and len(text) < len(want) + 40, text


def test_a_regulated_plugin_plant_without_point_under_safety_is_told_the_fix(fresh, monkeypatch):
    """[safety] on, a plant with a regulator and no point() (the example's unicycle): said as the
    missing method and the two fixes (it was 'point (its model for the safety filter) raised
    AttributeError: ... no attribute 'point'')."""
    monkeypatch.syspath_prepend(str(EXAMPLE))
    data = scenario(plant="unicycle", table={"plants": {"unicycle": "cdus_plugin_example.unicycle:UNICYCLE"}},
                    safety={"enabled": True})
    assert refusal(data) == (
        'x.toml: vehicle[0] (id "b1").plant: plug-in plant "unicycle" ([plugins.plants] of the scenario: '
        'cdus_plugin_example.unicycle:UNICYCLE): its plant (a cdus_plugin_example.unicycle.Unicycle) has no '
        'point(state, d, limits), which [safety] needs of a plant with a regulator (the dynamic safety filter\'s '
        'model of it, a cdus.core.safety.Point: docs/safety.md, docs/plugins.md); give it one, or run this fleet '
        'without [safety]')


def test_two_doors_giving_one_name_two_objects_are_refused(fresh):
    one = module(fresh, FAMILY, name="twin", change="pass")
    two = module(fresh, FAMILY, name="twin", change="pass")
    assert parse_scenario(scenario("twin", table={"paths": {"twin": f"{one}:FAMILY"}}))
    text = refusal(scenario("twin", table={"paths": {"twin": f"{two}:FAMILY"}}))
    assert 'registered already; give one of them another name' in text and f"{one}:FAMILY" in text


# --------------------------------------------------------------------------- at run time


@pytest.mark.parametrize("change, said", [
    ("if t > 1.0: return State((math.inf, 0.0), tuple(u), t)", "its state is no longer finite after a step"),
    ("if t > 1.0: raise RuntimeError('motor controller lost')", "step raised RuntimeError: motor controller lost"),
])
def test_a_plugin_plant_that_fails_in_the_run_is_a_diverged_vehicle_naming_it(fresh, change, said):
    """Past the probe (one control period), the plant fails at t = 1 s (in the tick from 0.9 s): the run stops with
    DivergedError naming the vehicle and the plug-in, never a hang."""
    name = module(fresh, PLANT, change=change)
    sc = parse_scenario(scenario(plant="late", table={"plants": {"late": f"{name}:MODEL"}}))
    with pytest.raises(DivergedError) as info:
        InProcessFleet(sc).run()
    text = str(info.value)
    assert text.startswith("vehicle b1: its numbers overflowed at t = 0.90 s (the vehicle diverged")
    assert f'plug-in plant "late" ([plugins.plants] of the scenario: {name}:MODEL): {said}' in text


def test_a_sweep_worker_handed_a_resolved_scenario_loads_its_plugins_first(fresh):
    """`cdus sweep` resolves each run on the driver and hands the Scenario to a fresh worker
    process, which had read no scenario and so knew no plug-in: every run of a plug-in's
    scenario failed ('unknown path family', for an installed package and a [plugins] table
    alike). Here the registries are put back as such a worker has them."""
    from cdus.app.sweepworker import run_task
    fam, plant = module(fresh, FAMILY, name="hoop", change="pass"), module(fresh, PLANT, change="pass")
    sc = parse_scenario(scenario("hoop", "point", table={"paths": {"hoop": f"{fam}:FAMILY"},
                                                         "plants": {"point": f"{plant}:MODEL"}}))
    for table, key in ((REGISTRY, "hoop"), (PLANTS, "point"), (plugins.LOADED, ("paths", "hoop")),
                       (plugins.LOADED, ("plants", "point"))):
        del table[key]
    row = run_task(sc, "inproc")
    assert (row["status"], row["reason"]) == ("ok", ""), row
    assert row["final_path_error_max"] == InProcessFleet(sc).run().metrics.final_path_error_max


def test_a_plugin_plant_runs_as_the_built_in_ideal_one_to_the_bit(fresh):
    """The wrapper adds nothing to the numbers: a point mass stepped q + h u, exact when its input
    is held (one step a period), is the ideal plant."""
    name = module(fresh, PLANT.replace("exact_when_held = False", "exact_when_held = True"), change="pass")
    mine = InProcessFleet(parse_scenario(scenario(plant="point", table={"plants": {"point": f"{name}:MODEL"}}))).run()
    ideal = InProcessFleet(parse_scenario(scenario())).run()
    for field in ("q", "omega", "path_error"):
        assert (mine.recorder.view(field) == ideal.recorder.view(field)).all(), field


# --------------------------------------------------------------------------- any table


VALUE = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
                     lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner,
                                                                                 max_size=3), max_leaves=8)
REF = st.builds(lambda m, sep, o: f"nosuchmodule_{m}{sep}{o}", st.text("abc_.", max_size=5),
                st.sampled_from([":", "", "::", ": "]), st.text("AB.:", max_size=4))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(table=VALUE | st.dictionaries(st.sampled_from(["paths", "plants", "other"]),
                                     VALUE | st.dictionaries(st.text(max_size=10), REF | VALUE, max_size=3),
                                     max_size=3))
def test_any_plugins_table_is_refused_by_name_never_raises(fresh, table):
    """Whatever [plugins] holds (no module of these names exists): problems naming a field under
    plugins, nothing registered, no exception."""
    before = dict(REGISTRY), dict(PLANTS)
    p = Problems()
    plugins.plugins_section(p, table)
    assert (dict(REGISTRY), dict(PLANTS)) == before
    assert all(field.startswith("plugins") for field, _ in p.items)
    if isinstance(table, dict) and any(isinstance(v, dict) and v for k, v in table.items() if k != "other"):
        assert p, table


@pytest.mark.parametrize("change, said", [
    ("if -50 < w < -2.0: raise ZeroDivisionError('the curve ends')",
     "f(ω) at ω = -2.00231 raised ZeroDivisionError: the curve ends"),
    ("if -50 < w < -2.0: raise SystemExit(0)", "f(ω) at ω = -2.00231 raised SystemExit: 0"),  # `cdus sim` exited 0
    ("if -50 < w < -2.0: return None", "its eval(ω) must return (f, f', f''), three tuples of 2 numbers; at ω = "
                                       "-2.00231 it returned a NoneType, not the 3 of (f, f', f''): None"),  # was a TypeError traceback
    ("if -50 < w < -2.0: f = ('a', 'b')", "its values are not finite numbers at ω = -2.00231"),
    ("if -50 < w < -2.0: f = f + (0.0,) * 5", "its eval(ω) must return (f, f', f''), three tuples of 2 numbers"),
    ("if -50 < w < -2.0: f = (1e300, 1e300)", "its values at ω = -2.00231 are beyond what a vehicle can follow "
                                              "(f within ±1e+06 m, f' and f'' within ±1e+18): (1e+300, 1e+300)"),
])
def test_a_plugin_family_that_raises_in_the_run_is_a_diverged_vehicle_naming_it(fresh, change, said):
    """Its curve goes wrong for ω in (-50, -2), which the probe's ω miss (what the probe checks is
    checked at every ω of the run): it raises, exits, returns no values, text, too many or too large
    ones; the boat reaches ω = -2 after about 2 s and the run stops there, naming the vehicle, the
    plug-in and the ω."""
    name = module(fresh, FAMILY, name="later", change=change)
    sc = parse_scenario(scenario("later", table={"paths": {"later": f"{name}:FAMILY"}}))
    with pytest.raises(DivergedError) as info:
        InProcessFleet(sc).run()
    text = str(info.value)
    assert text.startswith("vehicle b1: its numbers overflowed at t = 2.00 s")
    assert f'plug-in path family "later" ([plugins.paths] of the scenario: {name}:FAMILY): {said}' in text


@pytest.mark.parametrize("change, said", [
    ("if t > 1.0: raise SystemExit(3)", "step raised SystemExit: 3"),  # `cdus sim` exited 3 saying nothing
    ("if t > 1.0: return State(state.q * 2, tuple(u), t)", "after a step of 0.005 s its state's q is not a tuple of "
                                                          "2 numbers"),
    ("if t > 1.0: return State((1e300, 0.0), tuple(u), t)",
     "after a step of 0.005 s its state's q is beyond ±1e+06 m"),
])
def test_a_plugin_plant_exiting_or_leaving_its_shape_in_the_run_is_a_diverged_vehicle_naming_it(fresh, change, said):
    name = module(fresh, PLANT, change=change)
    sc = parse_scenario(scenario(plant="late", table={"plants": {"late": f"{name}:MODEL"}}))
    with pytest.raises(DivergedError) as info:
        InProcessFleet(sc).run()
    assert f'plug-in plant "late" ([plugins.plants] of the scenario: {name}:MODEL): {said}' in str(info.value)


def test_a_plugin_exiting_while_probed_is_refused_by_name_before_the_run(fresh):
    name = module(fresh, FAMILY, name="quits", change="raise SystemExit(0)")
    text = refusal(scenario("quits", table={"paths": {"quits": f"{name}:FAMILY"}}))
    assert f'([plugins.paths] of the scenario: {name}:FAMILY): f(ω) at ω = 0 raised SystemExit: 0' in text


def test_a_plugin_plant_asked_for_its_preset_limits_is_refused_by_name(fresh, monkeypatch):
    """A plug-in plant has no preset: `limits = { preset = true }` is a problem of the config
    (it was a ValueError traceback from cdus.core.limits)."""
    monkeypatch.syspath_prepend(str(EXAMPLE))
    data = scenario(plant="unicycle", table={"plants": {"unicycle": "cdus_plugin_example.unicycle:UNICYCLE"}})
    data["vehicle"][0]["limits"] = {"preset": True}
    assert refusal(data) == ('x.toml: vehicle[0] (id "b1").limits.preset: plant "unicycle" has no preset limits; '
                             'give the limits themselves, e.g. limits = { speed = 2.0 }')


def test_a_plugin_curve_of_four_dimensions_is_refused_naming_it(fresh):
    name = module(fresh, FAMILY.replace("    dim = 2\n", "    dim = 4\n"), name="hyper", change="pass")
    text = refusal(scenario("hyper", table={"paths": {"hyper": f"{name}:FAMILY"}}))
    assert text == (f'x.toml: vehicle[0] (id "b1").path: plug-in path family "hyper" ([plugins.paths] of the '
                    f"scenario: {name}:FAMILY): its curve's dim is 4, not 2 or 3")


class _Returns:
    """A plug-in curve whose eval returns whatever it is given (or raises it)."""

    dim, period, direction = 2, None, -1.0

    def __init__(self, value):
        self.value = value

    def eval(self, w):
        if isinstance(self.value, BaseException):
            raise self.value
        return self.value


NUMBER = st.floats(allow_nan=True, allow_infinity=True) | st.integers() | st.booleans() | st.none() | st.text(max_size=2)
VECTOR = st.tuples(NUMBER, NUMBER) | st.lists(NUMBER, max_size=3) | st.tuples(NUMBER, NUMBER, NUMBER) | NUMBER


@settings(max_examples=200, deadline=None)
@given(value=st.tuples(VECTOR, VECTOR, VECTOR) | st.lists(VECTOR, max_size=4) | VECTOR |
       st.sampled_from([ValueError("x"), RuntimeError("y"), ZeroDivisionError("z"), KeyError("k")]))
def test_any_value_a_plugin_curve_returns_is_a_problem_naming_it_never_an_exception(value):
    """What a plug-in's eval gives (any shape, NaN, a bool, text) or raises: the probe says what
    is wrong, naming the plug-in, and raises nothing."""
    origin = plugins.Origin("paths", "odd", "odd:FAMILY", "[plugins.paths] of the scenario")
    problem = plugins.path_problem(plugins.PluginPath(_Returns(value), origin), 2)
    assert problem is not None and problem.startswith(f"{origin}: "), problem
