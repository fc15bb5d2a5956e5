"""End to end (issue 18): formation and path changes in a fleet of processes.

- a lockstep run with a phase change and a path change scheduled in [[event]] equals the
  in-process run to the bit (every agent and the world apply them on the same tick);
- a ground station's `cdus gs formation` and `cdus gs path` against a running lockstep fleet:
  the formation settles to the new phases, measured against the new offsets."""

from __future__ import annotations

import math
import time

import numpy as np

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.sim.runmetrics import Metrics
from cdus.wire.transport import free_tcp_port

from .conftest import fleet_processes, run_cli, unique_fleet
from .test_ground_station import _world_t

BETA = 0.2
SCENARIO = f"""
[scenario]
name = "formation_change"
duration = 6.0

[rates]
control = 20.0

[graph]
topology = "ring"

[[vehicle]]
id = "usv1"
kind = "usv"
path = {{ family = "circle", center = [0, 0], radius = 10, speed = 2.0 }}

[[vehicle]]
id = "usv2"
kind = "usv"
phase = {2 * math.pi / 3 / BETA!r}
path = {{ family = "circle", center = [0, 0], radius = 10, speed = 2.0 }}

[[vehicle]]
id = "uav1"
kind = "uav"
phase = {4 * math.pi / 3 / BETA!r}
path = {{ family = "circle", center = [0, 0, 20], radius = 10, speed = 2.0 }}
"""
EVENTS = f"""
[[event]]
at = 2.0
action = "formation"
phases = {{ usv2 = {math.pi / BETA!r}, uav1 = 0.0 }}

[[event]]
at = 3.0
action = "path"
vehicle = "uav1"
path = {{ family = "circle", center = [30, 0, 20], radius = 5, speed = 1.0 }}
"""


def test_lockstep_with_a_scheduled_formation_and_path_change_reproduces_the_in_process_run(tmp_path, launches):
    cfg = tmp_path / "formation.toml"
    cfg.write_text(SCENARIO + EVENTS)
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches([str(cfg), "--clock", "lockstep", "--logs", str(run), "--trace-out", str(tmp_path / "trace.npz"),
                   "-q"], fleet)
    assert la.wait() == 0, la.output()
    ref = InProcessFleet(load_scenario(str(cfg))).run()
    trace = np.load(tmp_path / "trace.npz")
    for name in ("q", "omega", "omega_rate", "path_error", "heading", "edge_error"):
        mine = ref.recorder.edge_error() if name == "edge_error" else ref.recorder.view(name)
        assert np.array_equal(trace[name], mine), (name, np.abs(trace[name] - mine).max())
    assert trace["edge_error"][40].max() > 10.0  # measured against the new offsets from tick 40 (2 s)
    metrics = Metrics.read(run / "metrics.json")
    assert metrics.completed is True
    assert metrics.final_coord_error_max == ref.metrics.final_coord_error_max
    changes = [(e.kind, e.t, e.vehicle) for e in metrics.events if e.kind.endswith("_changed")]
    assert changes == [("formation_changed", 2.0, None), ("path_changed", 3.0, "uav1")]
    assert changes == [(e.kind, e.t, e.vehicle) for e in ref.metrics.events
                       if e.kind.endswith("_changed")]
    assert not fleet_processes(fleet)


def gs(fleet: str, port: int, run, *args: str):
    return run_cli(["gs", "--fleet", fleet, "-e", f"tcp/127.0.0.1:{port}",
                    "--zenoh-config", str(run / "secure" / "ground.json5"), *args], timeout=60)


def test_a_ground_stations_phase_and_path_change_is_settled_to_by_a_running_fleet(tmp_path, launches):
    """A long lockstep run; once the fleet is up, the operator moves usv2 half a lap from usv1
    and uav1 onto usv1, and sends uav1 to another circle; 15 s of simulated time later (in
    process it settles 5.5 s after the change), stops it. The formation settled to the new
    offsets: the coordination error, measured against them from the tick the world relayed, is
    under coord_tol at the end; uav1 ends on its new circle."""
    cfg = tmp_path / "formation.toml"
    cfg.write_text(SCENARIO.replace("duration = 6.0", "duration = 3000.0"))
    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    la = launches([str(cfg), "--clock", "lockstep", "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run),
                   "--trace-out", str(tmp_path / "trace.npz"), "-q"], fleet)
    la.wait_for("attach a ground station")
    res = gs(fleet, port, run, "formation", f"phases.usv2={math.pi / BETA!r}", "phases.uav1=0")
    assert res.returncode == 0, res.stderr
    res = gs(fleet, port, run, "path", "--vehicle", "uav1", "family=circle", "center=[30,0,20]", "radius=5",
             "speed=1.0")
    assert res.returncode == 0, res.stderr
    assert gs(fleet, port, run, "formation", "phases.usv2=x").returncode == 2  # refused locally
    assert gs(fleet, port, run, "path", "--vehicle", "uav1", "family=cirle").returncode == 2
    start = _world_t(gs(fleet, port, run, "status", "--once").stdout)
    deadline = time.monotonic() + 120
    t = None
    while time.monotonic() < deadline:
        t = _world_t(gs(fleet, port, run, "status", "--once").stdout)
        if t is not None and start is not None and t > start + 15.0:
            break
    assert t is not None and start is not None and t > start + 15.0
    assert gs(fleet, port, run, "stop").returncode == 0
    assert la.wait(timeout=60) == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    changed = [e for e in m.events if e.kind in ("formation_changed", "path_changed")]
    assert [e.kind for e in changed] == ["formation_changed", "path_changed"], m.events
    assert all("by gs" in e.text for e in changed)
    t_change = changed[0].t
    assert t_change < 50.0
    assert m.completion == "stopped" and m.final_coord_error_max < m.coord_tol, m
    assert m.coord_settle_s is not None and m.coord_settle_s > t_change  # it was off the new offsets first
    assert m.final_path_error["uav1"] < m.path_tol
    assert not fleet_processes(fleet)
    # the same commands given to the in-process fleet at the ticks the world relayed them give
    # the same run, to the bit: every agent applied them on that tick
    sc = load_scenario(str(cfg))
    period = 1.0 / sc.rates.control
    ref = InProcessFleet(sc)
    ref.set_formation({"usv2": math.pi / BETA, "uav1": 0.0}, round(changed[0].t / period))
    ref.set_path("uav1", {"family": "circle", "center": [30, 0, 20], "radius": 5, "speed": 1.0},
                 round(changed[1].t / period))
    trace = np.load(tmp_path / "trace.npz")
    rows = len(trace["t"])
    for _ in range(rows):
        ref.step()
    for name in ("q", "omega", "path_error"):
        assert np.array_equal(trace[name], ref.recorder.view(name)), name
    assert np.array_equal(trace["edge_error"], ref.recorder.edge_error())
