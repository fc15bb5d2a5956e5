"""End to end: a ground station attaches to a running fleet, watches it and commands it.

The fleets are launched as a user would, secured by default: the ground station holds the
run's ground credentials (<run>/secure/ground.json5), as the launcher's printed line says."""

from __future__ import annotations

import re
import time

import pytest

from cdus.sim.runmetrics import Metrics
from cdus.wire.transport import free_tcp_port

from .conftest import fleet_processes, run_cli, unique_fleet


def gs(fleet: str, port: int, run, *args: str):
    return run_cli(["gs", "--fleet", fleet, "-e", f"tcp/127.0.0.1:{port}",
                    "--zenoh-config", str(run / "secure" / "ground.json5"), *args], timeout=60)


def test_ground_station_watches_and_commands_a_running_fleet(tmp_path, launches):
    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    la = launches(["configs/concentric_circles.toml", "--clock", "realtime", "--duration", "600",
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run), "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    la.wait_for("attach a ground station")

    res = gs(fleet, port, run, "status", "--once")
    assert res.returncode == 0, res.stderr
    for vid in ("usv1", "usv2", "uav1", "uav2"):
        assert vid in res.stdout
    assert "world: t =" in res.stdout
    # piped (run_cli captures stdout): one table, no screen clears, no waiting for the run's end
    piped = gs(fleet, port, run, "status")
    assert piped.returncode == 0 and "\033[2J" not in piped.stdout and piped.stdout.count("world: t =") == 1

    typo = run_cli(["gs", "--fleet", fleet + "x", "-e", f"tcp/127.0.0.1:{port}",
                    "--zenoh-config", str(run / "secure" / "ground.json5"), "status", "--once"], timeout=60)
    assert typo.returncode == 3 and f"did you mean --fleet {fleet}?" in typo.stderr, typo.stderr

    res = gs(fleet, port, run, "link", "loss=1.0")  # cut every link
    assert res.returncode == 0, res.stderr
    assert gs(fleet, port, run, "link", "loss=7").returncode == 2  # a bad value is refused locally

    res = gs(fleet, port, run, "kill", "usv2")
    assert res.returncode == 0, res.stderr
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline:
        out = gs(fleet, port, run, "status", "--once").stdout
        if "kill of usv2 by" in out and "3/4 vehicles alive" in out:
            break
    assert "kill of usv2 by" in out and "3/4 vehicles alive" in out, out

    stop = gs(fleet, port, run, "stop")
    assert stop.returncode == 0
    assert la.wait(timeout=60) == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    assert m.completed is False  # stopped early, by the operator
    # the run ends after the tick the stop said, and the stop's event says it: the metrics ended
    # REALTIME_LAG ticks earlier (a stop "from tick 4800 (t = 96.00 s)" against duration_s 95.84)
    tick = int(re.search(r"applied from tick (\d+) \(t = ", stop.stdout)[1])
    stopped = [e.t for e in m.events if e.kind == "fleet" and "stopped by" in e.text]
    assert stopped == [m.duration_s] and m.duration_s == pytest.approx(tick * 0.02, abs=1e-9), (
        stop.stdout, m.duration_s)  # the tick's time as the world computes it (7.0200000000000005 at tick 351)
    assert m.link.faults.total.dropped_by.loss > 0
    kinds = [(e.kind, e.vehicle) for e in m.events]
    assert ("fault", "usv2") in kinds and ("link_changed", None) in kinds, m.events
    assert ("vehicle_lost", "usv2") not in kinds  # the kill it asked for is not news again
    assert not fleet_processes(fleet)


def _world_t(out: str) -> float | None:
    for line in out.splitlines():
        if "world: t =" in line:
            return float(line.split("world: t =")[1].split()[0])
    return None


def test_a_vehicle_paused_past_its_lease_and_resumed_from_the_ground_station_rejoins_in_lockstep(tmp_path, launches):
    """SIGSTOPped longer than the 1 s lease, the agent's session is closed and what the world
    sent meanwhile is lost; the world sends it again when its token is back. This hung the
    fleet for good before."""
    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    la = launches(["configs/concentric_circles.toml", "--clock", "lockstep", "--duration", "3000",
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run), "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    assert gs(fleet, port, run, "pause-vehicle", "uav1").returncode == 0
    time.sleep(3.0)  # well past the lease: the router closes its session
    assert gs(fleet, port, run, "resume-vehicle", "uav1").returncode == 0
    resumed = t = None
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline:
        if resumed is None and "resuming at tick" in (run / "logs" / "uav1.log").read_text():
            resumed = _world_t(gs(fleet, port, run, "status", "--once").stdout)
        elif resumed is not None:
            t = _world_t(gs(fleet, port, run, "status", "--once").stdout)
            if t is not None and t > resumed + 10.0:  # the fleet moves on with uav1 (500 ticks)
                break
        time.sleep(0.5)
    assert resumed is not None and t is not None and t > resumed + 10.0, (run / "logs" / "uav2.log").read_text()[-1500:]
    assert gs(fleet, port, run, "stop").returncode == 0
    assert la.wait(timeout=60) == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    kinds = [(e.kind, e.vehicle) for e in m.events]
    assert ("vehicle_back", "uav1") in kinds, m.events
    assert not fleet_processes(fleet)
