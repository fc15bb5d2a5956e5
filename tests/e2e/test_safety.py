"""End to end: the safety filter in a lockstep fleet of processes, fed by the world's
proximity sensor, reproduces the in-process run bit for bit."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet

from .conftest import fleet_processes, unique_fleet


def test_lockstep_with_the_safety_filter_reproduces_the_in_process_run(tmp_path, launches):
    """crossing.toml for 6 s: usv_a1 and usv_b1 meet at the upper crossing at about 2 s, so
    the filter intervenes (contacts sampled at 10 Hz, used one tick later) in both runs."""
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches(["configs/crossing.toml", "--clock", "lockstep", "--duration", "6",
                   "--logs", str(run), "--trace-out", str(tmp_path / "trace.npz"), "-q"], fleet)
    assert la.wait() == 0, la.output()
    sc = load_scenario("configs/crossing.toml", {"scenario.duration": 6.0})
    ref = InProcessFleet(sc).run()
    assert ref.metrics["interventions"] > 0
    trace = np.load(tmp_path / "trace.npz")
    for name in ("q", "omega", "omega_rate", "path_error", "heading"):
        diff = np.abs(trace[name] - ref.recorder.view(name)).max()
        assert diff < 1e-9, (name, diff)
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["completed"] is True
    assert metrics["interventions"] == ref.metrics["interventions"]
    assert metrics["min_separation_m"] == pytest.approx(ref.metrics["min_separation_m"], abs=1e-9)
    assert not fleet_processes(fleet)


def test_lockstep_with_the_dynamic_filter_reproduces_the_in_process_run(tmp_path, launches):
    """crossing_dynamic.toml (usv_3dof boats) for 6 s: the filter acts on τ_u at every physics
    step from the first second (usv_a1 and usv_b1 start 2.07 m apart), with velocities
    estimated from the sensor's samples: a pure function of what both runners give it."""
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches(["configs/crossing_dynamic.toml", "--clock", "lockstep", "--duration", "6",
                   "--logs", str(run), "--trace-out", str(tmp_path / "trace.npz"), "-q"], fleet)
    assert la.wait() == 0, la.output()
    sc = load_scenario("configs/crossing_dynamic.toml", {"scenario.duration": 6.0})
    ref = InProcessFleet(sc).run()
    assert ref.metrics["interventions"] > 0
    trace = np.load(tmp_path / "trace.npz")
    for name in ("q", "omega", "omega_rate", "path_error", "heading"):
        diff = np.abs(trace[name] - ref.recorder.view(name)).max()
        assert diff == 0.0, (name, diff)
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["completed"] is True
    assert metrics["interventions"] == ref.metrics["interventions"]
    assert metrics["min_separation_m"] == ref.metrics["min_separation_m"]
    assert not fleet_processes(fleet)
