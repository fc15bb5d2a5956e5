"""End to end: a run says it completed only when it did (docs/metrics.md, ``completed``).

- The router (inside the launcher) frozen for 5 s: every vehicle drops at once, the world
  waits for the fleet, the run finishes and matches the clean run.
- Forged telemetry rows from an outsider, far in the future: rejected, the run goes on to
  its end and matches the clean run.
- Two vehicles SIGKILLed with restarts off: ``completed`` false, ``completion`` "vehicles_lost".
"""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest
import zenoh

from cdus.sim.runmetrics import Metrics
from cdus.wire import keys
from cdus.wire.messages import StateMsg, encode_states
from cdus.wire.transport import free_tcp_port
from tests.outsider import raw_client

from .conftest import fleet_processes, unique_fleet

DURATION = "40"  # s simulated: ~4 s of wall time, long enough to be frozen in the middle
SAME = ("duration_s", "path_settle_s", "coord_settle_s", "final_path_error_max", "final_coord_error_max",
        "omega_rate_final", "final_path_error", "live_final", "min_separation_m")


def lockstep_run(launches, tmp_path, name: str, port: int | None = None, extra=()):
    fleet = unique_fleet()
    run = tmp_path / name
    args = ["configs/lake_circle.toml", "--clock", "lockstep", "--duration", DURATION, "--seed", "1",
            "--logs", str(run), "--trace-out", str(tmp_path / f"{name}.npz"), *extra]
    if port is not None:
        args += ["--listen", f"tcp/127.0.0.1:{port}"]
    return launches(args, fleet), fleet, run


def results(tmp_path, run, name):
    return Metrics.read(run / "metrics.json"), np.load(tmp_path / f"{name}.npz")


def assert_same_run(a, b):
    (ma, ta), (mb, tb) = a, b
    for f in SAME:
        assert getattr(ma, f) == getattr(mb, f), f
    for name in ("q", "omega", "omega_rate", "path_error", "heading", "live"):
        assert np.array_equal(ta[name], tb[name]), name


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """The clean run, once for the module (its own launcher, killed if it hangs)."""
    from .conftest import Launch
    tmp = tmp_path_factory.mktemp("clean")
    fleet = unique_fleet()
    la = Launch(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", DURATION, "--seed", "1",
                 "--logs", str(tmp / "run"), "--trace-out", str(tmp / "clean.npz"), "-q", "--fleet", fleet])
    try:
        assert la.wait() == 0, la.output()
    finally:
        la.kill()
    m = Metrics.read(tmp / "run" / "metrics.json")
    assert m.completed is True and m.completion == "completed"
    return m, np.load(tmp / "clean.npz")


def test_a_router_frozen_for_5_s_is_waited_for_and_the_run_matches_the_clean_one(tmp_path, launches, clean):
    la, fleet, run = lockstep_run(launches, tmp_path, "frozen")
    la.wait_for(f"fleet '{fleet}' up")
    time.sleep(1.0)  # under way
    os.kill(la.proc.pid, signal.SIGSTOP)
    try:
        time.sleep(5.0)
    finally:
        os.kill(la.proc.pid, signal.SIGCONT)
    assert la.wait(timeout=180) == 0, la.output()
    got = results(tmp_path, run, "frozen")
    assert got[0].completed is True and got[0].completion == "completed", la.output()
    assert got[0].live_final == clean[0].live_final and np.array_equal(got[1]["live"], clean[1]["live"])
    assert not [e for e in got[0].events if e.kind == "vehicle_lost"], got[0].events
    # an ω lost in flight while the router was frozen is said again by its sender and taken as
    # a gap filled (cdus.core.node), so the run is the clean one, bit for bit
    assert_same_run(got, clean)
    assert not fleet_processes(fleet)


def test_forged_telemetry_from_an_outsider_does_not_end_the_run(tmp_path, launches, clean):
    port = free_tcp_port()
    la, fleet, run = lockstep_run(launches, tmp_path, "forged", port, extra=["--insecure"])  # an open fleet's validation
    la.wait_for(f"fleet '{fleet}' up")
    session = zenoh.open(raw_client(f"tcp/127.0.0.1:{port}"))
    try:
        for j, vid in enumerate(["usv1", "usv2", "usv3", "uav1", "uav2", "uav3"]):
            q = (0.0, 0.0) if j < 3 else (0.0, 0.0, 20.0)
            session.put(keys.state(fleet, vid), encode_states([StateMsg(j, 6000, 120.0, q, 0.0, 1.0, 0.0, -1.0, 0.0)]))
        assert la.wait(timeout=180) == 0, la.output()
    finally:
        session.close()
    got = results(tmp_path, run, "forged")
    assert got[0].completed is True, la.output()
    assert got[0].rejected_by_reason.world.get("future", 0) >= 1, got[0].rejected_by_reason
    assert_same_run(got, clean)


def test_two_vehicles_killed_with_restarts_off_is_not_a_completed_run(tmp_path, launches):
    la, fleet, run = lockstep_run(launches, tmp_path, "killed", extra=["--restart", "never"])
    la.wait_for(f"fleet '{fleet}' up")
    time.sleep(1.0)
    for vid in ("usv2", "uav3"):
        line = [ln for ln in fleet_processes(fleet) if f"--id {vid}" in ln]
        assert line, fleet_processes(fleet)
        os.kill(int(line[0].split()[0]), signal.SIGKILL)
    code = la.wait(timeout=180)
    m = Metrics.read(run / "metrics.json")
    assert m.completed is False and m.completion == "vehicles_lost", la.output()
    # a run that failed exits 1, not 0 beside "completed: false" (attacker review)
    assert code == 1 and "error: the run did not complete: vehicles_lost" in la.output(), (code, la.output())
    assert m.final_path_error["usv2"] != 0.0
    assert not fleet_processes(fleet)
