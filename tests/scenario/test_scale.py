"""Large and hostile fleets: the graph checks stay linear, the fleet and the graph are bounded,
and thousands of mistakes give a readable error (bench/config_scale.py prints the timings)."""

import copy
from collections import deque

from hypothesis import given, settings, strategies as st
import pytest

from cdus.core import graph as graphs
from cdus.scenario import checks, graph as graph_module, vehicles as vehicles_module
from cdus.scenario.checks import IdList, Problems
from cdus.scenario.config import ConfigError, parse_scenario
from tests.scenario.common import base


def fleet(n: int, graph: dict | None = None) -> dict:
    v = {"kind": "usv", "path": {"family": "circle", "center": [0, 0], "radius": 10}}
    return {"scenario": {"name": "big"}, "graph": graph or {"topology": "ring"},
            "vehicle": [{**copy.deepcopy(v), "id": f"v{j}", "phase": 0.001 * j} for j in range(n)]}


# --------------------------------------------------------------------------- the spanning check


def _brute_root(ids, pairs):
    best, best_n = None, -1
    for r in ids:
        seen, q = {r}, deque([r])
        while q:
            x = q.popleft()
            for i, k in pairs:
                if k == x and i not in seen:
                    seen.add(i)
                    q.append(i)
        if len(seen) > best_n:
            best, best_n = r, len(seen)
    return best, best_n


@settings(max_examples=300, deadline=None)
@given(st.integers(1, 9).flatmap(lambda n: st.tuples(
    st.just(n), st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=20))))
def test_the_linear_spanning_root_is_the_root_reaching_the_most(case):
    n, raw = case
    ids = [f"v{j}" for j in range(n)]
    pairs = [(ids[a], ids[b]) for a, b in raw if a != b]
    root = graphs.spanning_root(ids, pairs)
    best, best_n = _brute_root(ids, pairs)
    assert root == best
    missing = graphs.unreachable(ids, pairs)
    assert len(missing) == n - best_n


def test_the_spanning_check_searches_a_bounded_number_of_roots(monkeypatch):
    """The old check searched from every vehicle: n searches of O(n + m), 520 s for 10,000."""
    calls = []
    real = graphs._reach
    monkeypatch.setattr(graphs, "_reach", lambda *a: calls.append(1) or real(*a))
    ids = [f"v{j}" for j in range(2000)]
    ring = [(ids[j], ids[j - 1]) for j in range(2000)]
    assert graphs.unreachable(ids, ring) == [] and len(calls) == 1
    calls.clear()
    pairs = [(ids[j], ids[j + 1]) for j in range(0, 2000, 2)]  # 1000 separate leaders
    missing = graphs.unreachable(ids, pairs)
    assert len(missing) == 1998 and len(calls) <= graphs.MAX_ROOT_SEARCHES + 1


def test_a_large_fleet_validates_with_linear_reference_checks(monkeypatch):
    monkeypatch.setattr(vehicles_module, "MAX_VEHICLES", 3000)
    data = fleet(3000, {"topology": "explicit", "edges": [[f"v{j}", f"v{j - 1}"] for j in range(1, 3000)],
                        "edge": [{"i": f"v{j}", "k": f"v{j - 1}", "delta": 0.5} for j in range(1, 3000)]})
    s = parse_scenario(data)
    assert len(s.vehicles) == 3000 and len(s.edges) == 2 * 2999


def test_id_list_membership_and_position():
    ids = IdList(["a", "b", "c"])
    assert "b" in ids and "z" not in ids and [1] not in ids and ids.position("c") == 2 and list(ids) == ["a", "b", "c"]


# --------------------------------------------------------------------------- limits


def test_a_fleet_over_the_size_limit_is_refused_naming_the_field_and_the_limit():
    n = vehicles_module.MAX_VEHICLES + 1
    with pytest.raises(ConfigError) as e:
        parse_scenario(fleet(n), "big.toml")
    assert e.value.problems[0][0] == "vehicle"
    assert f"{n} [[vehicle]] tables, more than the fleet-size limit of 1024" in str(e.value)
    assert len(e.value.problems) == 1  # nothing else is checked


def test_a_fleet_at_the_size_limit_is_accepted():
    s = parse_scenario(fleet(vehicles_module.MAX_VEHICLES))
    assert len(s.vehicles) == 1024


def test_a_graph_over_the_pair_limit_is_refused_before_its_pairs_are_built(monkeypatch):
    built = []
    monkeypatch.setattr(graphs, "build_pairs", lambda *a, **k: built.append(1))
    with pytest.raises(ConfigError) as e:
        parse_scenario(fleet(257, {"topology": "complete"}))
    assert "graph.topology" in str(e.value) and "65792 listening pairs, more than the limit of 65536" in str(e.value)
    assert not built


def test_a_complete_graph_of_256_is_within_the_pair_limit():
    assert 256 * 255 <= graph_module.MAX_PAIRS


# --------------------------------------------------------------------------- many problems


def test_thousands_of_problems_give_a_bounded_message_counting_the_rest():
    data = fleet(1000)
    for v in data["vehicle"]:
        v["kind"] = "boat"
    with pytest.raises(ConfigError) as e:
        parse_scenario(data)
    lines = str(e.value).splitlines()
    assert len(lines) == checks.MAX_PROBLEMS + 1
    assert lines[-1].endswith("and 900 more problems not shown; fix these first")


def test_problems_count_every_problem_and_keep_the_first():
    p = Problems()
    for j in range(checks.MAX_PROBLEMS + 5):
        p.add(f"f{j}", "bad")
        p.add(f"f{j}", "bad")  # once each
    assert len(p) == checks.MAX_PROBLEMS + 5 and p.since(checks.MAX_PROBLEMS)
    assert p.items[-1] == ("...", "and 5 more problems not shown; fix these first")


def test_a_long_id_list_in_a_message_is_cut():
    data = fleet(50)
    data["graph"] = {"topology": "star", "hub": "v999"}
    with pytest.raises(ConfigError) as e:
        parse_scenario(data)
    assert "v0, v1, v2, v3, v4, v5, v6, v7, v8, v9 and 40 more" in str(e.value)


def test_a_huge_bad_value_is_shown_cut():
    data = base()
    data["scenario"]["seed"] = list(range(100_000))
    with pytest.raises(ConfigError) as e:
        parse_scenario(data)
    assert len(str(e.value)) < 1000 and "characters)" in str(e.value)
