"""[safety], [disturbance], [observer] and limits preset = true: defaults, values, errors."""

import pytest

from cdus.core.limits import default_limits
from cdus.scenario.config import parse_scenario
from cdus.scenario.model import Safety

from .common import base, problems


def test_defaults_leave_everything_off():
    sc = parse_scenario(base())
    assert sc.safety == Safety() and not sc.safety.enabled
    assert all(v.observer is None and v.disturbance == () for v in sc.vehicles)


def test_safety_values_and_the_tick_schedule():
    data = base()
    data["safety"] = {"enabled": True, "radius": 3, "gamma": 0.5, "range": 15.0, "rate": 5.0, "latency": 0.05}
    sf = parse_scenario(data).safety
    assert (sf.enabled, sf.radius, sf.gamma, sf.range, sf.rate) == (True, 3.0, 0.5, 15.0, 5.0)
    assert sf.every(50.0) == 10 and sf.latency_ticks(50.0) == 3
    assert Safety(latency=0.0).latency_ticks(50.0) == 1  # never the tick it was sampled at


@pytest.mark.parametrize("table, text", [
    ({"enabled": "yes"}, 'safety.enabled: must be true (on) or false (off), got the string "yes"'),
    ({"radius": 0}, "safety.radius: must be a number > 0 and <= 1e+06 m, got 0"),
    ({"rate": -1}, "safety.rate: must be a number >= 0.001 and <= 100000 Hz, got -1"),
    ({"latency": -0.1}, "safety.latency: must be a number >= 0 and <= 1e+09 s"),
    ({"range": 1.0}, "safety.range: must be above safety.radius (2 m)"),
    ({"sidestep": 1.5}, "safety.sidestep: must be below 1"),
    ({"radus": 1.0}, 'safety.radus: unknown key; did you mean "radius"?'),
])
def test_bad_safety_names_the_field_and_the_fix(table, text):
    data = base()
    data["safety"] = table
    assert text in problems(data)


@pytest.mark.parametrize("table, text", [
    # both were accepted: a latency past the run left the filter silently off (0 interventions,
    # 1.218 m with R = 2 m in crossing_dynamic), a rate below 1 / duration steered by t = 0's positions
    ({"enabled": True, "latency": 1e9}, "safety.latency: must be below scenario.duration (100 s)"),
    ({"enabled": True, "rate": 0.01}, "safety.rate: must be above 1 / scenario.duration (0.01 Hz)"),
])
def test_a_sensor_slower_than_the_run_is_an_error(table, text):
    data = base()
    data["scenario"]["duration"] = 100.0
    data["safety"] = table
    assert text in problems(data)
    data["safety"] = {**table, "enabled": False}  # no filter, no sensor: nothing to say
    assert parse_scenario(data).safety.enabled is False


def test_fleet_disturbance_goes_to_its_kind_unless_a_vehicle_sets_its_own():
    data = base()
    data["disturbance"] = {"current": {"constant": [0.3, 0.1], "gust": 0.05},
                           "wind": {"constant": [1.0, 0.5, 0.0]}}
    data["observer"] = {"enabled": True, "bandwidth": 3.0}
    data["vehicle"][1]["disturbance"] = {"constant": [0.0, 0.2]}
    usv1, usv2, uav1 = parse_scenario(data).vehicles
    assert dict(usv1.disturbance) == {"constant": (0.3, 0.1), "gust": 0.05}
    assert dict(usv2.disturbance) == {"constant": (0.0, 0.2)}
    assert dict(uav1.disturbance) == {"constant": (1.0, 0.5, 0.0)}
    assert usv1.observer == usv2.observer == uav1.observer == 3.0


@pytest.mark.parametrize("section, table, text", [
    ("disturbance", {"current": {"constant": [0.3, 0.1, 0.0]}},
     "disturbance.current.constant: must be a list of 2 numbers >= -1000 and <= 1000 (the current on every usv in m/s"),
    ("disturbance", {"wind": {"gust": -1}}, "disturbance.wind.gust: must be a number >= 0 and <= 1000 m/s"),
    ("disturbance", {"breeze": {}}, "disturbance.breeze: unknown key"),
    ("observer", {"bandwidth": 0}, "observer.bandwidth: must be a number > 0 and <= 1e+06 rad/s"),
    ("observer", {"enabled": 1}, "observer.enabled: must be true"),
])
def test_bad_disturbance_and_observer(section, table, text):
    data = base()
    data[section] = table
    assert text in problems(data)


def test_limits_preset_starts_from_the_plant_preset():
    data = base()
    data["vehicle"][0].update(plant="usv_3dof", limits={"preset": True, "speed": 1.5})
    data["vehicle"][2].update(plant="uav_double_integrator", limits={"preset": True})
    usv1, _, uav1 = parse_scenario(data).vehicles
    want = default_limits("usv_3dof")
    assert dict(usv1.limits) == {"speed": 1.5, "tau_u": want.tau_u, "tau_r": want.tau_r, "yaw_rate": want.yaw_rate}
    assert dict(uav1.limits) == {"speed": 12.0, "accel": 6.0}
    data["vehicle"][0]["limits"] = {"preset": "yes"}
    assert "vehicle[0] (id \"usv1\").limits.preset: must be true" in problems(data)


def test_a_huge_gamma_is_refused_naming_its_bound():
    data = base()
    data["safety"] = {"enabled": True, "gamma": 1e300}
    assert "safety.gamma: must be a number > 0 and <= 1000 1/s, got 1e+300" in problems(data)
