"""Formation and path changes from a tick (cdus.core.formation), in the node and in the metrics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cdus.core.formation import FormationSchedule, base_phases, phases_from_offsets
from cdus.core.link import IdealLink
from cdus.core.metrics import MetricEdge, Recorder
from cdus.core.neighbours import NeighbourLink
from cdus.core.node import VehicleNode
from cdus.scenario.paths import make_path
from cdus.scenario.config import parse_scenario
from cdus.sim.build import build_node, formation_schedule


def test_a_schedule_gives_the_phases_in_force_at_each_tick_updates_of_a_tick_in_the_order_added():
    f = FormationSchedule([0.0, 1.0, 2.0])
    f.add(10, {1: 5.0})
    f.add(4, {2: 7.0})
    f.add(10, {1: 6.0, 0: -1.0})
    assert f.phases_at(3) == (0.0, 1.0, 2.0) and not f.changed_by(3)
    assert f.phases_at(4) == (0.0, 1.0, 7.0)
    assert f.phases_at(10) == (-1.0, 6.0, 7.0)  # the second update of tick 10 wins
    assert f.ticks == (4, 10, 10) and f.count_by(9) == 1
    assert f.offset(1, 2, 99.0, 3) == 99.0  # before any change: the scenario's own Δ, to the bit
    assert f.offset(1, 2, 99.0, 10) == 6.0 - 7.0
    with pytest.raises(ValueError):
        f.add(1, {3: 0.0})
    with pytest.raises(ValueError):
        f.add(1, {0: math.nan})


def test_offsets_on_a_chain_move_the_vehicles_behind_the_edge_and_keep_the_others_to_the_bit():
    ids = ["a", "b", "c", "d"]
    current = [0.0, 1.0, 2.0, 3.0]
    edges = [("b", "a"), ("a", "b"), ("c", "b"), ("b", "c"), ("d", "c"), ("c", "d")]
    out = phases_from_offsets(ids, current, edges, {("c", "b"): 5.0}, directed=False)
    assert set(out) == {"c", "d"}  # a and b keep theirs (a is the anchor)
    assert out["c"] - current[1] == pytest.approx(5.0, abs=1e-12)
    assert out["d"] - out["c"] == pytest.approx(1.0, abs=1e-12)


def test_offsets_that_do_not_close_around_a_cycle_are_found():
    ids = ["a", "b", "c"]
    ring = [("a", "b"), ("b", "a"), ("b", "c"), ("c", "b"), ("c", "a"), ("a", "c")]
    found = phases_from_offsets(ids, [0.0, 0.0, 0.0], ring, {("a", "b"): 1.0}, directed=False)
    assert isinstance(found, tuple)
    cycle, total = found
    assert cycle[0] == cycle[-1] and abs(abs(total) - 1.0) < 1e-12


def test_base_phases_are_the_vehicles_own_or_solved_from_the_graphs_deltas():
    assert base_phases(["a", "b"], {"a": 1.0, "b": 3.0}, [("a", "b", -2.0), ("b", "a", 2.0)]) == (1.0, 3.0)
    solved = base_phases(["a", "b"], {"a": 1.0, "b": 0.0}, [("b", "a", 5.0), ("a", "b", -5.0)])
    assert solved == pytest.approx((1.0, 6.0))  # the first vehicle keeps its phase


def _node(links, period=0.1):
    from cdus.sim.build import build_vehicle  # noqa: PLC0415
    from cdus.scenario.model import Rates  # noqa: PLC0415
    sc = parse_scenario({"scenario": {"name": "n"}, "vehicle": [
        {"id": "a", "kind": "usv", "path": {"family": "circle", "center": [0, 0], "radius": 10}},
        {"id": "b", "kind": "usv", "path": {"family": "circle", "center": [0, 0], "radius": 10}}]})
    v = build_vehicle(sc.vehicles[0], Rates(10.0, 10.0, 10.0), 0)
    return VehicleNode(0, v, links, IdealLink(), period=period, every=1, last_tick=100)


def test_a_node_takes_new_offsets_and_a_new_path_exactly_from_their_tick():
    node = _node((NeighbourLink(1, 1.0, -2.0),))
    node.formation = FormationSchedule([0.0, 2.0])
    node.set_formation({1: 0.5}, 3)
    new = make_path({"family": "circle", "center": [5.0, 5.0], "radius": 3.0})
    old = node.vehicle.path
    node.set_path(new, 2)
    for n in range(5):
        node.step(n)
        assert node.table.links[0].delta == (-2.0 if n < 3 else 0.0 - 0.5), n
        assert node.vehicle.path is (old if n < 2 else new), n
    refused = node.set_path(make_path({"family": "circle", "center": [0, 0, 1], "radius": 3.0}), 9)  # 3-D for a boat
    assert not refused and refused.reason == "a 2-D vehicle needs a 2-D path, got 3-D" and not node._paths


def test_a_node_built_alone_derives_phases_from_its_own_links():
    node = _node((NeighbourLink(1, 1.0, -2.0),))
    node.set_formation({0: 1.0}, 0)  # θ_a = 1, θ_b stays 2 (from Δ_ab = -2 with θ_a = 0)
    node.step(0)
    assert node.table.links[0].delta == 1.0 - 2.0


def test_a_node_rejoining_after_a_path_change_starts_on_the_new_path():
    node = _node((NeighbourLink(1, 1.0, 0.0),))
    new = make_path({"family": "circle", "center": [100.0, 0.0], "radius": 3.0})
    node.set_path(new, 5)
    node.rejoin(7, (103.0, 0.0), 0.0, 0.0)
    assert node.vehicle.path is new and node.vehicle.path_error() < 1e-6


def test_the_recorder_measures_each_row_against_the_offsets_in_force_then():
    rec = Recorder(["a", "b"], [2, 2], [MetricEdge(0, 1, 1.0, "a__b")])
    f = FormationSchedule([1.0, 0.0])
    rec.set_formation(f, 0.1)
    f.add(3, {1: -2.0})  # Δ_ab = 1 - (-2) = 3 from tick 3

    class Row:
        def __init__(self, w):
            self.q, self.heading, self.omega, self.omega_rate, self.path_error = (0.0, 0.0), 0.0, w, -1.0, 0.0

    for n in range(6):
        rec.record(n * 0.1, [Row(1.0), Row(0.0)])  # ω_a - ω_b = 1 all along
    err = rec.edge_error()[:, 0]
    assert list(err) == [0.0, 0.0, 0.0, 2.0, 2.0, 2.0]
    assert list(rec.edge_error(2, 4)[:, 0]) == [0.0, 2.0]
    assert list(rec.worst_errors()[1]) == [0.0, 0.0, 0.0, 2.0, 2.0, 2.0]
    plain = Recorder(["a", "b"], [2, 2], [MetricEdge(0, 1, 1.0, "a__b")])
    assert plain.deltas() is None


def test_build_node_applies_the_scenarios_scheduled_changes():
    sc = parse_scenario({"scenario": {"name": "n"}, "rates": {"control": 10}, "vehicle": [
        {"id": "a", "kind": "usv", "path": {"family": "circle", "center": [0, 0], "radius": 10}},
        {"id": "b", "kind": "usv", "phase": 1.0, "path": {"family": "circle", "center": [0, 0], "radius": 10}}],
        "event": [{"at": 0.25, "action": "formation", "phases": {"b": 4.0}},
                  {"at": 0.1, "action": "path", "vehicle": "a",
                   "path": {"family": "circle", "center": [1, 2], "radius": 4}}]})
    node = build_node(sc, "a", IdealLink())
    for n in range(4):
        node.step(n)
        assert node.table.links[0].delta == (-1.0 if n < 3 else -4.0), n  # 0.25 s is tick 3 at 10 Hz
        assert (node.vehicle.path.center == (1.0, 2.0)) == (n >= 1), n
    assert formation_schedule(sc).phases_at(3) == (0.0, 4.0)
    assert np.isfinite(node.vehicle.omega)


from hypothesis import given, settings, strategies as hst  # noqa: E402


class _Row:
    def __init__(self, w):
        self.q, self.heading, self.omega, self.omega_rate, self.path_error = (0.0, 0.0), 0.0, w, -1.0, 0.0


@settings(max_examples=80, deadline=None)
@given(changes=hst.lists(hst.tuples(hst.integers(0, 12), hst.integers(0, 2), hst.floats(-5, 5)), max_size=8),
       lo=hst.integers(0, 12), width=hst.integers(1, 13))
def test_the_deltas_of_any_rows_are_those_of_the_phases_in_force_at_each_row(changes, lo, width):
    ids = ["a", "b", "c"]
    edges = [MetricEdge(0, 1, 1.0, "a__b"), MetricEdge(2, 1, -0.5, "c__b")]
    rec = Recorder(ids, [2, 2, 2], edges)
    f = FormationSchedule([1.0, 0.0, -0.5])
    rec.set_formation(f, 0.1)
    for tick, j, theta in changes:
        f.add(tick, {j: theta})
    for n in range(12):
        rec.record(n * 0.1, [_Row(0.0)] * 3)
    got = rec.deltas(lo, lo + width)
    if got is None:
        assert not f.changed_by(min(12, lo + width) - 1) or lo >= 12
        return
    for r, n in enumerate(range(lo, min(12, lo + width))):
        want = [f.offset(e.i, e.k, e.delta, n) for e in edges]
        assert list(got[r]) == want, (n, list(got[r]), want)

