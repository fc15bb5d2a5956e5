import math

import pytest
from hypothesis import given, settings, strategies as st

from cdus.core.graph import build_pairs, inconsistent_cycle, reachable_from, suggest_phases, unreachable

IDS = ["a", "b", "c", "d"]


def test_undirected_ring_listens_both_ways_cyclically():
    assert build_pairs("ring", IDS, directed=False) == [
        ("a", "b"), ("a", "d"), ("b", "a"), ("b", "c"), ("c", "b"), ("c", "d"), ("d", "a"), ("d", "c"),
    ]


def test_directed_ring_listens_to_the_previous_vehicle():
    assert build_pairs("ring", IDS, directed=True) == [("a", "d"), ("b", "a"), ("c", "b"), ("d", "c")]


def test_ring_of_two_is_one_undirected_pair():
    assert build_pairs("ring", ["a", "b"], directed=False) == [("a", "b"), ("b", "a")]
    assert build_pairs("ring", ["a", "b"], directed=True) == [("a", "b"), ("b", "a")]


def test_ring_needs_two_vehicles():
    with pytest.raises(ValueError, match="at least 2"):
        build_pairs("ring", ["a"], directed=False)


def test_chain_directed_has_the_first_vehicle_as_leader():
    assert build_pairs("chain", IDS, directed=True) == [("b", "a"), ("c", "b"), ("d", "c")]
    assert build_pairs("chain", IDS, directed=False) == [
        ("a", "b"), ("b", "a"), ("b", "c"), ("c", "b"), ("c", "d"), ("d", "c"),
    ]


def test_complete_has_every_ordered_pair():
    pairs = build_pairs("complete", IDS, directed=False)
    assert len(pairs) == 12 and ("d", "a") in pairs and all(i != k for i, k in pairs)
    assert build_pairs("complete", IDS, directed=True) == pairs


def test_star_listens_to_the_hub():
    assert build_pairs("star", IDS, directed=True) == [("b", "a"), ("c", "a"), ("d", "a")]
    assert build_pairs("star", IDS, directed=True, hub="c") == [("a", "c"), ("b", "c"), ("d", "c")]
    assert build_pairs("star", IDS, directed=False, hub="c") == [
        ("a", "c"), ("b", "c"), ("c", "a"), ("c", "b"), ("c", "d"), ("d", "c"),
    ]


def test_explicit_pairs_are_deduplicated_and_mirrored_when_undirected():
    assert build_pairs("explicit", IDS, directed=True, explicit=[("b", "a"), ("b", "a"), ("c", "a")]) == [
        ("b", "a"), ("c", "a"),
    ]
    assert build_pairs("explicit", IDS, directed=False, explicit=[("b", "a")]) == [("a", "b"), ("b", "a")]


@pytest.mark.parametrize("kwargs, fragment", [
    (dict(topology="mesh"), "unknown topology"),
    (dict(topology="star", hub="z"), "hub"),
    (dict(topology="explicit", explicit=[("a", "a")]), "self-loop"),
    (dict(topology="explicit", explicit=[("a", "z")]), "not in"),
])
def test_build_pairs_rejects_bad_input(kwargs, fragment):
    with pytest.raises(ValueError, match=fragment):
        build_pairs(ids=IDS, directed=True, **kwargs)


def test_every_named_topology_has_a_spanning_tree():
    for topology in ("ring", "chain", "complete", "star"):
        for directed in (False, True):
            assert unreachable(IDS, build_pairs(topology, IDS, directed)) == []


def test_reachable_follows_information_from_k_to_i():
    assert reachable_from("a", [("b", "a"), ("c", "b")]) == {"a", "b", "c"}
    assert reachable_from("c", [("b", "a"), ("c", "b")]) == {"c"}


def test_reversed_directed_chain_has_no_spanning_tree_from_the_middle():
    # b listens to both ends: a reaches {a, b}, c reaches {c, b}; nobody reaches everyone
    pairs = [("b", "a"), ("b", "c")]
    assert unreachable(["a", "b", "c"], pairs) == ["c"]


def test_split_ring_reports_the_vehicles_outside_the_largest_component():
    ids = ["a", "b", "c", "d", "e"]
    pairs = build_pairs("explicit", ids, directed=False, explicit=[("a", "b"), ("b", "c"), ("d", "e")])
    assert unreachable(ids, pairs) == ["d", "e"]


def test_single_vehicle_is_its_own_spanning_tree():
    assert unreachable(["a"], []) == []


SIX = [f"v{j}" for j in range(1, 7)]


def test_paper_six_ring_with_two_thirds_pi_per_edge_is_inconsistent():
    edges = [(SIX[j], SIX[(j + 1) % 6], 2 * math.pi / 3) for j in range(6)]
    cycle, total = inconsistent_cycle(SIX, edges)
    assert cycle == SIX + ["v1"]
    assert total == pytest.approx(4 * math.pi)


def test_cycle_is_found_with_both_directions_of_each_pair_given():
    edges = []
    for j in range(6):
        i, k = SIX[j], SIX[(j + 1) % 6]
        edges += [(i, k, 2 * math.pi / 3), (k, i, -2 * math.pi / 3)]
    cycle, total = inconsistent_cycle(SIX, edges)
    assert cycle == SIX + ["v1"] and total == pytest.approx(4 * math.pi)


def test_consistent_offsets_from_phases_pass():
    theta = {v: 2 * math.pi * j / 6 for j, v in enumerate(SIX)}
    edges = [(i, k, theta[i] - theta[k]) for i in SIX for k in SIX if i != k]
    assert inconsistent_cycle(SIX, edges) is None


def test_two_opposite_deltas_on_one_pair_form_a_two_cycle():
    cycle, total = inconsistent_cycle(["a", "b"], [("a", "b", 1.0), ("b", "a", 0.5)])
    assert cycle == ["a", "b", "a"] and total == pytest.approx(1.5)


def test_inconsistency_in_a_second_component_is_found():
    edges = [("a", "b", 1.0), ("c", "d", 1.0), ("d", "e", 1.0), ("e", "c", 1.0)]
    cycle, total = inconsistent_cycle(["a", "b", "c", "d", "e"], edges)
    assert cycle == ["c", "d", "e", "c"] and total == pytest.approx(3.0)


def test_tolerance_accepts_rounding_of_large_values():
    big = 1e6 * math.pi
    edges = [("a", "b", big / 3), ("b", "c", big / 3), ("a", "c", 2 * big / 3)]
    assert inconsistent_cycle(["a", "b", "c"], edges) is None


def test_suggest_phases_propagates_along_a_bfs_tree():
    edges = [("a", "b", 1.0), ("c", "b", 0.5), ("d", "c", -2.0)]
    assert suggest_phases(["a", "b", "c", "d"], edges) == {"a": 0.0, "b": -1.0, "c": -0.5, "d": -2.5}


def test_suggest_phases_reproduces_consistent_offsets():
    theta = {"a": 0.0, "b": 1.0, "c": 3.0}
    edges = [("b", "a", 1.0), ("c", "b", 2.0), ("c", "a", 3.0)]
    assert suggest_phases(["a", "b", "c"], edges) == pytest.approx(theta)


@pytest.mark.parametrize("ids", [["a", "b", "c", "far"], ["far", "a", "b", "c"]])
def test_a_huge_offset_elsewhere_does_not_hide_a_cycle_that_does_not_close(ids):
    """The tolerance was 1e-9 of the largest value in the whole graph (and, before that, of the
    potentials at the edge's ends, ~1e8 when the first vehicle is the far one): a leaf 1e8 away
    let the cycle a -> b -> c miss closing by 0.05."""
    edges = [("a", "b", 0.0), ("b", "c", 0.0), ("c", "a", 0.05), ("far", "a", 1e8)]
    cycle, total = inconsistent_cycle(ids, edges)
    assert cycle == ["a", "b", "c", "a"] and total == pytest.approx(0.05)


def test_a_consistent_ring_through_a_huge_phase_passes_its_rounding():
    theta = [0.0, 0.0, 0.0, 0.0, 0.0968, 16777217.0]  # 2^24 + 1: residual 4e-9 on an edge near 0
    edges = [(SIX[j], SIX[(j + 1) % 6], theta[j] - theta[(j + 1) % 6]) for j in range(6)]
    assert inconsistent_cycle(SIX, edges) is None
    assert inconsistent_cycle(SIX[::-1], edges) is None


@settings(max_examples=80, deadline=None)
@given(theta=st.lists(st.floats(-1e9, 1e9), min_size=6, max_size=6), root=st.integers(0, 5),
       miss=st.floats(1e-3, 1.0))
def test_offsets_from_phases_close_and_a_miss_on_a_small_cycle_is_found(theta, root, miss):
    """Any phases within ±1e9 give offsets that close (the rounding of the sums is tolerated),
    around whichever vehicle the check starts; three vehicles near 0 whose Δs miss closing are
    found, however large the phases of the others."""
    th = dict(zip(SIX, theta))
    ids = SIX[root:] + SIX[:root]
    edges = [(i, k, th[i] - th[k]) for i in SIX for k in SIX if i < k]
    assert inconsistent_cycle(ids, edges) is None
    small = ["s1", "s2", "s3"]
    edges += [("s1", "s2", 0.0), ("s2", "s3", 0.0), ("s3", "s1", miss), ("s1", SIX[root], -th[SIX[root]])]
    found = inconsistent_cycle(ids + small, edges)
    assert found is not None and found[1] == pytest.approx(miss), found


def test_the_cycle_tolerance_is_1e_9_of_its_largest_delta_and_no_looser():
    """docs: a cycle closes within 1e-9 · max(1, its largest |Δ|). Offsets taken from phases
    ~2.5e8 apart miss closing by 3e-8 in float (rounding): they close. At small values a miss of
    1.5e-9 is a miss, 0.5e-9 is not (mutation testing: a tolerance divided instead of
    multiplied, or max(2, ...), went unseen)."""
    b, c = 252754923.8953228, -151013804.44788435
    rounded = [("a", "b", 0.0 - b), ("b", "c", b - c), ("c", "a", c - 0.0)]
    assert sum(d for _, _, d in rounded) != 0.0 and inconsistent_cycle(["a", "b", "c"], rounded) is None
    small = lambda miss: [("a", "b", 0.5), ("b", "c", 0.25), ("c", "a", -0.75 + miss)]  # noqa: E731
    assert inconsistent_cycle(["a", "b", "c"], small(0.5e-9)) is None
    cycle, total = inconsistent_cycle(["a", "b", "c"], small(1.5e-9))
    assert cycle == ["a", "b", "c", "a"] and total == pytest.approx(1.5e-9, rel=1e-6)


def test_a_pair_given_both_ways_is_a_two_vehicle_cycle_read_as_written():
    """Δ_ab + Δ_ba around a -> b -> a, whichever order the edges or the ids come in."""
    for ids, edges in [(["a", "b"], [("a", "b", 1.0), ("b", "a", 0.5)]), (["a", "b"], [("b", "a", 0.5), ("a", "b", 1.0)]),
                       (["b", "a"], [("a", "b", 1.0), ("b", "a", 0.5)]),
                       (["a", "b", "c"], [("a", "b", 1.0), ("b", "a", 0.5), ("b", "c", 2.0)])]:
        cycle, total = inconsistent_cycle(ids, edges)
        assert total == 1.5 and cycle in (["a", "b", "a"], ["b", "a", "b"]) and cycle[0] == ids[0], (ids, edges)
