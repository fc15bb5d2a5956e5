"""The [graph] section: listening pairs, weights, offsets, and the errors that say what to change."""

from __future__ import annotations

import math

import pytest

from cdus.scenario.config import Edge, parse_scenario
from tests.scenario.common import base, check_bad, edit, problems, section


def test_graph_edges_refine_weights_and_deltas_and_mirror_them_when_undirected():
    data = base()
    data["graph"] = {"weight": 2.0, "edge": [{"i": "usv2", "k": "usv1", "weight": 0.5, "delta": 1.0},
                                             {"i": "usv2", "k": "uav1", "delta": -1.0},
                                             {"i": "uav1", "k": "usv1", "delta": 2.0}]}
    s = parse_scenario(data)
    edges = {(e.i, e.k): (e.weight, e.delta) for e in s.edges}
    assert edges == {("usv1", "usv2"): (0.5, -1.0), ("usv1", "uav1"): (2.0, -2.0),
                     ("usv2", "usv1"): (0.5, 1.0), ("usv2", "uav1"): (2.0, -1.0),
                     ("uav1", "usv1"): (2.0, 2.0), ("uav1", "usv2"): (2.0, 1.0)}
    assert [(e.i, e.k) for e in s.metric_edges()] == [("usv1", "usv2"), ("usv1", "uav1"), ("usv2", "uav1")]


def test_deltas_default_to_the_phase_differences():
    data = base()
    for v, phase in zip(data["vehicle"], (0.0, 1.0, 3.0)):
        v["phase"] = phase
    s = parse_scenario(data)
    assert {(e.i, e.k): e.delta for e in s.edges}[("usv2", "uav1")] == -2.0


def test_explicit_directed_graph():
    data = base()
    data["graph"] = {"topology": "explicit", "directed": True, "edges": [["usv2", "usv1"]],
                     "edge": [{"i": "uav1", "k": "usv2", "delta": 0.5}]}
    s = parse_scenario(data)
    assert s.edges == (Edge("usv2", "usv1", 1.0, 0.0), Edge("uav1", "usv2", 1.0, 0.5))
    assert s.metric_edges() == s.edges
    assert s.neighbours("usv1") == ()


def test_star_hub_and_single_vehicle_without_graph():
    data = base()
    data["graph"] = {"topology": "star", "directed": True, "hub": "uav1"}
    assert [(e.i, e.k) for e in parse_scenario(data).edges] == [("usv1", "uav1"), ("usv2", "uav1")]
    data = base()
    data["vehicle"] = data["vehicle"][:1]
    assert parse_scenario(data).edges == ()


def test_paper_phases_pass():
    data = base()
    for j, v in enumerate(data["vehicle"]):
        v["phase"] = 2 * math.pi * j / 3
    assert len(parse_scenario(data).edges) == 6


def ring6_deltas(d):
    d["vehicle"] = [{"id": f"v{j}", "kind": "usv" if j % 2 else "uav",
                     "path": {"family": "circle", "center": [-40, 50, 20], "radius": 10}} for j in range(1, 7)]
    d["graph"] = {"edge": [{"i": f"v{j}", "k": f"v{j % 6 + 1}", "delta": 2 * math.pi / 3} for j in range(1, 7)]}


def ring3_deltas(d):
    d["graph"] = {"edge": [{"i": "usv1", "k": "usv2", "delta": 0.5}, {"i": "usv2", "k": "uav1", "delta": 0.25},
                           {"i": "uav1", "k": "usv1", "delta": 0.25}]}


BAD = {
    "unknown key": (section("graph", topolgy="ring"), 'graph.topolgy: unknown key; did you mean "topology"?'),
    "unknown topology": (section("graph", topology="rign"), 'graph.topology: unknown topology "rign" (did you mean '
                                                            '"ring"?); choose one of ring, chain, complete, star, '
                                                            "explicit"),
    "directed": (section("graph", directed="yes"), 'graph.directed: must be true or false, got the string "yes"'),
    "weight": (section("graph", weight=0), "graph.weight: must be a number > 0 and <= 1e+06 (a_ik), got 0"),
    "unknown vehicle in graph": (section("graph", topology="explicit", edges=[["usv1", "usv9"]]),
                                 'graph.edges[0]: "usv9" is not a vehicle'),
    "edges not pairs": (section("graph", topology="explicit", edges=[["usv1"]]),
                        "graph.edges[0]: must be a pair [i, k] of vehicle ids (i listens to k), got the list "
                        '["usv1"]'),
    "edges not a list": (section("graph", topology="explicit", edges="usv1"), "graph.edges: must be a list of [i, k] "
                                                                             "pairs"),
    "self loop pair": (section("graph", topology="explicit", edges=[["usv1", "usv1"]]),
                       'graph.edges[0]: self-loop ["usv1", "usv1"]'),
    "self loop": (section("graph", edge=[{"i": "usv1", "k": "usv1"}]), "graph.edge[0]: self-loop"),
    "edge id type": (section("graph", edge=[{"i": 1, "k": "usv1"}]), "graph.edge[0].i: must be a vehicle id, got "
                                                                     "the number 1"),
    "edge missing k": (section("graph", edge=[{"i": "usv1"}]), "graph.edge[0].k: missing; a [[graph.edge]] names"),
    "edge not tables": (section("graph", edge={"i": "usv1"}), "graph.edge: must be an array of tables "
                                                              "([[graph.edge]] sections with i, k, weight, delta)"),
    "hub": (section("graph", topology="star", hub="uav2"), 'graph.hub: "uav2" is not a vehicle'),
    "hub without star": (section("graph", hub="uav1"), 'graph.hub: only used with topology = "star"'),
    "edges without explicit": (section("graph", edges=[["usv1", "usv2"]]),
                               'graph.edges: only used with topology = "explicit" (topology is "ring")'),
    "edge not in topology": (section("graph", topology="chain", directed=True, edge=[{"i": "usv1", "k": "usv2"}]),
                             "graph.edge[0]: usv1 does not listen to usv2 in this directed chain"),
    "edge twice undirected": (section("graph", edge=[{"i": "usv1", "k": "usv2"}, {"i": "usv2", "k": "usv1"}]),
                              "graph.edge[1]: the pair usv2 - usv1 is already set by graph.edge[0]"),
    "not connected": (section("graph", topology="explicit", edges=[["usv1", "usv2"]]),
                      'graph: the graph is not connected: uav1 cannot exchange ω with usv1, usv2; add an edge such '
                      'as ["uav1", "usv1"]'),
    "reversed star": (section("graph", topology="explicit", directed=True, edges=[["usv1", "usv2"], ["usv1", "uav1"]]),
                      "no directed spanning tree: uav1 never hears (even indirectly) from usv2"),
    "inconsistent deltas": (ring3_deltas, "around the cycle usv1 -> usv2 -> uav1 -> usv1 the deltas sum to 1, not 0"),
    "paper 6-ring": (ring6_deltas, "the deltas sum to 12.5664 (4π), not 0"),
    "ring of one": (lambda d: d.update(vehicle=d["vehicle"][:1], graph={"topology": "ring"}),
                    "a ring needs at least 2 vehicles"),
}


@pytest.mark.parametrize("name", list(BAD))
def test_bad_graph_names_the_field_and_what_is_valid(name):
    check_bad(*BAD[name])


def test_paper_six_ring_with_two_thirds_pi_deltas_is_rejected_with_the_cycle_and_phases():
    message = problems(edit(ring6_deltas))
    assert message.count("\n") == 0
    assert ("graph.edge: inconsistent formation offsets: around the cycle "
            "v1 -> v2 -> v3 -> v4 -> v5 -> v6 -> v1") in message
    assert "the sum is 2 × 2π, 2 laps of the path: the formation cannot close" in message
    assert 'vehicle "v1" phase = 0.0, vehicle "v2" phase = 4.18879' in message


@pytest.mark.parametrize("first", [False, True])
def test_a_huge_phase_on_a_leaf_does_not_hide_deltas_that_do_not_close(first):
    """A vehicle at phase 1e8 listening to usv1 only made the cycle check's tolerance 0.1 for the
    whole graph: deltas missing closing by 0.05 around usv1 -> usv2 -> uav1 were taken."""
    def fn(d):
        far = {"id": "far", "kind": "usv", "phase": 1e8, "path": {"family": "circle", "center": [0, 0], "radius": 10}}
        d["vehicle"] = [far, *d["vehicle"]] if first else [*d["vehicle"], far]
        d["graph"] = {"topology": "explicit", "edges": [["usv1", "usv2"], ["usv2", "uav1"], ["uav1", "usv1"],
                                                        ["far", "usv1"]],
                      "edge": [{"i": "usv1", "k": "usv2", "delta": 0.5}, {"i": "usv2", "k": "uav1", "delta": -0.25},
                               {"i": "uav1", "k": "usv1", "delta": -0.2}]}
    check_bad(fn, "around the cycle usv1 -> usv2 -> uav1 -> usv1 the deltas sum to 0.05, not 0")


def test_reversed_directed_chain_suggests_the_direction():
    # uav1 leads (usv2 and usv1 hear it): a valid tree
    parse_scenario(edit(section("graph", topology="explicit", directed=True,
                                edges=[["usv1", "usv2"], ["usv2", "uav1"], ["usv1", "uav1"]])))
    message = problems(edit(section("graph", topology="explicit", directed=True,
                                    edges=[["usv1", "usv2"], ["usv1", "uav1"]])))
    assert 'add a pair such as ["uav1", "usv2"]' in message
    assert "reverse the pairs: written the other way round they form a tree led by usv1" in message


def test_references_are_not_checked_while_a_vehicle_id_is_bad():
    data = edit(section("graph", topology="star", hub="nobody"))
    data["vehicle"][0]["id"] = "bad id"
    assert "graph.hub" not in problems(data)
