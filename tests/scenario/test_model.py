"""The validated Scenario: its lookups, its edges, and what it carries for the runners."""

from __future__ import annotations

import pytest

from cdus.core.linkspec import LinkSpec
from cdus.scenario.config import parse_scenario
from cdus.scenario.model import Edge, Scenario, Supervision
from tests.scenario.common import base


def test_lookups_by_id():
    s = parse_scenario(base())
    assert s.ids == ("usv1", "usv2", "uav1")
    assert s.vehicle("uav1") is s.vehicles[2] and s.vehicle("uav1").index == 2
    with pytest.raises(KeyError, match="usv9.*ids are usv1, usv2, uav1"):
        s.vehicle("usv9")


def test_neighbours_and_metric_edges_of_an_undirected_ring():
    s = parse_scenario(base())
    assert s.neighbours("usv1") == (Edge("usv1", "usv2", 1.0, 0.0), Edge("usv1", "uav1", 1.0, 0.0))
    assert [(e.i, e.k) for e in s.metric_edges()] == [("usv1", "usv2"), ("usv1", "uav1"), ("usv2", "uav1")]
    data = base()
    data["graph"] = {"topology": "chain", "directed": True}
    d = parse_scenario(data)
    assert d.metric_edges() == d.edges == (Edge("usv2", "usv1", 1.0, 0.0), Edge("uav1", "usv2", 1.0, 0.0))


def test_the_link_seed_is_the_scenarios_unless_the_link_sets_one():
    data = base()
    data["scenario"]["seed"] = 9
    s = parse_scenario(data)
    assert (s.link, s.link_seed) == (LinkSpec(), 9)
    data["link"] = {"seed": 0}
    assert parse_scenario(data).link_seed == 0


def test_link_table_is_a_copy():
    data = base()
    data["link"] = {"loss": 0.1}
    s = parse_scenario(data)
    s.link_table["loss"] = 0.9
    assert s.raw["link"] == {"loss": 0.1}


def test_scenarios_are_frozen():
    s = parse_scenario(base())
    assert isinstance(s, Scenario) and isinstance(s.supervision, Supervision)
    with pytest.raises(AttributeError):
        s.seed = 3  # type: ignore[misc]
