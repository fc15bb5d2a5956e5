"""The small sections: [scenario], [rates], [metrics], [gains], [supervision]."""

from __future__ import annotations

import pytest

from cdus.scenario.checks import Problems
from cdus.scenario.config import parse_scenario
from cdus.scenario.model import MAX_BACKOFF_S, RESTART_POLICIES, Rates, Supervision
from cdus.scenario.sections import (
    gains_section, metrics_section, rates_section, scenario_section, supervision_section,
)
from tests.scenario.common import base, check_bad, drop, edit, section


def test_defaults_of_every_small_section():
    p = Problems()
    header = scenario_section(p, {"name": "x"})
    assert (header.name, header.description, header.duration, header.seed) == ("x", "", 60.0, 0)
    assert rates_section(p, {}) == Rates(physics=200.0, control=50.0, broadcast=50.0)
    assert metrics_section(p, {}) == (0.1, 0.05)
    assert gains_section(p, {"k": [1, 2]}) == {"k": [1, 2]}
    assert supervision_section(p, {}) == Supervision("never", 5, 0.5)
    assert not p


def test_unset_rates_follow_the_control_rate():
    s = parse_scenario(edit(section("rates", control=20)))
    assert s.rates == Rates(physics=200.0, control=20.0, broadcast=20.0)
    s = parse_scenario(edit(section("rates", control=500)))
    assert s.rates == Rates(physics=500.0, control=500.0, broadcast=500.0)


def test_a_bad_rate_is_not_compared_with_the_others():
    p = Problems()
    assert rates_section(p, {"control": -1, "broadcast": 100}) == Rates(200.0, 50.0, 100.0)
    assert [f for f, _ in p] == ["rates.control"]


BAD = {
    "unknown key": (section("scenario", durration=3), 'scenario.durration: unknown key; did you mean "duration"?'),
    "string for number": (section("rates", control="fast"),
                          'rates.control: must be a number >= 0.001 and <= 100000 Hz, got the string "fast"'),
    "bool for number": (section("scenario", duration=True), "scenario.duration: must be a number > 0 and <= 1e+07 s, "
                                                            "got the boolean true"),
    "missing name": (drop("scenario", "name"), "scenario.name: missing"),
    "empty name": (section("scenario", name=" "), 'scenario.name: must be a non-empty string, got the string " "'),
    "description": (section("scenario", description=3), "scenario.description: must be a string, got the number 3"),
    "seed": (section("scenario", seed=-1), "scenario.seed: must be an integer >= 0, got -1"),
    "float seed": (section("scenario", seed=1.5), "scenario.seed: must be an integer >= 0, got the number 1.5"),
    "negative duration": (section("scenario", duration=-5), "scenario.duration: must be a number > 0 and <= "
                                                            "1e+07 s, got -5"),
    "endless duration": (section("scenario", duration=1e308), "scenario.duration: must be a number > 0 and <= "
                                                              "1e+07 s, got 1e+308"),
    "zero rate": (section("rates", broadcast=0), "rates.broadcast: must be a number >= 0.001 and <= 100000 Hz, got 0"),
    "physics < control": (section("rates", physics=100, control=200), "rates.physics: must be >= rates.control "
                                                                       "(200 Hz)"),
    "broadcast > control": (section("rates", broadcast=100), "rates.broadcast: must be <= rates.control (50 Hz)"),
    "broadcast > given control": (section("rates", control=20, broadcast=50), "rates.broadcast: must be <= "
                                                                               "rates.control (20 Hz)"),
    "rates not a table": (lambda d: d.update(rates=5), "rates: must be a table, e.g. a [rates] section, got the "
                                                       "number 5"),
    "zero tolerance": (section("metrics", coord_tol=0.0), "metrics.coord_tol: must be a number > 0 and <= 1e+09 rad, got 0.0"),
    "tolerance key": (section("metrics", path_tolerance=1), 'metrics.path_tolerance: unknown key; did you mean '
                                                            '"path_tol"?'),
    "zero k": (section("gains", k=0), "gains.k: must be a number > 0, got 0"),
    "string k": (section("gains", k="x"), 'gains.k: must be a number > 0 (or a list of per-axis numbers), got '
                                          'the string "x"'),
    "empty k": (section("gains", k=[]), "gains.k: must be a number > 0 or a list of per-axis numbers > 0, got []"),
    "k element": (section("gains", k=[1, -1]), "gains.k[1]: must be a number > 0, got -1"),
    "gains key": (section("gains", kk=1), 'gains.kk: unknown key; did you mean "k"?'),
    "restart": (section("supervision", restart="on_failure"),
                'supervision.restart: unknown restart policy "on_failure" (did you mean "on-failure"?); choose one '
                "of never, on-failure, always"),
    "max_restarts": (section("supervision", max_restarts=-1),
                     "supervision.max_restarts: must be an integer >= 0 (restarts of one vehicle's process), got -1"),
    "max_restarts float": (section("supervision", max_restarts=2.0),
                           "supervision.max_restarts: must be an integer >= 0 (restarts of one vehicle's process), "
                           "got the number 2.0"),
    "backoff": (section("supervision", backoff_s=0),
                "supervision.backoff_s: must be a number > 0 and <= 3600 s (the wait before a vehicle's first restart), got 0"),
    "supervision key": (section("supervision", backoff=1), 'supervision.backoff: unknown key; did you mean '
                                                           '"backoff_s"?'),
}


@pytest.mark.parametrize("name", list(BAD))
def test_bad_section_names_the_field_and_what_is_valid(name):
    check_bad(*BAD[name])


# --------------------------------------------------------------------------- [supervision]


def test_supervision_is_read_from_the_file():
    s = parse_scenario(base())
    assert s.supervision == Supervision() == Supervision("never", 5, 0.5)
    data = base()
    data["supervision"] = {"restart": "on-failure", "max_restarts": 0, "backoff_s": 2}
    s = parse_scenario(data)
    assert s.supervision == Supervision(restart="on-failure", max_restarts=0, backoff_s=2.0)
    assert isinstance(s.supervision.backoff_s, float)
    assert parse_scenario(s.raw) == s
    for policy in RESTART_POLICIES:
        assert parse_scenario(base(), overrides={"supervision.restart": policy}).supervision.restart == policy


def test_backoff_doubles_per_restart_and_is_capped():
    sv = Supervision(backoff_s=0.5)
    assert [sv.backoff(n) for n in range(5)] == [0.5, 1.0, 2.0, 4.0, 8.0]
    assert sv.backoff(6) == 30.0 == MAX_BACKOFF_S and sv.backoff(100) == 30.0
    assert Supervision(backoff_s=45.0).backoff(0) == 30.0


# --------------------------------------------------------------------------- [guidance]


def test_guidance_scaling_of_omega_is_off_unless_asked_for():
    assert not any(v.scale_omega for v in parse_scenario(base()).vehicles)
    data = base()
    data["guidance"] = {"scale_omega": True}
    s = parse_scenario(data)
    assert all(v.scale_omega for v in s.vehicles) and parse_scenario(s.raw) == s


@pytest.mark.parametrize("table, fragment", [
    ({"scale_omega": 1}, "guidance.scale_omega"),
    ({"scale_omga": True}, 'did you mean "scale_omega"?'),
])
def test_a_bad_guidance_table_names_the_field(table, fragment):
    check_bad(lambda d: d.__setitem__("guidance", table), fragment)


def test_path_tol_defaults_by_plant_and_a_given_one_wins():
    from cdus.scenario.config import parse_scenario
    from tests.scenario.common import base

    assert parse_scenario(base()).path_tol == 0.1  # ideal boats and drones
    data = base()
    data["vehicle"][0]["plant"] = "usv_3dof"
    assert parse_scenario(data).path_tol == 0.15  # a usv_3dof boat (preset cybership2)
    data["vehicle"][0]["epsilon"] = [-0.465, 1.310, 0.0388, -0.181, 0.362, -0.503, -0.763]
    assert parse_scenario(data).path_tol == 0.15  # its own epsilon: cybership2's figure
    data["metrics"] = {"path_tol": 0.05}
    assert parse_scenario(data).path_tol == 0.05
    assert parse_scenario(base(), overrides={"metrics.path_tol": 0.3}).path_tol == 0.3
