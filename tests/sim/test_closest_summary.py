"""The safety figures of a run (cdus.sim.summary.safety_figures through run_metrics) and the
end-of-run summary's lines: the closest pair, a near collision flagged with the filter on
or off, a killed vehicle counted where it died, and the per-vehicle intervention counts the
in-process fleet records."""

from dataclasses import replace

import pytest

from cdus.app.report import closest_lines, summary_table
from cdus.results import Metrics, SafetyInfo
from cdus.scenario.config import parse_scenario
from cdus.sim.fleet import InProcessFleet


def _line(vid, origin, heading, omega0, kind="usv"):
    return {"id": vid, "kind": kind, "plant": "ideal", "omega0": omega0,
            "path": {"family": "line", "origin": origin, "heading": heading, "speed": 1.0}}


def _scenario(safety=None, events=(), duration=6.0, vehicles=None):
    """By default b1 sails east along y = 0 and b2 north along x = 0.3, both at (0.3, 0) at t = 3 s."""
    data = {
        "scenario": {"name": "meet", "duration": duration},
        "graph": {"topology": "ring"},
        "gains": {"k": 1.5, "c": 0.5},
        "vehicle": vehicles or [_line("b1", [0.0, 0.0], [-1.0, 0.0], 3.0), _line("b2", [0.3, 0.0], [0.0, -1.0], 3.0)],
    }
    if safety is not None:
        data["safety"] = safety
    if events:
        data["event"] = list(events)
    return parse_scenario(data)


def test_two_boats_meeting_without_the_filter_are_a_near_collision_at_the_default_radius():
    m = InProcessFleet(_scenario()).run().metrics
    p = m.closest_pair
    assert (p.domain, p.a, p.b, p.both_live) == ("usv", "b1", "b2", True)
    assert p.distance_m == m.min_separation_m < 0.5
    assert 2.5 < p.t_s < 3.5
    assert m.closest_pairs == {"usv": p}
    assert m.near_collision is True and m.safety == SafetyInfo(enabled=False, radius_m=2.0)
    [line] = closest_lines(m)
    assert line.startswith(f"  closest approach (boats): b1 - b2 {p.distance_m:.3f} m at t = {p.t_s:.2f} s, "
                           "both live")
    assert line.endswith("[NEAR COLLISION: below the [safety] radius 2 m; the filter is off]")
    assert line in summary_table(m, _scenario().vehicles).splitlines()


def test_the_off_radius_is_the_safety_tables_and_a_pass_beyond_it_is_no_near_collision():
    m = InProcessFleet(_scenario({"enabled": False, "radius": 0.1})).run().metrics
    assert m.near_collision is False and m.safety.radius_m == 0.1
    assert "NEAR COLLISION" not in closest_lines(m)[0]


def test_with_the_filter_the_pair_keeps_the_radius_and_interventions_are_recorded_per_vehicle():
    sc = _scenario({"enabled": True, "radius": 1.0, "range": 5.0, "rate": 10.0, "latency": 0.02})
    res = InProcessFleet(sc).run()
    m = res.metrics
    assert m.closest_pair.distance_m >= 1.0 - 0.01
    assert m.near_collision is (m.closest_pair.distance_m < 1.0)
    counts = res.recorder.view("interventions")
    assert m.interventions > 0 and counts[-1].sum() == m.interventions
    assert (counts[-1] > 0).all()  # both boats took their half
    assert (counts[1:] >= counts[:-1]).all() and counts[0].sum() == 0
    line = closest_lines(m)[0]
    if m.near_collision:
        assert line.endswith("[NEAR COLLISION: below the safety radius 1 m]")
    else:
        assert "NEAR COLLISION" not in line


def test_without_the_filter_the_recorder_counts_no_interventions():
    res = InProcessFleet(_scenario()).run()
    assert not res.recorder.view("interventions").any()


def test_a_killed_boat_is_an_obstacle_where_it_died_and_the_pair_says_it_was_not_live():
    """Both sail north, b2 1 m ahead of b1 on a line 0.3 m to the east; b2 is killed at 1 s,
    at (0.3, -2), and b1 passes 0.3 m from the wreck at about 2 s."""
    sc = _scenario(events=[{"at": 1.0, "action": "kill", "vehicle": "b2"}],
                   vehicles=[_line("b1", [0.0, 0.0], [0.0, -1.0], 4.0), _line("b2", [0.3, 0.0], [0.0, -1.0], 3.0)])
    m = InProcessFleet(sc).run().metrics
    p = m.closest_pair
    assert (p.a, p.b, p.a_live, p.b_live, p.both_live) == ("b1", "b2", True, False, False)
    assert p.distance_m == pytest.approx(0.3, abs=0.05) and p.t_s > 1.0
    assert "b2 not live then (killed or paused: counted where it stopped)" in closest_lines(m)[0]


def test_lines_of_every_domain_and_of_old_metrics():
    base = InProcessFleet(_scenario({"enabled": True, "radius": 2.0, "range": 5.0, "rate": 10.0,
                                     "latency": 0.02}, duration=0.2)).run().metrics.to_dict()
    m = {**base, "closest_pairs": {
        "uav": {"domain": "uav", "a": "d1", "b": "d2", "distance_m": 2.5, "t_s": 3.0, "a_live": True,
                "b_live": True, "both_live": True},
        "uav-usv": {"domain": "uav-usv", "a": "b1", "b": "d1", "distance_m": 1.25, "t_s": 4.5, "a_live": False,
                    "b_live": False, "both_live": False}}}
    drones, cross = closest_lines(Metrics.from_dict(m))
    assert drones == "  closest approach (drones): d1 - d2 2.500 m at t = 3.00 s, both live  (the filter kept the 2 m radius)"
    assert cross == ("  closest approach (drone to boat at the surface): b1 - d1 1.250 m at t = 4.50 s, b1 and d1 "
                     "not live then (killed or paused: counted where it stopped)  "
                     "[NEAR COLLISION: below the safety radius 2 m]")
    old = {k: v for k, v in base.items() if k not in ("closest_pairs", "closest_pair", "near_collision")}
    assert closest_lines(Metrics.from_dict(old)) == []  # metrics from before the field


def test_the_summary_of_a_run_whose_remote_vehicles_never_came_up_says_so():
    """Not "killed or paused" for vehicles that never came up (a --remote one nobody
    started): the world's metrics name them (``never_up``), the others were up and waiting."""
    from cdus.app.report import summary_table
    from cdus.core.metrics import Recorder
    from cdus.scenario.config import load_scenario
    from cdus.sim.build import metric_edges
    from cdus.sim.summary import run_metrics

    sc = load_scenario("configs/lake_circle.toml")
    rec = Recorder(list(sc.ids), [v.dim for v in sc.vehicles], metric_edges(sc))
    m = run_metrics(sc, rec, mode="lockstep", link=None, wall_s=0.0, policy="hold", completed=False,
                    completion="not_started", never_up=["usv1", "uav2"])
    text = summary_table(m, sc.vehicles)
    assert "killed or paused" not in text
    assert "NOT STARTED: usv1, uav2 never came up; the run did not begin" in text
    rows = {ln.split()[0]: ln for ln in text.splitlines()[3:9]}
    assert rows["usv1"].endswith("(never came up)") and rows["uav2"].endswith("(never came up)")
    assert rows["usv2"].endswith("(up, waiting for the others: the run never started)")


def test_the_summary_says_why_usv_3dof_boats_never_settle_on_the_path():
    from cdus.app.report import summary_table
    from cdus.scenario.config import load_scenario
    from cdus.sim.fleet import InProcessFleet

    sc = load_scenario("configs/lake_circle_dynamic.toml", {"scenario.duration": 5.0})
    m = InProcessFleet(sc).run().metrics
    m = replace(m, path_settle_s=None, path_tol=0.15,
                final_path_error={**m.final_path_error, "usv1": 0.1, "usv2": 0.2261, "usv3": 0.12})
    text = summary_table(m, sc.vehicles)
    assert "note: usv_3dof boats hold a steady offset from their path" in text
    assert "usv2 ended 0.226 m off, above path_tol 0.15 m; set [metrics] path_tol above it" in text
    m = replace(m, final_path_error={**m.final_path_error, "usv2": 0.1})  # the drones' are not the boats' offset
    assert "note:" not in summary_table(m, sc.vehicles)
