"""End to end (rev-gs): formation and path changes at the edges, lockstep == in process to the bit.

Scheduled in [[event]]: a phase change and a path change at t = 0 (tick 0), offsets closing a
3-cycle with a 1e-9 edge, a kill and restart of a vehicle between changes (the restarted process
builds its schedule from the file and rejoins where the run is), a Lissajous path with numbers at
the limits the checks allow (an amplitude of 1e6, a frequency of 1e-6), a phase of -1e9 one tick
before the end, a path change at the run's end (its last tick) and one past it (never applied).
The process fleet's trace equals `cdus sim`'s, field by field; before the fix the restart's
tick differed in the last bit (the in-process fleet rejoined the restarted node twice)."""

from __future__ import annotations

import math

import numpy as np

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.sim.runmetrics import Metrics

from .conftest import fleet_processes, unique_fleet
from .test_formation import BETA, SCENARIO

EDGES = f"""
[[event]]
at = 0.0
action = "formation"
phases = {{ usv2 = {math.pi / BETA!r} }}

[[event]]
at = 0.0
action = "path"
vehicle = "usv1"
path = {{ family = "ellipse", center = [0, 0], a = 12, b = 8, rotation = 1e6 }}

[[event]]
at = 1.0
action = "formation"
offsets = [{{ i = "uav1", k = "usv2", delta = -3.5 }}, {{ i = "usv2", k = "usv1", delta = 1e-9 }}, {{ i = "usv1", k = "uav1", delta = {3.5 - 1e-9!r} }}]

[[event]]
at = 1.5
action = "kill"
vehicle = "usv2"

[[event]]
at = 2.0
action = "restart"
vehicle = "usv2"

[[event]]
at = 2.5
action = "path"
vehicle = "uav1"
path = {{ family = "lissajous", center = [0, 0, 20], amplitude = [1e6, 1e-6, 3], frequency = [1e-6, 1, 2], phase = [0.3, 0.1, 1.7] }}

[[event]]
at = 5.95
action = "formation"
phases = {{ uav1 = -1e9 }}

[[event]]
at = 6.0
action = "path"
vehicle = "usv2"
path = {{ family = "line", origin = [0, 0], heading = [1e-6, 0] }}

[[event]]
at = 7.0
action = "path"
vehicle = "usv1"
path = {{ family = "circle", center = [0, 0], radius = 3 }}
"""


def test_lockstep_with_changes_at_the_edges_reproduces_the_in_process_run(tmp_path, launches):
    cfg = tmp_path / "edges.toml"
    cfg.write_text(SCENARIO + EDGES)
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches([str(cfg), "--clock", "lockstep", "--logs", str(run), "--trace-out", str(tmp_path / "trace.npz"),
                   "--rerun", "off", "-q"], fleet)
    assert la.wait() == 0, la.output()
    ref = InProcessFleet(load_scenario(str(cfg))).run()
    trace = np.load(tmp_path / "trace.npz")
    for name in ("q", "omega", "omega_rate", "path_error", "heading"):
        mine = ref.recorder.view(name)
        differ = np.argwhere(~((trace[name] == mine) | (np.isnan(trace[name]) & np.isnan(mine))))
        assert trace[name].shape == mine.shape and not len(differ), (name, differ[:3])
    metrics = Metrics.read(run / "metrics.json")
    changes = [(e.kind, e.t, e.vehicle) for e in metrics.events if e.kind.endswith("_changed")]
    assert changes == [(e.kind, e.t, e.vehicle) for e in ref.metrics.events
                       if e.kind.endswith("_changed")]
    assert ("path_changed", 6.0, "usv2") in changes and not any(t > 6.0 for _, t, _ in changes)
    assert metrics.final_coord_error_max == ref.metrics.final_coord_error_max
    assert not fleet_processes(fleet)
