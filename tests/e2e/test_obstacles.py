"""End to end: [[obstacle]]s in a lockstep fleet of processes reproduce the in-process run bit
for bit, the obstacles block of the metrics included."""

from __future__ import annotations

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.sim.runmetrics import Metrics

from .conftest import assert_same_trace, fleet_processes, unique_fleet

CONFIG = "configs/island_crossing.toml"
# every vehicle 27 s further back along its path, the formation kept: the boats reach the island
# and the pier within 3 s (the filter's obstacle rows act from then on), 8 s is enough
LEAD = 27.0
PHASES = {"usv_a": 0.0, "usv_b": 31.41592653589793, "uav_a": 15.707963267948966, "uav_b": 47.12388980384689}
STARTS = {f"vehicle.{v}.omega0": th - LEAD for v, th in PHASES.items()}


def test_lockstep_with_obstacles_reproduces_the_in_process_run(tmp_path, launches):
    fleet = unique_fleet()
    run = tmp_path / "run"
    sets = [a for k, v in STARTS.items() for a in ("--set", f"{k}={v!r}")]
    la = launches([CONFIG, "--clock", "lockstep", "--duration", "8", "--logs", str(run), "--rerun", "off",
                   "--trace-out", str(tmp_path / "trace.npz"), "-q", *sets], fleet)
    assert la.wait() == 0, la.output()
    ref = InProcessFleet(load_scenario(CONFIG, {**STARTS, "scenario.duration": 8.0})).run()
    ob = ref.metrics.obstacles
    assert ob.vehicles["usv_a"]["deflected_s"] > 0 and ob.vehicles["usv_b"]["deflected_s"] > 0
    assert_same_trace(tmp_path / "trace.npz", ref)
    metrics = Metrics.read(run / "metrics.json")
    assert metrics.completed is True
    assert metrics.obstacles == ob  # clearances from the same positions, deflected steps from the agents' stats
    assert not fleet_processes(fleet)
