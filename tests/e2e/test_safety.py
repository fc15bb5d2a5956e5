"""End to end: the safety filter in a lockstep fleet of processes, fed by the world's
proximity sensor, reproduces the in-process run bit for bit."""

from __future__ import annotations


import pytest

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.sim.runmetrics import Metrics

from .conftest import assert_same_trace, fleet_processes, unique_fleet


@pytest.mark.parametrize("config", ["configs/crossing.toml", "configs/crossing_dynamic.toml"])
def test_lockstep_with_the_safety_filter_reproduces_the_in_process_run(tmp_path, launches, config):
    """6 s of each. crossing.toml (ideal plants): usv_a1 and usv_b1 meet at the upper
    crossing at about 2 s, so the velocity-level filter intervenes (contacts sampled at 10 Hz,
    used one tick later). crossing_dynamic.toml (usv_3dof boats): the dynamic filter acts on
    τ_u at every physics step from the first second (usv_a1 and usv_b1 start 2.07 m apart),
    with velocities estimated from the sensor's samples. Both are pure functions of what the
    two runners give them: equal to the bit."""
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches([config, "--clock", "lockstep", "--duration", "6",
                   "--logs", str(run), "--trace-out", str(tmp_path / "trace.npz"), "-q"], fleet)
    assert la.wait() == 0, la.output()
    sc = load_scenario(config, {"scenario.duration": 6.0})
    ref = InProcessFleet(sc).run()
    assert ref.metrics.interventions > 0
    assert_same_trace(tmp_path / "trace.npz", ref)
    metrics = Metrics.read(run / "metrics.json")
    assert metrics.completed is True
    assert metrics.interventions == ref.metrics.interventions  # a completed run: every count reported
    assert metrics.min_separation_m == ref.metrics.min_separation_m
    assert not fleet_processes(fleet)
