"""End to end: the world's closest pair and near-collision flag are the in-process run's
(lockstep), and in realtime what the world's own rows say (one builder, cdus.sim.summary)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cdus.core.metrics import closest_pairs
from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.sim.runmetrics import ClosestPair, Metrics

from .conftest import fleet_processes, unique_fleet

ARGS = ["configs/crossing.toml", "--duration", "3", "--set", "safety.enabled=false", "-q"]


def _run(launches, tmp_path, clock):
    fleet = unique_fleet()
    run = tmp_path / clock
    la = launches([*ARGS, "--clock", clock, "--logs", str(run), "--trace-out", str(tmp_path / f"{clock}.npz")], fleet)
    assert la.wait() == 0, la.output()
    assert not fleet_processes(fleet)
    return Metrics.read(run / "metrics.json"), np.load(tmp_path / f"{clock}.npz")


def test_lockstep_names_the_same_closest_pair_as_the_in_process_run(tmp_path, launches):
    """usv_a1 and usv_b1 come within 1.07 m at 1.18 s without the filter: a near collision."""
    metrics, _ = _run(launches, tmp_path, "lockstep")
    ref = InProcessFleet(load_scenario("configs/crossing.toml", {"scenario.duration": 3.0,
                                                                 "safety.enabled": False})).run().metrics
    assert ref.near_collision is True and ref.closest_pair.a == "usv_a1"
    assert metrics.near_collision is True
    for domain, p in ref.closest_pairs.items():
        got = metrics.closest_pairs[domain]
        assert got.distance_m == pytest.approx(p.distance_m, abs=1e-6)
        assert replace(got, distance_m=0.0) == replace(p, distance_m=0.0)
    assert metrics.closest_pairs.keys() == ref.closest_pairs.keys()


def test_realtime_closest_pair_is_the_one_its_rows_show(tmp_path, launches):
    metrics, trace = _run(launches, tmp_path, "realtime")
    kinds = [v.kind for v in load_scenario("configs/crossing.toml").vehicles]
    pairs = closest_pairs(trace["t"], trace["q"], trace["live"], list(trace["ids"]), kinds)
    assert {d: ClosestPair(**p.as_dict()) for d, p in pairs.items()} == metrics.closest_pairs
    assert metrics.closest_pair == metrics.closest_pairs["usv"]
    assert metrics.near_collision is (metrics.closest_pair.distance_m < 2.0)
