"""The in-process fleet against the paper's behaviour (docs/control.md §2, §7).

Every scenario here is a shipped config run for its full duration with its own seed, so
the numbers in the README come from the same runs.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest

from cdus.scenario.config import load_scenario, parse_scenario
from cdus.core.schedule import delivery_tick
from cdus.sim.fleet import InProcessFleet
from cdus.core.metrics import Recorder
from cdus.core.vehicle import DivergedError, Telemetry


def run(name: str, **overrides):
    sc = load_scenario(f"configs/{name}.toml", overrides)
    return sc, InProcessFleet(sc).run()


@functools.cache
def lake_circle():
    """The shipped lake_circle as it is, run once for the tests that read it (none changes it)."""
    return run("lake_circle")


def test_lake_circle_ideal_reaches_the_papers_objectives():
    sc, res = lake_circle()
    m = res.metrics
    # Objectives 1 and 3: every |Φ| < 0.1 m and every edge error < 0.05 rad before the end
    assert m.path_settle_s is not None and m.path_settle_s < sc.duration
    assert m.coord_settle_s is not None and m.coord_settle_s < sc.duration
    assert m.final_path_error_max < 0.1
    assert m.final_coord_error_max < 0.05
    # Objective 2: ω̇ -> -1 (mean over the last second)
    for vid, rate in m.omega_rate_final.items():
        assert abs(rate + 1.0) < 0.01, (vid, rate)
    # docs/control.md §2: at 50 Hz, ideal tracking holds |Φ| ≈ 0.063 m (the tangential offset
    # 1/(k|f'|) = 0.067 m that balances the -1 drift, less the chord effect)
    assert 0.03 < m.final_path_error_max < 0.08
    # The 120° formation holds on the water: USVs 2π/3 apart along the circle
    w = res.recorder.view("omega")[-1]
    ids = list(res.recorder.ids)
    gap = (w[ids.index("usv2")] - w[ids.index("usv1")]) % (2 * math.pi)
    assert gap == pytest.approx(2 * math.pi / 3, abs=0.05)


def test_lake_circle_with_vehicle_models_converges():
    """USV ε-model with the heading regulator, UAV double integrator, at 1 m/s.

    Tolerance 0.15 m (the config's path_tol): the heading regulator leaves a steady crab
    angle (~8.7° at 1 m/s), which the -KΦ term offsets with |Φ| = |f'| tan(crab)/k ≈ 0.10 m.
    """
    sc, res = run("lake_circle_dynamic")
    m = res.metrics
    assert sc.path_tol == 0.15
    assert m.path_settle_s is not None and m.coord_settle_s is not None
    assert m.final_path_error_max < 0.15
    assert m.final_coord_error_max < 0.05
    usv_errors = [m.final_path_error[v.id] for v in sc.vehicles if v.kind == "usv"]
    assert all(0.05 < e < 0.15 for e in usv_errors)  # the crab-angle offset is really there
    for rate in m.omega_rate_final.values():
        assert abs(rate + 1.0) < 0.03


@pytest.mark.parametrize("rate,max_path_error,max_rate_error", [
    (10.0, 0.35, 0.03),   # chord error of a 10 m/s circle at 10 Hz ≈ 0.3 m (docs/control.md §2)
    (20.0, 0.2, 0.01),
    (50.0, 0.08, 0.01),
])
def test_stable_and_converged_at_every_control_rate(rate, max_path_error, max_rate_error):
    sc = load_scenario("configs/lake_circle.toml", {"rates.control": rate, "rates.broadcast": rate})
    shipped, shipped_run = lake_circle()
    # at 50 Hz this is the shipped lake_circle (equal but for the TOML text it keeps): its run, made once
    res = shipped_run if dataclasses.replace(sc, raw=shipped.raw) == shipped else InProcessFleet(sc).run()
    m = res.metrics
    assert np.isfinite(res.recorder.view("omega")).all()
    assert m.final_path_error_max < max_path_error
    assert m.coord_settle_s is not None
    for r in m.omega_rate_final.values():
        assert abs(r + 1.0) < max_rate_error


def test_directed_chain_converges():
    """A directed spanning tree (Assumption 1), outside the Lyapunov proof: converges here,
    more slowly than the ring (measured: coordination settles at ~363 s, seed 1; 420 s shows
    it, 500 s did too)."""
    sc, res = run("lake_circle", **{"graph.topology": "chain", "graph.directed": True, "scenario.duration": 420.0})
    assert sc.directed and len(sc.edges) == len(sc.vehicles) - 1
    m = res.metrics
    assert m.coord_settle_s is not None
    assert m.final_coord_error_max < 0.05
    assert m.final_path_error_max < 0.1


@pytest.mark.parametrize("name", ["lissajous_5x5", "concentric_circles", "offset_circles"])
def test_shipped_scenarios_converge(name):
    sc, res = run(name)
    m = res.metrics
    assert m.path_settle_s is not None, m
    assert m.coord_settle_s is not None, m
    for r in m.omega_rate_final.values():
        assert abs(r + 1.0) < 0.01


def test_in_process_runs_are_deterministic():
    _, a = run("lake_circle", **{"scenario.duration": 20.0})
    _, b = run("lake_circle", **{"scenario.duration": 20.0})
    assert np.array_equal(a.recorder.view("q"), b.recorder.view("q"))
    assert np.array_equal(a.recorder.view("omega"), b.recorder.view("omega"))


def test_seed_changes_the_start_and_not_the_outcome():
    # 150 s, not the shipped 250: seeds 2 and 3 settle at 86.28 s and 110.58 s
    _, a = run("lake_circle", **{"scenario.seed": 2, "scenario.duration": 150.0})
    _, b = run("lake_circle", **{"scenario.seed": 3, "scenario.duration": 150.0})
    assert not np.array_equal(a.recorder.view("q")[0], b.recorder.view("q")[0])
    assert a.metrics.coord_settle_s is not None and b.metrics.coord_settle_s is not None


def test_messages_are_used_one_tick_after_they_are_sent_at_the_earliest():
    assert delivery_tick(10, 0.0, 0.02) == 11
    assert delivery_tick(10, 0.1, 0.02) == 15
    assert delivery_tick(10, 0.101, 0.02) == 16


def test_broadcast_slower_than_control_still_converges_and_counts_messages():
    sc, res = run("lake_circle", **{"rates.broadcast": 10.0, "scenario.duration": 200.0})
    link = res.metrics.link
    # 6 vehicles x 2 listeners x 10 Hz x 200 s (from t = 0; nothing is sent at the last instant)
    assert link.sent == 6 * 2 * (200 * 10)
    assert link.dropped == 0 and link.rejected == 0
    assert res.metrics.coord_settle_s is not None


def kill_usv2(at: float = 20.0, restart: float | None = None, duration: float = 30.0):
    sc = load_scenario("configs/lake_circle.toml", {"scenario.duration": duration})
    events = [{"at": at, "action": "kill", "vehicle": "usv2"}]
    if restart is not None:
        events.append({"at": restart, "action": "restart", "vehicle": "usv2"})
    return parse_scenario({**sc.raw, "event": events})


def test_a_killed_vehicle_leaves_its_neighbours_sums_for_good():
    """The bug of old: its last in-flight ω re-admitted it into usv1's and usv3's sums."""
    sc = kill_usv2()
    fleet = InProcessFleet(sc)
    res = fleet.run()
    j = sc.ids.index("usv2")
    for vid in ("usv1", "usv3"):
        node = fleet.nodes[sc.ids.index(vid)]
        assert j in node.neighbours and j not in node.table.latest
    news = [(e.kind, e.vehicle, e.t) for e in res.metrics.events]
    assert news[0] == ("fault", "usv2", 20.0)  # reported as the world does (cdus.sim.reports)
    assert news[1][0] == "graph" and "vehicle_lost" not in [k for k, _, _ in news]
    omega = res.recorder.view("omega")[:, j]
    t = res.recorder.view("t")
    assert np.all(omega[t >= 20.0] == omega[t >= 20.0][0])  # frozen where it was last seen


def test_the_formation_errors_leave_out_a_killed_vehicle_and_nobody_counts_messages_to_it():
    """Killed at 200 s after the fleet settled: the frozen ω of usv2 is not the formation's
    error (it would be tens of rad), the rest still settles; its neighbours' messages to it
    are not counted as sent (a dead process hears nothing)."""
    sc = kill_usv2(at=200.0, duration=250.0)
    res = InProcessFleet(sc).run()
    m = res.metrics
    assert m.live_final == tuple(v for v in sc.ids if v != "usv2")
    assert m.coord_settle_s is not None and m.coord_settle_s < 200.0
    assert m.final_coord_error_max < 0.05
    raw = res.recorder.edge_error()[-1].max()
    assert raw > 1.0  # the edges to usv2 are far off; they are just not the formation's
    live = res.recorder.view("live")
    t = res.recorder.view("t")
    j = sc.ids.index("usv2")
    assert live[t < 200.0, j].all() and not live[t >= 200.0, j].any()
    # a message counts as sent when its receiver decides it, at the receiver's next tick: from
    # tick 10000 on usv2 neither sends to its 2 neighbours nor hears them (2 x 2 x 2500), and
    # the two ω its neighbours sent it at 9999 are never decided (+2), as in a lockstep run
    whole_sc, whole_run = lake_circle()
    assert whole_sc.duration == 250.0
    whole = whole_run.metrics
    assert whole.link.sent - m.link.sent == 2 * 2 * 2500 + 2


def test_a_restarted_vehicle_rejoins_near_its_neighbours_consensus():
    sc = kill_usv2(at=20.0, restart=25.0, duration=60.0)
    res = InProcessFleet(sc).run()
    kinds = [(e.kind, e.vehicle, e.t) for e in res.metrics.events]
    assert [k for k in kinds if k[0] != "graph"] == [("fault", "usv2", 20.0), ("fault", "usv2", 25.0),
                                                     ("vehicle_back", "usv2", 25.0)]
    j = sc.ids.index("usv2")
    t = res.recorder.view("t")
    w = res.recorder.view("omega")
    # it carries on: its ω after the restart is within half a lap of its neighbours' pull
    i1, i3 = sc.ids.index("usv1"), sc.ids.index("usv3")
    after = np.searchsorted(t, 25.0)
    assert abs(w[after, j] - (w[after, i1] + w[after, i3]) / 2) < np.pi
    assert res.metrics.final_coord_error_max < 0.5


def test_lake_circle_dynamic_settles_from_every_shipped_seed_start():
    """Seed 4 of lake_circle_dynamic (boats and drones with a 2 m/s limit): with ω's
    path-following part scaled by the speed limit its boats ran away (|Φ| 3.1 km at 200 s);
    the scaling is off unless [guidance] scale_omega asks for it, and the run settles."""
    sc = load_scenario("configs/lake_circle_dynamic.toml", {"scenario.seed": 4})
    m = InProcessFleet(sc).run().metrics
    assert m.path_settle_s is not None and m.final_path_error_max < 0.15


def test_a_diverging_fleet_stops_with_an_error_naming_the_vehicle_not_a_traceback():
    # k = 300 at 50 Hz is past the bound the scenario validation enforces (k < 2 x 50,
    # cdus.core.gain_bounds), so the validated scenario's specs are changed behind its back
    sc = load_scenario("configs/lake_circle.toml", {"scenario.duration": 20.0})
    sc = dataclasses.replace(sc, vehicles=tuple(dataclasses.replace(v, k=(300.0,) * v.dim) for v in sc.vehicles))
    with pytest.raises(DivergedError, match=r"vehicle usv1: its numbers overflowed at t = .* gains k = \(300.0"):
        InProcessFleet(sc).run()


def test_with_no_vehicle_live_nothing_is_settled():
    rec = Recorder(["a"], [2], [], capacity=4)
    row = Telemetry("a", 0.0, (0.0, 0.0), 0.0, 0.0, 0.0, 0.0, 0.0)
    for n in range(3):
        rec.record(n * 0.1, [row], [n == 0])
    path, coord = rec.worst_errors()
    assert path[0] == 0.0 and np.isnan(path[1:]).all() and np.isnan(coord[1:]).all()
    m = rec.summary(scenario="x", mode="inproc", seed=1, path_tol=0.1, coord_tol=0.1, link={}, wall_s=1.0)
    assert m["path_settle_s"] is None and m["final_path_error_max"] is None and m["live_final"] == []


def test_lake_circle_dynamic_settles_with_the_default_path_tol_and_a_margin():
    """usv_3dof boats hold ~0.0997 m off a 10 m circle at 1 m/s (crab angle): the default 0.1 m
    was met with 0.3 mm to spare. The file no longer sets path_tol; a fleet with such boats
    defaults to 0.15 m, and the boats' offset sits well inside it."""
    assert "path_tol" not in open("configs/lake_circle_dynamic.toml").read().split("[metrics]")[1].split("[")[0] \
        .replace("# path_tol", "")
    sc = load_scenario("configs/lake_circle_dynamic.toml", {"scenario.duration": 60.0})
    assert sc.path_tol == 0.15
    m = InProcessFleet(sc).run().metrics
    boats = [m.final_path_error[v.id] for v in sc.vehicles if v.plant == "usv_3dof"]
    assert m.path_settle_s is not None and m.path_settle_s < 40.0
    assert max(boats) < 0.8 * sc.path_tol and min(boats) > 0.09  # the offset is real, and inside the tolerance
