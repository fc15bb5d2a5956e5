"""Building the core's pieces from a validated scenario."""

from __future__ import annotations

import math

import pytest

from cdus.core.link import IdealLink, LinkEmulator
from cdus.core.linkspec import LinkSpec
from cdus.core.metrics import MetricEdge
from cdus.core.neighbours import NeighbourLink
from cdus.core.plants import PointState, UAVState, USVState
from cdus.scenario.config import load_scenario, parse_scenario
from cdus.sim.build import build_vehicle, link_emulator_for, link_model_for, links_of, metric_edges

TWO = {
    "scenario": {"name": "t"},
    "vehicle": [
        {"id": "usv0", "kind": "usv", "phase": 0.5, "path": {"family": "circle", "center": [0, 0], "radius": 10}},
        {"id": "uav0", "kind": "uav", "path": {"family": "circle", "center": [0, 0, 20], "radius": 10}},
    ],
    "graph": {"topology": "chain", "directed": True},
}


def test_metric_edges_name_and_index_the_listening_pairs():
    sc = parse_scenario(TWO)
    assert metric_edges(sc) == (MetricEdge(1, 0, -0.5, "uav0__usv0"),)


def test_links_of_lists_whom_a_vehicle_listens_to():
    sc = parse_scenario(TWO)
    assert links_of(sc, "uav0") == (NeighbourLink(0, 1.0, -0.5),)
    assert links_of(sc, "usv0") == ()


def test_a_vehicle_starts_on_its_path_at_its_phase():
    sc = parse_scenario(TWO)
    v = build_vehicle(sc.vehicles[0], sc.rates, sc.seed)
    assert isinstance(v.state, PointState)
    assert v.omega == 0.5
    assert v.q == pytest.approx((10 * math.cos(0.5), 10 * math.sin(0.5)))
    assert v.path_error() == pytest.approx(0.0, abs=1e-12)


def test_vehicle_models_get_their_plant_state():
    sc = load_scenario("configs/lake_circle_dynamic.toml")
    kinds = {type(build_vehicle(v, sc.rates, sc.seed).state) for v in sc.vehicles}
    assert kinds == {USVState, UAVState}


def with_link(link: dict, seed: int = 11):
    return parse_scenario({**TWO, "scenario": {"name": "t", "seed": seed}, "link": link})


def test_the_link_model_is_ideal_without_faults_and_an_emulator_with_the_right_seed():
    assert isinstance(link_model_for(parse_scenario(TWO)), IdealLink)
    assert isinstance(link_model_for(with_link({"policy": "timeout", "timeout": 2.0, "seed": 4})), IdealLink)
    assert isinstance(link_model_for(with_link({"loss": 0.0, "override": [{"src": "usv0", "loss": 0.0}]})), IdealLink)
    assert isinstance(link_model_for(with_link({"delay": {"reorder": False}})), IdealLink)
    m = link_model_for(with_link({"loss": 0.4}))
    assert isinstance(m, LinkEmulator) and m.seed == 11
    twin = LinkEmulator(LinkSpec(loss=0.4), ("usv0", "uav0"), 11)
    assert [m.decide(0, 1, s, s * 0.02) for s in range(300)] == [twin.decide(0, 1, s, s * 0.02) for s in range(300)]
    assert link_model_for(with_link({"loss": 0.4, "seed": 0})).seed == 0
    assert isinstance(link_model_for(with_link({"partition": [{"groups": [["usv0"]]}]})), LinkEmulator)


def test_the_emulator_is_built_from_the_scenarios_validated_spec():
    sc = with_link({"loss": 0.3, "down": [{"src": "usv0", "from": 1.0, "to": 2.0}]}, seed=5)
    e = link_emulator_for(sc)
    assert isinstance(e, LinkEmulator) and e.seed == 5
    assert isinstance(link_emulator_for(parse_scenario(TWO)), LinkEmulator)  # ideal too: faults can come later
