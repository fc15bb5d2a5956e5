"""The closest approach of a run (cdus.core.metrics.closest_pairs): per domain, who, how
close, when, and whether both were live; dead vehicles count where they stopped."""

import math

import numpy as np
import pytest

from cdus.core.metrics import CROSS_DOMAIN, ClosestPair, closest_pairs, min_separation


def _run(ticks=5, n=4):
    t = np.arange(ticks) * 0.5
    q = np.zeros((ticks, n, 3))
    for j in range(n):
        q[:, j, 0] = 100.0 * j  # far apart unless a test brings them together
    return t, q, np.ones((ticks, n), dtype=bool)


def test_the_closest_pair_of_each_domain_with_its_time():
    t, q, live = _run()
    ids, kinds = ["b1", "b2", "d1", "d2"], ["usv", "usv", "uav", "uav"]
    q[2, 1, :2] = (3.0, 4.0)  # b2 5 m from b1 at t = 1.0
    q[3, 3] = (200.0, 0.0, 3.0)  # d2 3 m above d1 at t = 1.5
    q[4, 3] = (200.0, 2.0, 0.0)  # d2 2 m from d1 at t = 2.0: closer
    pairs = closest_pairs(t, q, live, ids, kinds)
    assert pairs["usv"] == ClosestPair("usv", "b1", "b2", 5.0, 1.0, True, True)
    assert pairs["uav"] == ClosestPair("uav", "d1", "d2", 2.0, 2.0, True, True)
    assert pairs["usv"].distance == pytest.approx(min_separation(q[:, :2], kinds[:2]))


def test_boats_are_compared_on_the_water_drones_in_3d_and_drone_to_boat_at_the_surface():
    t, q, live = _run(ticks=2, n=3)
    ids, kinds = ["b1", "d1", "b2"], ["usv", "uav", "usv"]
    q[1, 2] = (0.0, 1.0, 7.0)  # b2 1 m from b1 on the water (its z is not a height)
    q[0, 1] = (200.0, 0.0, 6.0)  # d1 6 m above b2's start (x = 200): 6 m
    pairs = closest_pairs(t, q, live, ids, kinds)
    assert pairs["usv"].distance == pytest.approx(1.0)
    cross = pairs[CROSS_DOMAIN]
    assert (cross.a, cross.b, cross.t) == ("d1", "b2", 0.0)  # scenario order: d1 before b2
    assert cross.distance == pytest.approx(6.0)
    assert "uav" not in pairs  # one drone: no drone pair


def test_a_vehicle_not_live_counts_where_it_stopped_and_is_flagged():
    """A killed boat's rows repeat where it died; another that sails into the wreck is a
    closest approach with b_live false."""
    t, q, live = _run(ticks=6, n=2)
    ids, kinds = ["b1", "b2"], ["usv", "usv"]
    q[:, 1] = (50.0, 0.0, 0.0)
    live[2:, 1] = False  # b2 killed at t = 1.0, its row frozen at x = 50
    q[:, 0, 0] = [0.0, 10.0, 20.0, 30.0, 49.0, 60.0]  # b1 passes 1 m from the wreck at t = 2.0
    p = closest_pairs(t, q, live, ids, kinds)["usv"]
    assert (p.a, p.b, p.distance, p.t) == ("b1", "b2", 1.0, 2.0)
    assert p.a_live and not p.b_live and not p.both_live
    d = p.as_dict()
    assert d["both_live"] is False and d["b_live"] is False and d["distance_m"] == 1.0 and d["t_s"] == 2.0


def test_ties_go_to_the_earlier_time_then_the_first_pair():
    t, q, live = _run(ticks=3, n=3)
    ids, kinds = ["a", "b", "c"], ["usv"] * 3
    q[:, 0, :2] = (0.0, 0.0)
    q[:, 1, :2] = (2.0, 0.0)  # a-b 2 m at every tick: the first tick wins
    q[:, 2, :2] = (-2.0, 0.0)  # a-c 2 m too: a-b comes first
    p = closest_pairs(t, q, live, ids, kinds)["usv"]
    assert (p.a, p.b, p.t) == ("a", "b", 0.0)
    q[2, 2, :2] = (-1.0, 0.0)
    p = closest_pairs(t, q, live, ids, kinds)["usv"]
    assert (p.a, p.b, p.t, p.distance) == ("a", "c", 1.0, 1.0)


def test_no_rows_no_pair_and_non_finite_rows_are_skipped():
    t, q, live = _run(ticks=0, n=2)
    assert closest_pairs(t, q, live, ["a", "b"], ["usv", "usv"]) == {}
    t, q, live = _run(ticks=3, n=3)
    assert closest_pairs(t[:1], q[:1, :1], live[:1, :1], ["a"], ["usv"]) == {}  # one vehicle
    q[1, 0, 0] = math.nan  # a diverged at t = 0.5: that row says nothing
    q[2, 1, :2] = (1.0, 0.0)
    q[2, 0, :2] = (0.0, 0.0)
    p = closest_pairs(t, q, live, ["a", "b", "c"], ["usv"] * 3)["usv"]
    assert (p.a, p.b, p.distance, p.t) == ("a", "b", 1.0, 1.0)
    q[:, 0, :] = math.nan  # a never finite: the pairs with a say nothing, b-c still do
    p = closest_pairs(t, q, live, ["a", "b", "c"], ["usv"] * 3)["usv"]
    assert (p.a, p.b) == ("b", "c")
    q[:, 1:, :] = math.inf
    assert closest_pairs(t, q, live, ["a", "b", "c"], ["usv"] * 3) == {}


def test_the_recorder_keeps_intervention_counts_carried_forward_through_growth():
    from types import SimpleNamespace

    from cdus.core.metrics import Recorder

    rec = Recorder(["a", "b"], [2, 2], (), capacity=16)
    tel = SimpleNamespace(q=(0.0, 0.0), heading=0.0, omega=0.0, omega_rate=-1.0, path_error=0.0)
    for n in range(40):
        rec.record(n * 0.02, [tel, tel], interventions=[n, 2 * n] if n % 3 == 0 else None)
    counts = rec.view("interventions")
    assert counts.shape == (40, 2) and counts.dtype == np.int64
    assert counts[:, 0].tolist() == [3 * (n // 3) for n in range(40)]  # a row without counts repeats the last
    assert counts[:, 1].tolist() == [6 * (n // 3) for n in range(40)]
    assert Recorder(["a"], [2], ()).view("interventions").shape == (0, 1)


def test_rows_taken_in_chunks_give_the_same_pair_ties_included(monkeypatch):
    import cdus.core.metrics as metrics

    rng = np.random.default_rng(5)
    t, q, live = _run(ticks=50, n=6)
    q[:] = np.round(rng.uniform(0.0, 4.0, q.shape))  # integer grid: many exact ties
    live[:] = rng.uniform(size=live.shape) < 0.7
    kinds = ["usv", "uav", "usv", "uav", "uav", "usv"]
    ids = [f"v{j}" for j in range(6)]
    whole = closest_pairs(t, q, live, ids, kinds)
    monkeypatch.setattr(metrics, "_CHUNK", 7)  # a couple of rows at a time
    assert closest_pairs(t, q, live, ids, kinds) == whole
    for domain, p in whole.items():  # and the pair a plain loop finds
        best = None
        for i in range(len(t)):
            for j in range(6):
                for k in range(j + 1, 6):
                    dom = kinds[j] if kinds[j] == kinds[k] else CROSS_DOMAIN
                    if dom != domain:
                        continue
                    if dom == CROSS_DOMAIN:
                        drone, boat = (j, k) if kinds[j] == "uav" else (k, j)
                        d = math.dist(q[i, drone], (*q[i, boat, :2], 0.0))
                    else:
                        d = math.dist(q[i, j, :2 if dom == "usv" else 3], q[i, k, :2 if dom == "usv" else 3])
                    if best is None or d < best[0]:
                        best = (d, i, j, k)
        d, i, j, k = best
        assert (p.a, p.b, p.t, p.a_live, p.b_live) == (ids[j], ids[k], t[i], live[i, j], live[i, k])
        assert p.distance == pytest.approx(d)
