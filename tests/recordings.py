"""How does a test get a saved Rerun recording of a short in-process run? ``record`` writes one."""

from __future__ import annotations

from pathlib import Path

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from world_sim.sinks import make_sink


def record(config: str | Path, rrd: Path, duration: float) -> Path:
    """``config`` run in process for ``duration`` simulated s, saved to ``rrd`` (returned)."""
    sink = make_sink(f"save:{rrd}")
    InProcessFleet(load_scenario(config, {"scenario.duration": duration}), sink=sink).run()
    sink.close()
    return rrd
