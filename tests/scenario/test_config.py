"""Reading a scenario file: loading, overrides, and every section put together."""

import copy
import math
import pathlib
import pickle
import re
import tomllib

import pytest

from cdus.core.events import Event
from cdus.core.linkspec import Delay, LinkSpec
from cdus.scenario.paths import make_path
from cdus.scenario.config import (
    ConfigError, Edge, Rates, Scenario, Supervision, VehicleSpec, apply_override, load_scenario, parse_scenario,
    parse_value, parse_text,
)
from tests.scenario.common import MINIMAL, base, check_bad, problems


# --------------------------------------------------------------------------- valid


def test_minimal_file_resolves_to_the_dataclasses_with_defaults(tmp_path):
    f = tmp_path / "two.toml"
    f.write_text(MINIMAL)
    s = load_scenario(f)
    assert isinstance(s, Scenario)
    assert (s.name, s.description, s.source, s.duration, s.seed) == ("two_boats", "", str(f), 60.0, 0)
    assert s.rates == Rates(physics=200.0, control=50.0, broadcast=50.0)
    assert (s.path_tol, s.coord_tol, s.topology, s.directed) == (0.1, 0.05, "ring", False)
    assert s.link == LinkSpec() and s.events == () and s.supervision == Supervision()
    v1, v2 = s.vehicles
    assert v1 == VehicleSpec(
        id="usv1", index=0, kind="usv", dim=2, plant="ideal", epsilon=None, preset=None, regulator=None,
        regulator_gains=(), path=(("center", (0, 0)), ("family", "circle"), ("radius", 10)), phase=0.0,
        start_position=None, start_heading=None, omega0=None, k=(1.5, 1.5), c=2.0, limits=(), disturbance=(),
    )
    assert make_path(dict(v1.path)).period == pytest.approx(2 * math.pi)
    # undirected ring of two: one pair, both directions, Δ from the phases
    assert s.edges == (Edge("usv1", "usv2", 1.0, -1.5), Edge("usv2", "usv1", 1.0, 1.5))
    assert s.neighbours("usv2") == (Edge("usv2", "usv1", 1.0, 1.5),)
    assert s.metric_edges() == (Edge("usv1", "usv2", 1.0, -1.5),)
    assert s.vehicle("usv2") is v2
    with pytest.raises(KeyError, match="usv9"):
        s.vehicle("usv9")
    assert s.raw["vehicle"][1]["phase"] == 1.5
    hash(v1)  # specs are hashable


def test_every_section_resolved_together():
    data = base()
    data["rates"] = {"physics": 400, "control": 100, "broadcast": 20}
    data["metrics"] = {"path_tol": 0.2}
    data["link"] = {"loss": 0.1, "delay": {"base": 0.05}}
    data["event"] = [{"at": 10.0, "action": "kill", "vehicle": "usv1"}]
    data["supervision"] = {"restart": "always"}
    s = parse_scenario(data)
    assert s.rates == Rates(400.0, 100.0, 20.0) and (s.path_tol, s.coord_tol) == (0.2, 0.05)
    assert s.link == LinkSpec(loss=0.1, delay=Delay(base=0.05))
    assert s.events == (Event(10.0, "kill", "usv1"),)
    assert s.supervision == Supervision(restart="always")
    assert len(s.vehicles) == 3 and len(s.edges) == 6


def test_raw_round_trips_to_the_same_scenario():
    data = base()
    data["vehicle"][0]["start"] = {"region_min": [-5, -5], "region_max": [5, 5]}
    data["link"] = {"loss": 0.2, "down": [{"src": "usv1", "from": 1.0}]}
    data["event"] = [{"at": 3.0, "action": "pause", "vehicle": "uav1", "duration": 1.0}]
    s = parse_scenario(data)
    assert parse_scenario(s.raw) == s
    assert "start" not in base()["vehicle"][0]  # input not modified


def test_base_is_valid():
    s = parse_scenario(copy.deepcopy(base()))
    assert [v.id for v in s.vehicles] == ["usv1", "usv2", "uav1"]


def test_the_example_in_the_user_reference_is_valid():
    doc = pathlib.Path(__file__).resolve().parents[2] / "docs" / "config.md"
    example = re.search(r"```toml\n(.*?)```", doc.read_text(), re.S).group(1)
    s = parse_scenario(tomllib.loads(example), "docs/config.md")
    assert [v.id for v in s.vehicles] == ["usv1", "uav1"]
    assert s.rates == Rates(200.0, 50.0, 50.0)
    assert s.vehicle("usv1").regulator == "heading" and s.vehicle("uav1").k == (1.5, 1.5, 3.0)
    assert s.supervision == Supervision(restart="on-failure", max_restarts=3, backoff_s=1.0)


def test_every_shipped_config_is_valid():
    configs = sorted(pathlib.Path(__file__).resolve().parents[2].glob("configs/*.toml"))
    assert configs
    for path in configs:
        assert load_scenario(path).vehicles


# --------------------------------------------------------------------------- overrides


def test_apply_override_sets_dotted_keys_and_creates_tables():
    data = base()
    apply_override(data, "scenario.seed", 4)
    apply_override(data, "rates.control", 20.0)
    apply_override(data, "link.loss", 0.2)
    apply_override(data, "vehicle.usv2.gains.k", [1, 2])
    apply_override(data, "vehicle.uav1.path.radius", 5)
    apply_override(data, "graph.topology", "chain")
    assert data["scenario"]["seed"] == 4 and data["rates"] == {"control": 20.0} and data["link"] == {"loss": 0.2}
    assert data["vehicle"][1]["gains"] == {"k": [1, 2]} and data["vehicle"][2]["path"]["radius"] == 5
    s = parse_scenario(data)
    assert (s.seed, s.rates.control, s.link.loss, s.topology) == (4, 20.0, 0.2, "chain")
    assert s.vehicle("usv2").k == (1.0, 2.0)


def test_overrides_passed_to_load_scenario(tmp_path):
    f = tmp_path / "two.toml"
    f.write_text(MINIMAL)
    s = load_scenario(f, {"scenario.duration": 5.0, "vehicle.usv1.phase": 0.5})
    assert s.duration == 5.0 and s.vehicle("usv1").phase == 0.5
    assert s.raw["scenario"]["duration"] == 5.0


@pytest.mark.parametrize("key, fragment", [
    ("vehicle.usv9.gains.k", '"usv9" is not a vehicle (did you mean "usv2"?); ids are usv1, usv2, uav1'),
    ("vehicle.usv1", "vehicle.<id>.<key>"),
    ("scenario..seed", "not a dotted key"),
    ("scenario.name.x", 'scenario.name is the string "t", not a table, so it has no key "x"'),
])
def test_bad_override(key, fragment):
    with pytest.raises(ConfigError) as info:
        apply_override(base(), key, 1)
    assert fragment in str(info.value)


def test_override_error_names_the_file():
    assert 'x.toml: override vehicle.usv3.phase: "usv3" is not a vehicle' in problems(
        base(), {"vehicle.usv3.phase": 1.0})


@pytest.mark.parametrize("text, value", [
    ("3", 3), ("2.5", 2.5), ("-1e3", -1000.0), ("true", True), ("False", False), ("[1, 2]", [1, 2]),
    ('"x y"', "x y"), ("ring", "ring"), ("{ k = 1 }", {"k": 1}), ("1979-05-27", "1979-05-27"),
])
def test_parse_value(text, value):
    assert parse_value(text) == value and type(parse_value(text)) is type(value)


# --------------------------------------------------------------------------- bad files


@pytest.mark.parametrize("fn, fragment", [
    (lambda d: d.update(vehicles=[]), 'vehicles: unknown section; did you mean "vehicle"?'),
    (lambda d: d.update(link=3), "link: must be a table, e.g. a [link] section"),
    (lambda d: d.update(supervision=[]), "supervision: must be a table, e.g. a [supervision] section, got the "
                                         "list []"),
    (lambda d: d.update(event={"t": 1}), "event: must be an array of tables"),
], ids=["unknown section", "link not a table", "supervision not a table", "event not array"])
def test_bad_top_level_names_the_section(fn, fragment):
    check_bad(fn, fragment)


def test_every_problem_is_reported_at_once():
    data = base()
    data["rates"] = {"control": -1}
    data["scenario"]["duration"] = 0
    data["vehicle"][2]["gains"] = {"k": [1, 2]}
    data["vehicle"][1]["kind"] = "boat"
    data["supervision"] = {"restart": "sometimes"}
    data["link"] = {"loss": -1}
    with pytest.raises(ConfigError) as info:
        parse_scenario(data, "x.toml")
    fields = [f for f, _ in info.value.problems]
    assert fields == ["scenario.duration", "rates.control", "supervision.restart", 'vehicle[1] (id "usv2").kind',
                      'vehicle[2] (id "uav1").gains.k', "link.loss"]
    assert len(str(info.value).splitlines()) == 6


def test_toml_syntax_error_gives_line_and_column(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text('[scenario]\nname = "x\n')
    with pytest.raises(ConfigError) as info:
        load_scenario(f)
    assert str(info.value).startswith(f"{f}: line 2, column ")
    assert "TOML syntax error" in str(info.value)


def test_missing_file():
    with pytest.raises(ConfigError, match="not found"):
        load_scenario("/nonexistent/x.toml")


def test_config_error_survives_pickling():
    try:
        parse_scenario(base() | {"rates": {"control": -1}}, "x.toml")
    except ConfigError as e:
        again = pickle.loads(pickle.dumps(e))
        assert str(again) == str(e) and again.problems == e.problems
    else:
        pytest.fail("no ConfigError")


def test_a_section_override_is_checked_like_the_file():
    assert "x.toml: supervision.max_restarts: must be an integer >= 0" in problems(
        base(), {"supervision.max_restarts": -2})
    assert problems(base(), {"rates.control": -1}).startswith("x.toml: rates.control: must be a number >= 0.001 and <= 100000 Hz, got -1")



def _lap(spec: dict, dim: int | None = None, n: int = 20000) -> tuple[float, float, float]:
    """(lap length, min speed, max speed) at ω̇ = -1, by sampling one period."""
    from cdus.core.paths import for_dimension

    path = make_path(spec)
    path = for_dimension(path, dim) if dim else path
    T = path.period
    speeds = [math.sqrt(sum(x * x for x in path.eval(T * (i + 0.5) / n)[1])) for i in range(n)]
    return sum(speeds) * T / n, min(speeds), max(speeds)


def test_the_path_table_of_the_user_reference_names_every_family_with_its_figures():
    """docs/config.md, "Paths": every family, and the lap lengths and speeds it states."""
    from cdus.core.paths import FAMILIES

    doc = (pathlib.Path(__file__).parents[2] / "docs" / "config.md").read_text()
    table = doc[doc.index("### Paths"):doc.index("**start.**")]
    assert {f for f in FAMILIES if f"| `{f}` |" in table} == set(FAMILIES)
    L, lo, hi = _lap({"family": "self_intersecting"})
    assert (f"{L:.1f}", f"{lo:.2f}", f"{hi:.0f}") == ("88.1", "5.29", "10")
    assert "88.1 m in 3-D" in table and "5.29 to 10 m/s" in table
    L, lo, _ = _lap({"family": "self_intersecting"}, 2)
    assert "86.1 m in x, y" in table and f"{L:.1f}" == "86.1" and f"{lo:.2f}" == "4.99"
    L, lo, hi = _lap({"family": "trefoil", "center": [0, 0, 0]})
    assert (f"{L:.1f}", f"{lo:.2f}", f"{hi:.2f}") == ("28.8", "3.90", "5.83") and "3.90 to 5.83 m/s" in table
    L, _, _ = _lap({"family": "ellipse", "center": [0, 0], "a": 2, "b": 1})
    assert f"{L:.2f}" == "9.69" and "9.69 m for a = 2, b = 1" in table
    assert "refused" in table and "All\nphases 0 always do this" in table


def test_an_integer_of_more_digits_than_python_reads_is_a_config_error_not_a_traceback():
    # tomllib raises ValueError (not a TOMLDecodeError) on an int of over 4,300 digits: a scenario
    # file with `radius = 1000...0` and `--set gains.k=1000...0` were tracebacks
    huge = "1" + "0" * 5000
    with pytest.raises(ConfigError) as info:
        parse_text(f"[gains]\nk = {huge}\n".encode(), "x.toml")
    assert "file" in str(info.value) and "cannot read" in str(info.value)
    assert parse_value(huge) == huge  # kept as text, then refused by the field as not a number
