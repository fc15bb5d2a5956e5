"""The proximity sensor and the safety filter in whole in-process runs (docs/safety.md)."""

import math
import tomllib

import numpy as np
import pytest

from cdus.core.metrics import min_separation
from cdus.scenario.config import load_scenario, parse_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.sim.sensing import contacts_of, sense_tick

R = 2.0
# The filter keeps ḣ ≥ -γh on positions sampled at 10 Hz and used one 50 Hz tick later,
# so it can overshoot R by what the vehicles close in between samples; measured on
# crossing.toml: 2.0204 m (contacts extrapolated at their estimated velocities; 2.0036 m
# without). The tests allow 1 cm below R.
TOLERANCE = 0.01


def run(overrides=None, duration=None):
    sc = load_scenario("configs/crossing.toml", overrides or {})
    return InProcessFleet(sc).run(duration)


def test_sense_tick_gives_every_sampled_vehicle_a_message_and_same_domain_contacts():
    sc = load_scenario("configs/crossing.toml")
    msgs = sense_tick(sc, 5, {0: (0.0, 0.0), 1: (3.0, 4.0), 2: (30.0, 0.0)})  # usv_b2 did not step tick 5
    assert sorted(msgs) == [0, 1, 2]
    assert all(m.tick == 5 for m in msgs.values())
    assert msgs[0].contacts == ((1, 0.5, (3.0, 4.0)),) and msgs[2].contacts == ()
    (c,) = contacts_of(msgs[1], sc.ids)
    assert (c.id, c.q, c.share) == ("usv_a1", (0.0, 0.0), 0.5)


def test_min_separation_compares_boats_on_the_water_and_drones_in_3d():
    q = np.zeros((2, 4, 3))
    q[:, 1] = (3.0, 4.0, 0.0)  # a boat 5 m from the boat at the origin
    q[:, 2] = (0.0, 0.0, 20.0)  # a drone right above it: another domain
    q[:, 3] = (0.0, 1.0, 22.0)
    assert min_separation(q, ["usv", "usv", "uav", "uav"]) == pytest.approx(math.sqrt(5.0))
    assert min_separation(q, ["usv", "uav", "uav", "usv"]) == pytest.approx(1.0)  # boats: z ignored
    assert min_separation(q[:, :2], ["usv", "uav"]) is None


def test_crossing_without_the_filter_comes_closer_than_the_radius():
    m = run({"safety.enabled": False}).metrics
    assert m.min_separation_m < R  # measured 1.07 m
    assert m.interventions == 0


def test_crossing_with_the_filter_keeps_the_radius_and_the_formation_settles():
    m = run().metrics
    assert m.min_separation_m >= R - TOLERANCE  # measured 2.0204 m
    assert m.interventions > 0  # measured 240 control steps, all in the first 6 s
    assert m.path_settle_s is not None and m.coord_settle_s is not None  # 15.2 s and 62.8 s
    assert m.final_coord_error_max < 0.05 and m.final_path_error_max < 0.1


def test_vehicles_starting_inside_the_radius_get_out_without_a_crash_or_a_freeze():
    """usv_a1 and usv_b1 start on the same spot (the upper crossing), usv_a2 0.5 m from
    them: the QP is infeasible at first; the relaxed filter separates them (coincident ones
    along a direction fixed by their ids), then the formation settles."""
    sc = load_scenario("configs/crossing.toml", {
        "vehicle.usv_a1.start.position": [0.0, 8.0], "vehicle.usv_b1.start.position": [0.0, 8.0],
        "vehicle.usv_a2.start.position": [0.5, 8.0], "scenario.duration": 80.0})
    fleet = InProcessFleet(sc)
    res = fleet.run()
    q = res.recorder.view("q")
    t = res.recorder.view("t")
    assert min_separation(q[:1], [v.kind for v in sc.vehicles]) < 0.5  # they did start inside R
    late = t >= 10.0
    assert min_separation(q[late], [v.kind for v in sc.vehicles]) >= R - TOLERANCE
    assert np.isfinite(q).all()
    rates = res.metrics.omega_rate_final
    assert all(r == pytest.approx(-1.0, abs=0.05) for r in rates.values())  # moving on, not frozen
    assert res.metrics.path_settle_s is not None


def test_wind_and_current_with_the_observer_leave_a_smaller_steady_path_error():
    """lake_windy for 80 s: mean |Φ| over the last 30 s, over the six vehicles. Measured:
    0.797 m without the observer, 0.123 m with it (6.5x smaller; docs/safety.md)."""
    def steady(observer):
        sc = load_scenario("configs/lake_windy.toml", {"observer.enabled": observer, "scenario.duration": 80.0})
        rec = InProcessFleet(sc).run().recorder
        t, pe = rec.view("t"), rec.view("path_error")
        return float(pe[t >= 50.0].mean())

    with_, without = steady(True), steady(False)
    print(f"steady mean |Φ|: {without:.3f} m without the observer, {with_:.3f} m with it")
    assert with_ < 0.5 * without


def test_lake_windy_seed_3_holds_its_path_with_the_preset_limits():
    """With a bare speed cap (thrust unbounded) seed 3's usv2 ran away at 71 s; with the
    preset's limits every vehicle stays within a metre of its path from 60 s on."""
    sc = load_scenario("configs/lake_windy.toml", {"scenario.seed": 3, "scenario.duration": 90.0})
    rec = InProcessFleet(sc).run().recorder
    t, pe = rec.view("t"), rec.view("path_error")
    assert np.isfinite(pe).all()
    assert pe[t >= 60.0].max() < 1.0


# --------------------------------------------------------------------------- on the dynamics


def run_dynamic(overrides=None):
    sc = load_scenario("configs/crossing_dynamic.toml", overrides or {})
    return sc, InProcessFleet(sc).run()


REGULATORS = ["heading", "paper"]


@pytest.mark.parametrize("regulator", REGULATORS)
def test_crossing_dynamic_without_the_filter_comes_closer_than_the_radius(regulator):
    _, res = run_dynamic({"safety.enabled": False, "defaults.regulator": regulator})
    assert res.metrics.min_separation_m < R  # measured 1.218 m (heading), 1.242 m (paper)


@pytest.mark.parametrize("regulator", REGULATORS)
def test_crossing_dynamic_with_the_filter_keeps_the_radius_and_the_formation_settles(regulator):
    """usv_3dof boats with the preset's limits (the velocity-level filter alone kept 1.437 m):
    the dynamic filter holds R on τ_u at the physics rate, behind either regulator; the
    formation settles (paper regulator: 2.069 m, path 23.6 s, coordination 111.0 s)."""
    _, res = run_dynamic({"defaults.regulator": regulator})
    m = res.metrics
    assert m.min_separation_m >= R - TOLERANCE  # measured 2.069 m (their distance at the start)
    assert m.interventions > 0  # measured 1179
    assert m.path_settle_s is not None and m.coord_settle_s is not None  # 28.4 s and 114.5 s


def test_a_killed_boat_stays_an_obstacle_the_others_avoid():
    """usv_b1 is killed at 0.5 s, next to usv_a1's way: the sensor keeps it where it died
    (share 1 for the others) and usv_a1 keeps R from it. If the sensor dropped it, usv_a1
    came within 1.83 m of it."""
    data = tomllib.loads(open("configs/crossing_dynamic.toml").read())
    data["scenario"]["duration"] = 30.0
    data["event"] = [{"at": 0.5, "vehicle": "usv_b1", "action": "kill"}]
    sc = parse_scenario(data, source="crossing_dynamic+kill")
    res = InProcessFleet(sc).run()
    q = res.recorder.view("q")
    gap = np.linalg.norm(q[:, 0, :2] - q[:, 1, :2], axis=1)
    assert np.allclose(q[-1, 1], q[len(q) // 2, 1])  # it does not move after its death
    assert gap.min() >= R - TOLERANCE  # measured 2.069 m


def test_a_boat_whose_path_a_dead_boat_blocks_gets_past_it():
    """usv_b1 dies at 0.5 s on usv_b2's circle; usv_b2 reaches it at about 25 s. It keeps R
    from it and gets past (measured: 6.9 m beyond it at 60 s, back on its path by 70 s).
    Before the shaper's correction was taken from the unclipped reference, usv_b2 stopped
    2.16 m from the dead boat and stayed there for good (|Φ| growing to 3.2 m at 150 s)."""
    data = tomllib.loads(open("configs/crossing_dynamic.toml").read())
    data["scenario"]["duration"] = 70.0
    data["event"] = [{"at": 0.5, "vehicle": "usv_b1", "action": "kill"}]
    sc = parse_scenario(data, source="crossing_dynamic+kill")
    res = InProcessFleet(sc).run()
    t, q = res.recorder.view("t"), res.recorder.view("q")
    gap = np.linalg.norm(q[:, 3, :2] - q[:, 1, :2], axis=1)
    assert gap.min() >= R - TOLERANCE  # measured 2.182 m
    assert gap[t >= 60.0].min() > 5.0  # past it (stuck: 2.16 m)


def test_sense_tick_keeps_vehicles_that_are_gone_as_obstacles_taken_whole():
    sc = load_scenario("configs/crossing.toml")
    msgs = sense_tick(sc, 5, {0: (0.0, 0.0), 2: (1.0, 0.0)}, {1: (3.0, 4.0), 3: (40.0, 0.0)})
    assert sorted(msgs) == [0, 2]  # the dead are sent nothing
    assert msgs[0].contacts == ((2, 0.5, (1.0, 0.0)), (1, 1.0, (3.0, 4.0)))  # in id order: usv_a2, usv_b1
    assert msgs[2].contacts == ((0, 0.5, (0.0, 0.0)), (1, 1.0, (3.0, 4.0)))
