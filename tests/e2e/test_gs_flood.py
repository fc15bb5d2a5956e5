"""End to end (rev-gs): a flood of command queries from a ground station changes nothing.

Two floods of 4000 command queries (junk, up to 8 kB each) from one session holding the run's ground
credentials, asked in 0.05 s without waiting, at a secured lockstep fleet. Before the router
dropped command queries it cannot pass on (cdus.wire.transport.COMMANDS_DROP), it held its
routing thread on the world's full link (queries are BLOCK by Zenoh's default) until it closed
that link: the world lost and got back every vehicle, then usv1 was lost for 120-220 s of
simulated time (2 runs of 2 by hand, floods of 3000 at t = 200 s; the result changed), and 1000s of
the queries were never answered. The break depends on the box's load: this test caught it in 0 of
3 runs without the fix on a quiet moment; tests/wire/test_router_qos checks the setting itself."""

from __future__ import annotations

import json

import numpy as np
import zenoh

from cdus.scenario.config import parse_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.wire import keys
from cdus.wire.transport import Transport, free_tcp_port, open_session

from .conftest import fleet_processes, unique_fleet


def test_a_flood_of_command_queries_leaves_a_lockstep_run_as_in_process(tmp_path, launches):
    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    la = launches(["configs/concentric_circles.toml", "--clock", "lockstep", "--duration", "600",
                   "--listen", f"tcp/127.0.0.1:{port}", "--rerun", "off", "--logs", str(run),
                   "--trace-out", str(tmp_path / "trace.npz"), "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    s = open_session(Transport(mode="client", connect=(f"tcp/127.0.0.1:{port}",),
                               config_file=str(run / "secure" / "ground.json5")))
    try:
        key = keys.world_command(fleet, keys.GROUND)
        answered = 0
        for _ in range(2):  # two floods, each read out before the next
            handlers = [s.get(key, payload=bytes([i % 256]) * (i % 8000), timeout=60,
                              consolidation=zenoh.ConsolidationMode.NONE) for i in range(4000)]
            answered += sum(1 for h in handlers for r in h if r.ok is not None)
    finally:
        s.close()
    assert la.wait() == 0, la.output()
    world_log = (run / "logs" / "world.log").read_text()
    assert " lost" not in world_log, world_log[-2000:]
    assert answered > 0
    ref = InProcessFleet(parse_scenario(json.loads((run / "scenario.json").read_text()), "flood")).run()
    trace = np.load(tmp_path / "trace.npz")
    for name in ("q", "omega", "omega_rate", "path_error", "heading"):
        assert np.array_equal(trace[name], ref.recorder.view(name), equal_nan=True), name
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["completed"] is True and metrics["rejected_by_reason"]["world"].get("malformed", 0) > 0
    assert not fleet_processes(fleet)
