"""The gains the discrete controller can take at its rate (cdus.core.gain_bounds), shown on
real runs: just inside each bound a short in-process run stays finite, just outside the
scenario is refused with the field named (the divergence itself is measured in the module
docstring and checked for k on the ideal plant here)."""

import math

import pytest

from cdus.core.gain_bounds import (
    c_bound, gains_problem_for_rate, k_bound, regulator_bound, regulator_gains_problem,
)
from cdus.core.vehicle import DivergedError
from cdus.scenario.config import ConfigError, load_scenario
from cdus.sim.fleet import InProcessFleet

CONFIGS = __import__("pathlib").Path(__file__).resolve().parents[2] / "configs"
LAKE = CONFIGS / "lake_circle.toml"
DYNAMIC = CONFIGS / "lake_circle_dynamic.toml"


def run(config, overrides, duration=4.0):
    sc = load_scenario(config, {"scenario.duration": duration, **overrides})
    result = InProcessFleet(sc).run()
    return max(v.path_error() for v in result.vehicles), [v.omega for v in result.vehicles]


# --------------------------------------------------------------------------- the pure bounds


def test_the_bounds():
    assert k_bound("ideal", 50.0, 200.0) == 100.0  # k T < 2 at the control rate
    assert k_bound("usv_3dof", 50.0, 200.0) == 400.0  # at the physics rate
    assert k_bound("uav_double_integrator", 50.0, 200.0) == 400.0
    assert c_bound(50.0, 2.0) == 25.0 and c_bound(50.0, 0.0) == math.inf
    assert regulator_bound(200.0) == 400.0


def test_gains_problem_for_rate_names_the_gain_and_the_limit():
    assert gains_problem_for_rate(1.5, 2.0, 50.0, weight_sum=2.0) is None
    assert gains_problem_for_rate([99.0, 1.0], 24.9, 50.0, weight_sum=2.0) is None
    msg = gains_problem_for_rate(1e300, None, 50.0)
    assert "k = 1e+300 is too large for the control rate of 50 Hz" in msg and "k < 2 × 50 = 100" in msg
    assert "k = 100" in gains_problem_for_rate([1.0, 100.0], None, 50.0)
    msg = gains_problem_for_rate(None, 25.0, 50.0, weight_sum=2.0)
    assert "c = 25 is too large" in msg and "c < rate / Σa_ik = 25" in msg
    assert "physics rate of 200 Hz" in gains_problem_for_rate(400.0, None, 50.0, plant="usv_3dof", physics_hz=200.0)
    assert gains_problem_for_rate(399.0, None, 50.0, plant="usv_3dof", physics_hz=200.0) is None
    assert gains_problem_for_rate(math.inf, math.nan, 50.0, weight_sum=1.0) == "k must be finite; c must be finite"
    assert regulator_gains_problem((("b", 399.0),), 200.0) is None
    assert "b = 400 is too large for the physics rate of 200 Hz" in regulator_gains_problem((("b", 400.0),), 200.0)


# --------------------------------------------------------------------------- the bounds on real runs


def test_k_just_inside_the_ideal_bound_runs_and_just_outside_diverges_and_is_refused():
    phi, omegas = run(LAKE, {"gains.k": 99.0})
    assert phi < 1.0 and all(math.isfinite(w) for w in omegas)
    with pytest.raises(ConfigError) as e:
        load_scenario(LAKE, {"gains.k": 101.0})
    assert 'vehicle[0] (id "usv1").gains.k: k = 101 is too large for the control rate of 50 Hz' in str(e.value)
    assert "(set in [gains])" in str(e.value)
    # the refusal is right: the same run with the check taken out diverges
    import cdus.scenario.vehicles as vehicles
    saved = vehicles.gains_problem_for_rate
    try:
        vehicles.gains_problem_for_rate = lambda *a, **k: None
        phi, _ = run(LAKE, {"gains.k": 101.0}, duration=20.0)
    finally:
        vehicles.gains_problem_for_rate = saved
    assert phi > 1e6


def test_k_at_a_lower_control_rate_is_bounded_lower():
    run(LAKE, {"rates.control": 10.0, "gains.k": 19.0})
    with pytest.raises(ConfigError, match=r"gains\.k: k = 21 is too large for the control rate of 10 Hz"):
        load_scenario(LAKE, {"rates.control": 10.0, "gains.k": 21.0})


def test_dynamic_plants_are_bounded_by_the_physics_rate():
    phi, omegas = run(DYNAMIC, {"gains.k": 396.0}, duration=2.0)
    assert math.isfinite(phi) and all(math.isfinite(w) for w in omegas)
    with pytest.raises(ConfigError, match="too large for the physics rate of 200 Hz"):
        load_scenario(DYNAMIC, {"gains.k": 404.0})


def test_c_just_inside_the_bound_runs_under_every_policy_and_just_outside_is_refused():
    for policy in ("hold", "extrapolate"):
        phi, omegas = run(LAKE, {"gains.c": 24.9, "link.policy": policy})
        assert phi < 20.0 and max(omegas) - min(omegas) < 10.0, policy  # finite, not diverging
    with pytest.raises(ConfigError) as e:
        load_scenario(LAKE, {"gains.c": 25.1})
    assert ".gains.c: c = 25.1 is too large for the control rate of 50 Hz with edge weights summing to 2" in str(e.value)


def test_the_reported_1e300_gain_is_refused_with_its_field():
    with pytest.raises(ConfigError) as e:
        load_scenario(LAKE, {"vehicle.usv2.gains.k": 1e300})
    assert 'vehicle[1] (id "usv2").gains.k: k = 1e+300 is too large' in str(e.value)
    assert "(set in" not in str(e.value)  # the vehicle's own value


def test_regulator_gains_are_bounded_by_the_physics_rate():
    with pytest.raises(ConfigError, match=r"regulator_gains: b_u = 400 is too large for the physics rate of 200 Hz"):
        load_scenario(DYNAMIC, {"vehicle.usv1.regulator_gains": {"b_u": 400.0}})
    load_scenario(DYNAMIC, {"vehicle.usv1.regulator_gains": {"b_u": 399.0}})


def test_every_shipped_config_is_within_the_bounds():
    for config in sorted(CONFIGS.glob("*.toml")):
        load_scenario(config)


def test_a_diverging_dynamic_vehicle_raises_rather_than_running_on():
    """What the bound prevents: past it, a dynamic plant's state stops being finite."""
    import cdus.scenario.vehicles as vehicles
    saved = vehicles.gains_problem_for_rate
    try:
        vehicles.gains_problem_for_rate = lambda *a, **k: None
        with pytest.raises(DivergedError):
            run(DYNAMIC, {"gains.k": 404.0}, duration=3.0)
    finally:
        vehicles.gains_problem_for_rate = saved


def test_c_is_unbounded_without_edges_and_bounded_by_a_fractional_weight_sum():
    from cdus.core.gain_bounds import C_LIMIT, c_bound, gains_problem_for_rate
    assert gains_problem_for_rate(None, 1e6, 50.0) is None  # no weight sum given: a vehicle that listens to nobody
    assert c_bound(50.0, 0.5) == C_LIMIT * 50.0 / 0.5
    assert gains_problem_for_rate(None, C_LIMIT * 50.0 / 0.5 * 1.01, 50.0, weight_sum=0.5) is not None
