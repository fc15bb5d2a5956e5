"""End to end: with [radio] on, a lockstep fleet of processes (the world samples the
geometry, the agents wait for the sample in force and decide each message with the radio
channel) reproduces the in-process run bit for bit: the trace, the radio counters by cause,
the utilisation and the split/rejoin events."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet

from .conftest import ROOT, fleet_processes, unique_fleet

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


RESTART = """
[[event]]
at = 3.0
action = "kill"
vehicle = "uav2"

[[event]]
at = 5.0
action = "restart"
vehicle = "uav2"

[[event]]
at = 7.0
action = "radio"
tx_power = -10.0
"""


def test_a_restarted_vehicle_gets_the_geometry_in_force_and_the_run_stays_equal(tmp_path, launches):
    """range_out for 10 s with uav2 killed at 3 s and restarted at 5 s, and a scheduled radio
    change at 7 s (-10 dBm: the station hears nobody): the new process is sent the newest
    geometry samples with its catch-up, waits for the one in force, and the fleet
    of processes still equals the in-process run to the bit (the trajectories; the radio
    counters too, but for what the killed process decided since its last report)."""
    config = tmp_path / "range_out_restart.toml"
    config.write_text((ROOT / "configs" / "range_out.toml").read_text() + RESTART)
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches([str(config), "--clock", "lockstep", "--duration", "10", "--logs", str(run),
                   "--trace-out", str(tmp_path / "trace.npz"), "-q"], fleet)
    assert la.wait() == 0, la.output()
    ref = InProcessFleet(load_scenario(config, {"scenario.duration": 10.0})).run()
    trace = np.load(tmp_path / "trace.npz")
    for name in ("q", "omega"):
        assert np.array_equal(trace[name], ref.recorder.view(name)), name
    metrics = json.loads((run / "metrics.json").read_text())
    radio, expected = metrics["radio"], ref.metrics["radio"]
    assert (radio["utilisation"], radio["splits"]) == (expected["utilisation"], expected["splits"])
    # a process killed before its first stats report (about 1 s of wall time) takes its counts
    # along (docs/metrics.md: counts are equal when no process was killed)
    assert 0 < radio["sent"] <= expected["sent"] and radio["sent"] >= expected["sent"] - 3 * 2 * 10
    assert radio["dropped_by"]["range"] == expected["dropped_by"]["range"] > 0  # after 7 s, every process
    assert [e["kind"] for e in metrics["events"] if e["kind"] == "vehicle_back"] == ["vehicle_back"]
    changed = [(e["t"], e["text"]) for e in metrics["events"] if e["kind"] == "radio_changed"]
    assert changed == [(e["t"], e["text"]) for e in ref.metrics["events"] if e["kind"] == "radio_changed"]
    assert changed == [(7.0, "radio: tx_power = -10 dBm from tick 140 (t = 7 s) (scheduled)")]
    assert not fleet_processes(fleet)


def _world_log_value(path, text: str, number: bool = True, timeout: float = 60.0):
    """The number after ``text`` in the first line of the world's log that has it (waits)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        lines = [ln for ln in (path.read_text().splitlines() if path.exists() else []) if text in ln]
        if lines:
            return float(lines[0].split(text)[1].split()[0]) if number else lines[0]
        time.sleep(0.2)
    raise AssertionError(f"no {text!r} in {path} within {timeout} s")


def test_a_ground_station_radio_command_changes_delivery_from_its_time_on(tmp_path, launches):
    """`cdus gs ... radio tx_power=-30 --at 0` on a lockstep lake_radio fleet: the world moves
    the change past its grant, relays it, and from then on the shore station hears nobody
    (range drops); the run up to the stop equals the in-process run given the same change at
    the same time (InProcessFleet.set_radio), to the bit."""
    from cdus.wire.transport import free_tcp_port

    from .test_ground_station import gs

    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    la = launches(["configs/lake_radio.toml", "--clock", "lockstep", "--duration", "3000",
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run),
                   "--trace-out", str(tmp_path / "trace.npz"), "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    assert gs(fleet, port, run, "radio", "tx_power=-300").returncode == 2  # refused before sending
    res = gs(fleet, port, run, "radio", "tx_power=-30", "--at", "0")
    assert res.returncode == 0, res.stderr
    at_text = _world_log_value(run / "logs" / "world.log", "radio changed from t =")
    period = 1.0 / 50.0
    at = round(at_text / period) * period  # the world moved it to the tick after its grant
    _world_log_value(run / "logs" / "world.log", "communication graph split", number=False)  # the station hears nobody
    assert gs(fleet, port, run, "stop").returncode == 0
    assert la.wait(timeout=60) == 0, la.output()
    metrics = json.loads((run / "metrics.json").read_text())
    kinds = [e["kind"] for e in metrics["events"]]
    assert "radio_changed" in kinds
    assert metrics["radio"]["dropped_by"]["range"] > 0
    trace = np.load(tmp_path / "trace.npz")
    sc = load_scenario("configs/lake_radio.toml")
    ref = InProcessFleet(sc)
    ref.set_radio({"tx_power": -30.0}, at)
    out = ref.run(metrics["duration_s"])
    n = len(trace["t"])
    assert n == len(out.recorder) and n * period > at + 0.5
    for name in ("q", "omega"):
        assert np.array_equal(trace[name], out.recorder.view(name)), name
    assert not fleet_processes(fleet)
