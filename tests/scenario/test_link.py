"""The [link] section: a raw table checked against the vehicle ids into a LinkSpec (docs/link.md)."""

from __future__ import annotations

import math
import tomllib

import pytest

from cdus.core.linkspec import Burst, Delay, Down, LinkSpec, Override
from cdus.scenario.checks import Problems
from cdus.scenario.config import ConfigError, parse_scenario
from cdus.scenario.link import link_section, validate_link
from tests.scenario.common import MINIMAL, base, problems

IDS = ("usv1", "usv2", "usv3", "uav1", "uav2", "uav3")


def spec(table):
    return validate_link(table, IDS, "test.toml")


def test_the_full_example_table_is_valid():
    s = spec({
        "policy": "timeout", "timeout": 1.5, "seed": 7,
        "delay": {"base": 0.1, "jitter": 0.02, "distribution": "uniform", "reorder": True},
        "loss": 0.3, "burst": {"p": 0.05, "r": 0.5, "bad_loss": 1.0, "good_loss": 0.0}, "duplicate": 0.0,
        "override": [{"src": "usv1", "dst": "*", "loss": 0.5}],
        "down": [{"src": "usv1", "dst": "usv2", "from": 30.0, "to": 40.0}],
        "partition": [{"from": 60.0, "to": 90.0, "groups": [["usv1", "usv2", "usv3"], ["uav1", "uav2", "uav3"]]},
                      {"from": 90.0, "to": 100.0, "drops": {"usv2": ["usv1"], "uav1": ["usv3", "uav3"]}}],
    })
    assert (s.policy, s.timeout, s.seed, s.loss) == ("timeout", 1.5, 7, 0.3)
    assert s.burst == Burst(0.05, 0.5, 1.0, 0.0) and s.delay == Delay(0.1, 0.02, "uniform", True)
    assert s.partitions[1].drops == (("usv2", ("usv1",)), ("uav1", ("usv3", "uav3")))
    assert not s.is_ideal
    assert spec({}) == LinkSpec() and LinkSpec().is_ideal


BAD = [
    ({"los": 0.3}, "link.los", 'unknown key; did you mean "loss"?'),
    ({"loss": 1.5}, "link.loss", "must be a probability in [0, 1] (Bernoulli loss), got 1.5"),
    ({"loss": True}, "link.loss", "must be a probability in [0, 1] (Bernoulli loss), got the boolean true"),
    ({"policy": "hodl"}, "link.policy", 'unknown stale-neighbour policy "hodl" (did you mean "hold"?); '
                                        "choose one of hold, timeout, extrapolate"),
    ({"timeout": 0}, "link.timeout", "must be a number > 0 and <= 1e+09 (s a neighbour may stay silent under policy timeout), got 0"),
    ({"timeout": float("inf")}, "link.timeout", "must be a finite number > 0"),
    ({"seed": -1}, "link.seed", "must be an integer >= 0"),
    ({"seed": 1.5}, "link.seed", "must be an integer >= 0"),
    ({"delay": {"jitter": -0.01}}, "link.delay.jitter", "must be a number >= 0"),
    ({"delay": {"base": "100ms"}}, "link.delay.base", 'got the string "100ms"'),
    ({"delay": {"distribution": "gauss"}}, "link.delay.distribution", "choose one of uniform, normal, pareto"),
    ({"delay": {"reorder": 1}}, "link.delay.reorder", "must be true"),
    ({"delay": 0.1}, "link.delay", "must be a table, e.g. { base = 0.1"),
    ({"delay": {"bsae": 0.1}}, "link.delay.bsae", 'did you mean "base"?'),
    ({"burst": {"p": 0.1}}, "link.burst.r", "missing; a burst needs p"),
    ({"burst": {"p": 0.1, "r": -0.2}}, "link.burst.r", "must be a probability in [0, 1] (P(bad -> good)"),
    ({"burst": {"p": 0.1, "r": 0.2, "h": 0.5}}, "link.burst.h", "valid keys here: p, r, bad_loss, good_loss"),
    ({"duplicate": float("nan")}, "link.duplicate", "must be a probability in [0, 1]"),
    ({"override": [{"src": "usv11", "loss": 0.1}]}, "link.override[0].src",
     '"usv11" is not a vehicle (did you mean "usv1"?); ids are usv1, usv2, usv3, uav1, uav2, uav3 or "*"'),
    ({"override": [{"src": "usv1"}]}, "link.override[0]", "sets nothing"),
    ({"override": {"src": "usv1", "loss": 0.1}}, "link.override", "must be an array of tables ([[link.override]]"),
    ({"override": [{"dst": "uav1", "delay": {"base": -1}}]}, "link.override[0].delay.base", "must be a number >= 0"),
    ({"down": [{"src": "usv1", "from": 40.0, "to": 30.0}]}, "link.down[0].to", "must be > from (40.0)"),
    ({"down": [{"src": "usv1", "from": 30.0, "to": 30.0}]}, "link.down[0].to", "the window is [from, to)"),
    ({"down": [{"dst": 3, "from": 1.0, "to": 2.0}]}, "link.down[0].dst", "must be a vehicle id or \"*\""),
    ({"down": [{"from": -1.0, "to": 2.0}]}, "link.down[0].from", "must be a number >= 0"),
    ({"down": [{"start": 1.0, "to": 2.0}]}, "link.down[0].start", "valid keys here: src, dst, from, to"),
    ({"partition": [{"from": 1.0, "to": 2.0, "groups": [["usv1", "usv2"], ["usv2", "uav1"]]}]},
     "link.partition[0].groups", 'vehicle "usv2" is in groups 0 and 1; a vehicle belongs to one group at most'),
    ({"partition": [{"from": 1.0, "to": 2.0, "groups": [["usv1", "usv1"]]}]},
     "link.partition[0].groups", 'vehicle "usv1" is twice in this group'),
    ({"partition": [{"from": 1.0, "to": 2.0, "groups": ["usv1", "usv2"]}]},
     "link.partition[0].groups", "must be a non-empty list of non-empty lists of vehicle ids"),
    ({"partition": [{}, {"from": 1.0, "to": 2.0, "groups": [["uav7"]]}]}, "link.partition[1].groups[0]",
     '"uav7" is not a vehicle'),
    ({"partition": [{"from": 1.0, "to": 2.0}]}, "link.partition[0]", "missing; give groups"),
    ({"partition": [{"groups": [["usv1"]], "drops": {"usv2": ["usv1"]}}]}, "link.partition[0]",
     "give either groups or drops, not both"),
    ({"partition": [{"drops": {"usv2": ["usv2"]}}]}, "link.partition[0].drops.usv2",
     '"usv2" cannot drop its own messages'),
    ({"partition": [{"drops": {"usv2": "usv1"}}]}, "link.partition[0].drops.usv2",
     "must be a non-empty list of the vehicle ids"),
    ({"partition": [{"drops": {"usb2": ["usv1"]}}]}, "link.partition[0].drops.usb2",
     '"usb2" is not a vehicle (did you mean "usv2"?)'),
]


@pytest.mark.parametrize("table, field, fragment", BAD, ids=[b[1] + "-" + str(i) for i, b in enumerate(BAD)])
def test_bad_link_tables_name_the_field_and_what_is_valid(table, field, fragment):
    with pytest.raises(ConfigError) as err:
        validate_link(table, IDS, "bad.toml")
    assert err.value.source == "bad.toml"
    matches = [m for f, m in err.value.problems if f == field]
    assert matches, err.value.problems
    assert any(fragment in m for m in matches), matches
    assert f"bad.toml: {field}: " in str(err.value)


def test_every_problem_is_reported_at_once():
    with pytest.raises(ConfigError) as err:
        validate_link({"loss": -1, "duplicate": 2, "delay": {"jitter": -1}, "policy": "x"}, IDS, "bad.toml")
    assert [f for f, _ in err.value.problems] == ["link.policy", "link.delay.jitter", "link.loss", "link.duplicate"]


def test_a_non_table_link_is_an_error():
    with pytest.raises(ConfigError, match="link: must be a table"):
        validate_link([1, 2], IDS, "bad.toml")


def test_windows_and_overrides_default_to_any_vehicle_and_forever():
    s = spec({"down": [{"from": 5.0}], "override": [{"loss": 0.5}]})
    assert s.down == (Down(5.0, math.inf, "*", "*"),)
    assert s.overrides == (Override(loss=0.5),)


def test_without_the_ids_only_the_types_of_references_are_checked():
    p = Problems()
    s = link_section(p, {"down": [{"src": "anyone", "from": 1.0, "to": 2.0}]}, None)
    assert not p and s.down == (Down(1.0, 2.0, "anyone", "*"),)
    link_section(p, {"down": [{"src": 3}]}, None)
    assert [f for f, _ in p] == ["link.down[0].src"]


def test_the_scenario_carries_the_validated_spec_and_the_table_as_written():
    data = base()
    data["link"] = {"loss": 0.1, "delay": {"base": 0.05}, "seed": 3}
    s = parse_scenario(data)
    assert s.link == LinkSpec(loss=0.1, delay=Delay(base=0.05), seed=3)
    assert s.link_table == {"loss": 0.1, "delay": {"base": 0.05}, "seed": 3} == s.raw["link"]
    assert s.link_seed == 3
    assert parse_scenario(base()).link == LinkSpec() and parse_scenario(base()).link_table == {}


def test_link_problems_are_reported_even_when_a_vehicle_id_is_bad():
    data = base()
    data["vehicle"][0]["id"] = 7
    data["link"] = {"loss": 2.0, "down": [{"src": "nobody"}]}
    message = problems(data)
    assert "link.loss: must be a probability" in message and "vehicle[0].id" in message
    assert "nobody" not in message  # the ids are not known, so references are not judged


@pytest.mark.parametrize("link, fragment", [
    ({"loss": 2.0}, "link.loss: must be a probability"),
    ({"partition": [{"from": 5.0, "to": 1.0, "groups": [["usv1"], ["usv2"]]}]}, "link.partition[0].to: must be > from"),
    ({"override": [{"src": "usv3", "loss": 0.1}]}, 'link.override[0].src: "usv3" is not a vehicle'),
])
def test_link_table_is_checked_with_the_scenarios_vehicle_ids(link, fragment):
    data = tomllib.loads(MINIMAL)
    data["link"] = link
    with pytest.raises(ConfigError) as e:
        parse_scenario(data)
    assert fragment in str(e.value)
