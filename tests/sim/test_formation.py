"""In process: a formation change the fleet settles to, measured against the new offsets, and a
path change that takes a drone to a new circle (issue 18)."""

from __future__ import annotations

import math

import numpy as np

from cdus.scenario.config import parse_scenario
from cdus.sim.fleet import InProcessFleet

BETA = 0.2  # speed 2 m/s on r = 10 m: a lap is 2π/β in ω units


def scenario(events=(), duration=30.0):
    def circle(z=None, center=(0, 0), radius=10, speed=2.0):
        return {"family": "circle", "center": [*center] + ([] if z is None else [z]), "radius": radius,
                "speed": speed}
    return parse_scenario({
        "scenario": {"name": "formation", "duration": duration}, "rates": {"control": 20},
        "graph": {"topology": "ring"},
        "vehicle": [{"id": "usv1", "kind": "usv", "path": circle(), "phase": 0.0},
                    {"id": "usv2", "kind": "usv", "path": circle(), "phase": 2 * math.pi / 3 / BETA},
                    {"id": "uav1", "kind": "uav", "path": circle(20), "phase": 4 * math.pi / 3 / BETA}],
        "event": list(events)})


HALF_LAP = math.pi / BETA


def test_a_scheduled_phase_change_is_settled_to_and_measured_against_the_new_offsets():
    """The formation starts settled (on the path, at its phases); at 5 s usv2 moves half a lap
    from usv1 and uav1 onto usv1: the coordination error against the new offsets jumps, then
    goes back under coord_tol and stays there."""
    sc = scenario([{"at": 5.0, "action": "formation", "phases": {"usv2": HALF_LAP, "uav1": 0.0}}])
    run = InProcessFleet(sc).run()
    rec, m = run.recorder, run.metrics
    t = rec.view("t")
    _, worst = rec.worst_errors()
    before, after = worst[t < 5.0 - 1e-9], worst[t >= 5.0 - 1e-9]
    assert before.max() < 1e-6  # settled to the old formation
    assert after[0] > 10.0  # the new offsets are what is measured from the change's tick
    assert 5.0 < m.coord_settle_s < 25.0 and m.final_coord_error_max < sc.coord_tol
    w = rec.view("omega")[-1]
    assert abs((w[1] - w[0]) - HALF_LAP) < sc.coord_tol and abs(w[2] - w[0]) < sc.coord_tol
    kinds = [(e.kind, e.t) for e in m.events]
    assert ("formation_changed", 5.0) in kinds


def test_a_commanded_change_equals_the_same_change_scheduled_to_the_bit():
    ev = {"at": 5.0, "action": "formation", "phases": {"usv2": HALF_LAP}}
    path = {"family": "circle", "center": [30.0, 0.0, 20.0], "radius": 5.0, "speed": 1.0}
    scheduled = InProcessFleet(scenario([ev, {"at": 6.0, "action": "path", "vehicle": "uav1", "path": path}],
                                        duration=10.0)).run()
    fleet = InProcessFleet(scenario(duration=10.0))
    fleet.set_formation({"usv2": HALF_LAP}, 100, by="gs1")
    fleet.set_path("uav1", path, 120, by="gs1")
    commanded = fleet.run()
    for name in ("q", "omega", "path_error"):
        assert np.array_equal(scheduled.recorder.view(name), commanded.recorder.view(name)), name
    assert np.array_equal(scheduled.recorder.edge_error(), commanded.recorder.edge_error())


def test_a_path_change_takes_a_drone_to_its_new_circle():
    """At 5 s uav1 is sent to a circle of r = 5 m centred 30 m away (speed 1 m/s, β = 0.2 as
    before, so its phase still means the same fraction of a lap): it gets there, on the path,
    and the formation settles again."""
    path = {"family": "circle", "center": [30.0, 0.0, 20.0], "radius": 5.0, "speed": 1.0}
    sc = scenario([{"at": 5.0, "action": "path", "vehicle": "uav1", "path": path}], duration=40.0)
    run = InProcessFleet(sc).run()
    rec, m = run.recorder, run.metrics
    q = rec.view("q")[-1, 2]
    assert abs(math.hypot(q[0] - 30.0, q[1]) - 5.0) < 0.05 and abs(q[2] - 20.0) < 0.05
    pe = rec.view("path_error")[:, 2]
    t = rec.view("t")
    assert pe[t < 5.0 - 1e-9].max() < 0.05 and pe[np.searchsorted(t, 5.0 - 1e-9)] > 20.0  # measured on the new path
    assert m.final_path_error["uav1"] < sc.path_tol and m.final_coord_error_max < sc.coord_tol
    assert any(e.kind == "path_changed" and e.vehicle == "uav1" and e.t == 5.0 for e in m.events)
