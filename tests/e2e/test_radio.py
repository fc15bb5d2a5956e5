"""End to end: with [radio] on, a lockstep fleet of processes (the world samples the
geometry, the agents wait for the sample in force and decide each message with the radio
channel) reproduces the in-process run bit for bit: the trace, the radio counters by cause,
the utilisation and the split/rejoin events."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet

from .conftest import fleet_processes, unique_fleet

RADIO_KINDS = ("radio_split", "radio_joined")


@pytest.mark.parametrize("config, duration", [("configs/lake_radio.toml", 6.0), ("configs/range_out.toml", 24.0)])
def test_lockstep_with_the_radio_reproduces_the_in_process_run(tmp_path, launches, config, duration):
    """lake_radio: 6 s, six vehicles relayed by the shore station (collisions drop some
    messages). range_out: 24 s, the drones leave the station's range at about 19 s: the
    split is reported by the world as by the in-process fleet, at the same time."""
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches([config, "--clock", "lockstep", "--duration", str(duration),
                   "--logs", str(run), "--trace-out", str(tmp_path / "trace.npz"), "-q"], fleet)
    assert la.wait() == 0, la.output()
    sc = load_scenario(config, {"scenario.duration": duration})
    ref = InProcessFleet(sc).run()
    trace = np.load(tmp_path / "trace.npz")
    for name in ("q", "omega", "omega_rate", "path_error", "heading"):
        diff = np.abs(trace[name] - ref.recorder.view(name)).max()
        assert diff == 0.0, (name, diff)
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["completed"] is True
    radio, expected = metrics["radio"], ref.metrics["radio"]
    assert radio["sent"] > 0 and radio["dropped"] > 0
    assert radio == expected
    ours = [(e["t"], e["kind"], e["text"]) for e in metrics["events"] if e["kind"] in RADIO_KINDS]
    theirs = [(e["t"], e["kind"], e["text"]) for e in ref.metrics["events"] if e["kind"] in RADIO_KINDS]
    assert ours == theirs
    if "range_out" in config:
        assert [k for _, k, _ in ours] == ["radio_split"]
        assert radio["dropped_by"]["range"] > 0
    assert not fleet_processes(fleet)
