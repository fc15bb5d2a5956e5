"""The vehicle models' registry (cdus.core.models), the stale-neighbour policies' (cdus.core.policies),
and the plant objects' invariants under bounded inputs (cdus.core.plants)."""

import math

import pytest
from hypothesis import given, settings, strategies as st

from cdus.core import models
from cdus.core.limits import default_limits
from cdus.core.models import PLANTS, PlantModel, UnknownName, plant_model, register_plant
from cdus.core.plants import USV_PRESETS, DoubleIntegrator, IdealPlant, USV3DOF
from cdus.core.policies import POLICIES, make_policy
from cdus.core.regulators import PD, Heading, HeadingGains, Paper, PaperGains, UAVGains
from cdus.scenario import vehicles

EPS = USV_PRESETS["cybership2"]


# --------------------------------------------------------------------------- the registries


@pytest.mark.parametrize("name", ["usv3dof", "", 3, None])
def test_an_unknown_plant_is_refused_naming_the_field_and_the_known_names(name):
    with pytest.raises(UnknownName) as err:
        plant_model(name)
    msg = str(err.value)
    assert msg.startswith("plant: unknown plant")
    assert "ideal, usv_3dof, uav_double_integrator" in msg
    assert err.value.field == "plant" and err.value.known == tuple(PLANTS)


def test_an_unknown_regulator_is_refused_naming_the_plant_and_its_regulators():
    with pytest.raises(UnknownName, match=r"^regulator: unknown regulator of plant 'usv_3dof' 'pd'; "
                                          r"known: heading, paper$"):
        models.build("usv_3dof", "pd", {}, {})


@pytest.mark.parametrize("name", ["hodl", "Timeout", 1])
def test_an_unknown_policy_is_refused_naming_the_field_and_the_known_names(name):
    with pytest.raises(UnknownName, match=r"^policy: unknown stale-neighbour policy .*; known: hold, timeout, "
                                          r"extrapolate$"):
        make_policy(name)


def test_each_name_builds_the_objects_it_names():
    plant, regulator = models.build("ideal", None, {}, {})
    assert isinstance(plant, IdealPlant) and regulator is None
    plant, regulator = models.build("uav_double_integrator", None, {}, {"b": 2.0})
    assert isinstance(plant, DoubleIntegrator) and regulator == PD(UAVGains(b=2.0))
    plant, regulator = models.build("usv_3dof", None, {"preset": "cybership2"}, {})
    assert plant == USV3DOF(EPS) and regulator == Heading(EPS, HeadingGains())  # heading: the default
    given = (-1.0, 1.0, 0.5, -0.5, 0.5, -0.5, -0.5)
    plant, regulator = models.build("usv_3dof", "paper", {"epsilon": given}, {"b2": 4.0})
    assert plant.eps == given and regulator == Paper(given, PaperGains(b2=4.0))
    assert [make_policy(p, 2.0).name for p in POLICIES] == list(POLICIES)


def test_the_scenarios_vocabulary_is_the_registrys():
    assert vehicles.PLANTS == {name: m.kinds for name, m in PLANTS.items()}
    assert vehicles.REGULATORS == {"usv_3dof": {"heading": ("b_u", "b_r", "k_psi"), "paper": ("b1", "b2", "b3")},
                                   "uav_double_integrator": {"pd": ("b",)}}


def test_register_plant_adds_a_name_and_refuses_one_taken(monkeypatch):
    monkeypatch.setattr(models, "PLANTS", dict(PLANTS))
    mine = PlantModel(("usv",), lambda params: IdealPlant())
    register_plant("my_boat", mine)
    assert models.plant_model("my_boat") is mine
    with pytest.raises(ValueError, match="'ideal' is already a plant"):
        register_plant("ideal", mine)
    with pytest.raises(ValueError, match="non-empty string"):
        register_plant("", mine)


# --------------------------------------------------------------------------- the plants under bounded inputs

H = st.sampled_from([0.002, 0.01, 0.02])
SPAN = st.floats(-1.0, 1.0)  # an input as a fraction of its limit


@settings(max_examples=60, deadline=None)
@given(u=st.lists(st.tuples(SPAN, SPAN, SPAN), min_size=1, max_size=8), d=st.tuples(SPAN, SPAN, SPAN), h=H)
def test_the_ideal_plant_flies_its_command_plus_the_disturbance(u, d, h):
    plant = IdealPlant()
    state = plant.start((1.0, -2.0, 3.0), 0.0)
    q0, t, bound = state.q, 0.0, 0.0
    for cmd in u:
        for _ in range(20):
            state = plant.step(state, cmd, d, h)
            t += h
        assert plant.velocity(state) == tuple(a + b for a, b in zip(cmd, d))
        bound = max(bound, math.hypot(*cmd) + math.hypot(*d))
    assert plant.finite(state)
    # plus the rounding of adding small steps to a position of order 1 (an ulp of 3 is 4.4e-16 a step)
    assert math.dist(state.q, q0) <= bound * t * (1 + 1e-9) + 1e-12


@settings(max_examples=60, deadline=None)
@given(u=st.lists(st.tuples(SPAN, SPAN, SPAN), min_size=1, max_size=8), h=H)
def test_the_double_integrator_gains_speed_at_most_at_its_acceleration_limit(u, h):
    plant, accel = DoubleIntegrator(), default_limits("uav_double_integrator").accel
    state = plant.start((0.0, 0.0, 10.0), 0.0)
    t = 0.0
    for frac in u:
        n = math.hypot(*frac)
        tau = tuple(accel * x / max(1.0, n) for x in frac)  # |τ| <= accel
        for _ in range(50):
            state = plant.step(state, tau, (0.0, 0.0, 0.0), h)
            t += h
        assert plant.finite(state)
        assert math.hypot(*plant.velocity(state)) <= accel * t * (1 + 1e-9)


@settings(max_examples=60, deadline=None)
@given(u=st.lists(st.tuples(SPAN, SPAN), min_size=1, max_size=10), h=H, psi=st.floats(-math.pi, math.pi))
def test_the_usv_keeps_its_yaw_rate_and_speed_within_what_its_input_limits_allow(u, h, psi):
    """From rest with |τ_u| <= tau_u, |τ_r| <= tau_r (the preset's limits): ṙ = ε4 r + ε5 τ_r keeps
    |r| <= ε5 tau_r / |ε4|; V = u² + b v² with b = -ε2/ε7 (the Coriolis terms cancel) has
    V̇/2 = ε1 u² + b ε6 v² + ε3 u τ_u, so V <= U² (1 + ε1/ε6), U = ε3 tau_u / |ε1|: the speed
    stays below sqrt(V (1 + 1/b)). Heun's step adds O(h²): 1 % is allowed."""
    plant, lim = USV3DOF(EPS), default_limits("usv_3dof", "cybership2")
    e1, e2, e3, e4, e5, e6, e7 = EPS
    r_max = e5 * lim.tau_r / -e4
    b = -e2 / e7
    big_u = e3 * lim.tau_u / -e1
    speed_max = math.sqrt(big_u ** 2 * (1 + e1 / e6) * (1 + 1 / b))
    state = plant.start((0.0, 0.0), psi)
    for fu, fr in u:
        for _ in range(100):
            state = plant.step(state, (fu * lim.tau_u, fr * lim.tau_r), (0.0, 0.0), h)
            assert plant.finite(state)
            assert abs(state.r) <= r_max * 1.01
            assert math.hypot(*plant.velocity(state)) <= speed_max * 1.01
    assert plant.heading(state) == state.psi
