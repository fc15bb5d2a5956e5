"""End to end: supervision. No process of the fleet outlives its launcher (even a SIGKILLed
one), a world that dies still leaves a metrics.json that says so, and the launcher's command
key moves the scenario's vehicles only, never the world."""

from __future__ import annotations

import os
import signal
import subprocess
import time

import pytest
import zenoh

from cdus.sim.runmetrics import Metrics
from cdus.wire import keys
from cdus.wire.messages import encode_control
from cdus.wire.schemas import encode_status
from cdus.wire.transport import free_tcp_port

from tests.outsider import raw_client

from .conftest import WorldTime, fleet_processes, unique_fleet

ORPHAN_WAIT_S = 3.0  # the bound: no process of the fleet 3 s after the launcher's SIGKILL


def pids(fleet: str, module: str = "") -> list[int]:
    return [int(ln.split()[0]) for ln in fleet_processes(fleet) if module in ln]


def wait_no_process(fleet: str, seconds: float) -> list[str]:
    deadline = time.monotonic() + seconds
    while True:
        left = fleet_processes(fleet)
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.1)


def test_a_sigkilled_launcher_leaves_no_process_of_its_fleet(tmp_path, launches):
    fleet = unique_fleet()
    run = tmp_path / "run"
    port = free_tcp_port()
    la = launches(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", "3000", "--rerun", "off",
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run), "-q", "--insecure"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    assert len(set(pids(fleet)) - {la.proc.pid}) == 7  # the world and six agents, each in its own session
    # one vehicle paused (SIGSTOPped) by a fault: a stopped process acts on no signal but SIGKILL
    s = zenoh.open(raw_client(f"tcp/127.0.0.1:{port}"))
    try:
        s.put(keys.launcher_cmd(fleet), encode_control("pause_vehicle", vehicle="usv2"))
        la.wait_for("fault: pause usv2")
    finally:
        s.close()
    os.kill(la.proc.pid, signal.SIGKILL)  # the launcher alone, not its children's groups
    la.wait(timeout=10)
    left = wait_no_process(fleet, ORPHAN_WAIT_S)
    assert not left, "\n".join(left)
    # they were told (SIGTERM), not killed: the world still wrote what it had
    m = Metrics.read(run / "metrics.json")
    assert m.completed is False


def test_a_sigkilled_world_leaves_metrics_that_say_so_and_the_launcher_fails(tmp_path, launches):
    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    la = launches(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", "3000",
                   "--rerun", f"save:{run / 'rec.rrd'}",
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run), "-q", "--insecure"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    s = zenoh.open(raw_client(f"tcp/127.0.0.1:{port}"))
    try:
        clock = WorldTime(s, fleet)
        t = clock.wait_past(1.0)
        world = pids(fleet, "world_sim")
        assert len(world) == 1
        # issue 27: on this open fleet a forged status, then the world's SIGKILL, put the forged
        # values into the launcher's world_lost metrics (duration 2,999 s for a run at 63 s). The
        # world stopped first, so the forgeries are the last statuses the launcher hears
        os.kill(world[0], signal.SIGSTOP)
        ids = ["usv1", "usv2", "usv3", "uav1", "uav2", "uav3"]
        forged = encode_status(2999.0, 3000.0, "lockstep", ids, ids, 1e-9, 1e-9, [], False)
        for _ in range(5):
            s.put(keys.world_status(fleet), forged)
        s.put(keys.launcher_cmd(fleet), b"junk")  # after them, a message the launcher says it dropped:
        la.wait_for("a malformed command on")  # it has heard the forgeries too
    finally:
        s.close()
    os.kill(world[0], signal.SIGKILL)
    assert la.wait(timeout=60) == 1, la.output()
    m = Metrics.read(run / "metrics.json")
    assert m.completed is False and m.completion == "world_lost", m
    assert m.written_by == "launcher"
    assert m.world_lost.world_exit == -signal.SIGKILL
    assert t <= m.world_lost.last_status_t < 2999.0  # what the launcher knew from its own world only
    assert m.duration_s < 2999.0 and m.final_path_error_max != 1e-9
    assert m.world_lost.rejected_by_launcher.get("status unsigned", 0) >= 1, m.world_lost
    assert "world wrote no metrics" in la.output()
    # issue 27: the launcher printed a recording path the killed world never wrote; it says what exists
    assert not (run / "rec.rrd").exists()
    (said,) = [ln for ln in la.output().splitlines() if ln.startswith("  recording:")]
    assert said.startswith(f"  recording: {run / 'rec.rrd'} was not written; what was recorded is in") \
        or said == f"  recording: none; {run / 'rec.rrd'} was not written (the world's log says why)", said
    assert not fleet_processes(fleet)


def test_the_launchers_key_moves_vehicles_only_never_the_world(tmp_path, launches):
    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    la = launches(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", "3000", "--rerun", "off",
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run), "-q", "--insecure"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    world = pids(fleet, "world_sim")
    s = zenoh.open(raw_client(f"tcp/127.0.0.1:{port}"))
    try:
        clock = WorldTime(s, fleet)
        t = clock.wait_past(0.5)
        key = keys.launcher_cmd(fleet)
        s.put(key, encode_control("kill", vehicle="\x1b[2Jnobody"))
        s.put(key, encode_control("pause_vehicle", vehicle="world"))
        s.put(key, encode_control("kill", vehicle="world"))
        s.put(key, encode_control("restart", vehicle="world"))
        s.put(key, b"\xc1 not msgpack")
        la.wait_for("rejected: kill \\x1b[2Jnobody")  # logged escaped
        # the world is neither killed nor frozen: its time goes on (lockstep: nobody steps if it stops)
        clock.wait_past(clock.wait_past(t) + 5.0)
        assert pids(fleet, "world_sim") == world
        # the same key still carries out a fault on a vehicle: the check above could fail
        s.put(key, encode_control("pause_vehicle", vehicle="usv2"))
        la.wait_for("fault: pause usv2")
        s.put(key, encode_control("resume_vehicle", vehicle="usv2"))
        la.wait_for("fault: resume usv2")
    finally:
        s.close()
    la.proc.send_signal(signal.SIGINT)
    assert la.wait(timeout=60) == 130, la.output()
    out = la.output()
    assert "fault: kill world" not in out and "fault: pause world" not in out
    assert "\x1b" not in out
    # counted by reason: three about the world and the escaped one, one malformed
    assert "the launcher dropped 5 messages: 1 command malformed, 4 command not_a_vehicle" in out, out
    m = Metrics.read(run / "metrics.json")
    assert m.completion != "world_lost"  # the world wrote its own
    assert not fleet_processes(fleet)


def test_children_are_asked_to_stop_when_their_parent_dies():
    """The mechanism alone: a child started as the launcher starts it gets SIGTERM when its
    parent dies (the parent here: a shell that execs nothing and is SIGKILLed)."""
    from cdus.app.launcher import die_with_parent

    assert die_with_parent(os.getpid()) is not None
    code = ("import os, signal, subprocess, sys, time\n"
            "from cdus.app.launcher import die_with_parent\n"
            "p = subprocess.Popen([sys.executable, '-c', 'import signal, sys, time\\n"
            "signal.signal(signal.SIGTERM, lambda *a: (print(\"TERM\", flush=True), sys.exit(0)))\\n"
            "print(\"ready\", flush=True)\\ntime.sleep(60)'], start_new_session=True, "
            "preexec_fn=die_with_parent(os.getpid()))\n"
            "print(p.pid, flush=True)\ntime.sleep(60)\n")
    parent = subprocess.Popen([os.sys.executable, "-c", code], stdout=subprocess.PIPE, text=True,
                              start_new_session=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    child = None
    try:
        lines = []
        while len(lines) < 2:
            lines.append(parent.stdout.readline().strip())
        child = int(next(ln for ln in lines if ln.isdigit()))
        parent.kill()
        parent.wait()
        assert "TERM" in parent.stdout.read()  # the child (sharing the pipe) printed it on SIGTERM
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            try:
                os.kill(child, 0)
            except ProcessLookupError:
                break
            time.sleep(0.05)
        else:
            raise AssertionError("the child outlived its parent")
    finally:
        if parent.poll() is None:
            os.killpg(parent.pid, signal.SIGKILL)
        if child is not None:
            try:
                os.killpg(child, signal.SIGKILL)
            except ProcessLookupError:
                pass


@pytest.mark.parametrize("wait_for_the_stop", [True, False])
def test_a_second_sigterm_while_stopping_still_stops_cleanly(tmp_path, launches, wait_for_the_stop):
    """`timeout` and `pkill` each send a SIGTERM: the second one, arriving while the launcher
    stops the fleet, used to abort the stop (no metrics.json, zombie children, a launcher that
    never exited)."""
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", "3000", "--rerun", "off",
                   "--logs", str(run), "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    os.kill(la.proc.pid, signal.SIGTERM)
    if wait_for_the_stop:
        la.wait_for("interrupted: stopping the fleet")
    else:  # as `timeout` and `pkill` do: the second one lands while the first is being handled
        time.sleep(0.01)
    os.kill(la.proc.pid, signal.SIGTERM)
    assert la.wait(timeout=60) == 130, la.output()
    m = Metrics.read(run / "metrics.json")
    assert m.completed is False and m.completion == "interrupted", m.completion
    assert not wait_no_process(fleet, ORPHAN_WAIT_S)
