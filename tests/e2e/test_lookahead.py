"""End to end: the lockstep lookahead (a tick waits only for the broadcasts it can use) and the
horizon grants keep a fleet of processes equal to `cdus sim` to the bit: broadcasts slower
than the control loop, link delays fixed and jittered, and a run-time link change that lowers
the delay."""

from __future__ import annotations

import queue

import numpy as np
import pytest
import zenoh

from cdus.scenario.config import load_scenario
from cdus.scenario.link import validate_link
from cdus.sim.fleet import InProcessFleet
from cdus.sim.runmetrics import Metrics
from cdus.wire import keys
from cdus.wire.messages import encode_control
from cdus.wire.schemas import decode_event
from cdus.wire.transport import Transport, free_tcp_port, open_session
from cdus.wire.rejected import Rejected

from .conftest import fleet_processes, unique_fleet

TRACE = ("q", "omega", "omega_rate", "path_error", "heading")
METRICS = ("duration_s", "path_settle_s", "coord_settle_s", "final_path_error_max", "final_coord_error_max",
           "omega_rate_final")


def assert_same(tmp_path, run, ref) -> None:
    trace = np.load(tmp_path / "trace.npz")
    for name in TRACE:
        assert np.array_equal(trace[name], ref.recorder.view(name), equal_nan=True), name
    metrics = Metrics.read(run / "metrics.json")
    assert metrics.mode == "lockstep" and metrics.completed is True
    for field in METRICS:
        assert getattr(metrics, field) == getattr(ref.metrics, field), field
    assert metrics.link.delivered == ref.metrics.link.delivered
    assert metrics.link.dropped == ref.metrics.link.dropped


@pytest.mark.parametrize("settings", [
    {"rates.broadcast": 10.0},
    {"link.delay.base": 0.1},
    {"link.delay.base": 0.1, "link.delay.jitter": 0.04, "link.loss": 0.1},
    {"rates.broadcast": 10.0, "link.delay.base": 0.06, "link.delay.jitter": 0.03, "link.delay.distribution": "pareto"},
], ids=["broadcast 10 Hz", "delay 0.1 s", "delay 0.1 +- 0.04 s, loss", "10 Hz, pareto delay"])
def test_lockstep_with_lookahead_reproduces_the_in_process_run(tmp_path, launches, settings):
    fleet = unique_fleet()
    run = tmp_path / "run"
    sets = [a for k, v in settings.items() for a in ("--set", f"{k}={v}")]
    la = launches(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", "20", *sets, "--logs", str(run),
                   "--trace-out", str(tmp_path / "trace.npz"), "-q", "--rerun", "off"], fleet)
    assert la.wait(timeout=300) == 0, la.output()
    ref = InProcessFleet(load_scenario("configs/lake_circle.toml", {"scenario.duration": 20.0, **settings})).run()
    assert_same(tmp_path, run, ref)
    assert not fleet_processes(fleet)


def test_a_run_time_link_change_that_lowers_the_delay_reproduces_the_in_process_run(tmp_path, launches):
    """Delay 0.2 ± 0.05 s (a least delay of 8 ticks: the vehicles step 8 ticks ahead of their
    neighbours' newest ω) lowered at t = 40 s to 0.04 ± 0.02 s (1 tick): from the tick the
    change applies every vehicle waits for the newer broadcasts the lower delay makes usable."""
    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    base = {"scenario.duration": 50.0, "link.delay.base": 0.2, "link.delay.jitter": 0.05}
    sets = [a for k, v in base.items() if k != "scenario.duration" for a in ("--set", f"{k}={v}")]
    la = launches(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", "50", *sets,
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run), "--trace-out", str(tmp_path / "trace.npz"),
                   "-q", "--insecure", "--rerun", "off"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    change = {"delay": {"base": 0.04, "jitter": 0.02}}
    session = open_session(Transport(mode="client", connect=(f"tcp/127.0.0.1:{port}",)))
    heard: queue.Queue = queue.Queue()
    session.declare_subscriber(keys.world_events(fleet), lambda s: heard.put(decode_event(s.payload.to_bytes())))
    try:
        session.put(keys.world_cmd(fleet, "test"), encode_control("link", link=change, at=40.0),
                    congestion_control=zenoh.CongestionControl.BLOCK)
        while True:
            e = heard.get(timeout=120)
            if not isinstance(e, Rejected) and e.kind == "link_changed":
                break
    finally:
        session.close()
    assert "from t = 40.00 s" in e.text, e.text  # not yet granted: it applies where asked
    assert la.wait(timeout=300) == 0, la.output()
    sc = load_scenario("configs/lake_circle.toml", base)
    ref = InProcessFleet(sc)
    while ref.tick < 2000:
        ref.step()
    ref.link.update(validate_link({"delay": {"base": 0.04, "jitter": 0.02}}, list(sc.ids), "change"), 40.0)
    assert_same(tmp_path, run, ref.run())
    assert not fleet_processes(fleet)
