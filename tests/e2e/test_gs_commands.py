"""End to end: a ground station an operator can trust. Every command is answered by the world
(applied from a tick, or rejected with the reason) and `cdus gs` exits by that answer; a
vehicle's credentials are denied; the fleet's state comes out as JSON; two ground stations
command one fleet, and one killed mid-command changes nothing.

One lockstep fleet (concentric_circles: 4 ideal vehicles), secured as `cdus launch` makes it
by default, the ground station holding <run>/secure/ground.json5."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time

import zenoh

from cdus.sim.runmetrics import Metrics
from cdus.wire.transport import Transport, free_tcp_port
from ground_station.console import GroundStation

from .conftest import ROOT, fleet_processes, run_cli, unique_fleet


def gs_args(fleet: str, port: int, run, role: str = "ground") -> list[str]:
    return ["gs", "--fleet", fleet, "-e", f"tcp/127.0.0.1:{port}",
            "--zenoh-config", str(run / "secure" / f"{role}.json5")]


def popen(args: list[str]) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "cdus.app.cli", *args], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})


def finish(p: subprocess.Popen, timeout: float = 60) -> tuple[int, str, str]:
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        out, err = p.communicate()
        raise AssertionError(f"{p.args} timed out:\n{out}\n{err}")
    return p.returncode, out, err


VICTIM = """
import sys
from cdus.wire.transport import Transport
from ground_station.console import GroundStation
gs = GroundStation(sys.argv[1], Transport(mode="client", config_file=sys.argv[2]), name="victim")
gs.open(watch=False)
print("asking", flush=True)
gs.command("pause_vehicle", vehicle="usv1", timeout=120)
print("answered", flush=True)
"""


def test_every_command_is_answered_and_the_ground_station_exits_by_the_answer(tmp_path, launches):
    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    la = launches(["configs/concentric_circles.toml", "--clock", "lockstep", "--duration", "3000",
                   "--listen", f"tcp/127.0.0.1:{port}", "--rerun", "off", "--logs", str(run), "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    base = gs_args(fleet, port, run)

    def gs(*args: str, name: str = "op"):
        return run_cli([*base, "--name", name, *args], timeout=60)

    # machine-readable: every vehicle with live values
    res = gs("status", "--json")
    assert res.returncode == 0, res.stderr
    snap = json.loads(res.stdout)
    assert snap["v"] == 1 and snap["fleet"] == fleet and snap["run"] == "running" and snap["clock"] == "lockstep"
    assert [v["id"] for v in snap["vehicles"]] == ["uav1", "uav2", "usv1", "usv2"]
    for v in snap["vehicles"]:
        assert v["reason"] is None and v["alive"] and v["state"] == "live", v
        assert len(v["telemetry"]["q"]) == (3 if v["id"].startswith("uav") else 2) and v["telemetry"]["tick"] >= 0

    # the whole fleet: applied from a tick, and a pause of a paused fleet is refused
    res = gs("pause")
    assert res.returncode == 0 and "pause of fleet" in res.stdout and "applied from tick" in res.stdout, res
    res = gs("pause")
    assert res.returncode == 1 and "rejected by the fleet: the fleet is already paused" in res.stderr, res
    # a ground station attaching during the pause sees every vehicle where it stands (no telemetry flows)
    res = gs("status", "--once")
    assert res.returncode == 0 and res.stdout.count("[paused (fleet)]") == 4, res.stdout
    assert "no data yet" not in res.stdout
    res = gs("snapshot", str(tmp_path / "snap.json"))
    assert res.returncode == 0, res.stderr
    snap = json.loads((tmp_path / "snap.json").read_text())
    assert snap["run"] == "paused" and all(v["reason"] == "paused (fleet)" and v["telemetry"] for v in snap["vehicles"])
    res = gs("snapshot", str(tmp_path / "snap.json" / "x.json"))  # cannot be written: said, no traceback
    assert res.returncode == 2 and "could not write the snapshot to" in res.stderr and "Traceback" not in res.stderr, res
    assert gs("resume").returncode == 0

    # gains: beyond what a vehicle takes is refused with the world's reason (it said "sent" before)
    res = gs("gains", "k=[1,2,3]", "--vehicle", "usv1")
    assert res.returncode == 1 and "k: must be 2 numbers > 0 for this vehicle" in res.stderr, res
    res = gs("formation", "phases.usv9=1")  # an id the fleet lacks: a usage error, as for gains (was exit 1)
    assert res.returncode == 2 and "no vehicle 'usv9' in this fleet" in res.stderr, res
    res = gs("gains", "k=1.5", "c=2.0")  # the configured gains: a visible no-op
    assert res.returncode == 0 and "applied from tick" in res.stdout, res
    res = gs("link", "loss=0.0", "--at", "0")
    assert res.returncode == 0 and "applied from tick" in res.stdout, res
    # the snapshot saves the settings in force: every run-time change made, phases, the link table
    res = gs("snapshot", str(tmp_path / "settings.json"))
    assert res.returncode == 0, res.stderr
    settings = json.loads((tmp_path / "settings.json").read_text())["settings"]
    assert [(c["seq"], c["op"], c["vehicle"]) for c in settings["changes"]] == [(0, "gains", None), (1, "link", None)]
    assert settings["changes"][0]["fields"]["gains"] == {"k": 1.5, "c": 2.0} and settings["link"] == {"loss": 0.0}
    assert sorted(settings["phases"]) == ["uav1", "uav2", "usv1", "usv2"] and settings["unreadable"] == 0

    # vehicle faults: answered when they land on their tick
    for args in (("pause-vehicle", "uav1"), ("resume-vehicle", "uav1"), ("kill", "usv2"), ("restart", "usv2")):
        res = gs(*args, "--timeout", "45")  # each waits for the one before (a resumed process's reconnection, under load)
        assert res.returncode == 0 and "applied from tick" in res.stdout, (args, res)
    res = gs("resume-vehicle", "usv1")  # it is live: nothing to do
    assert res.returncode == 1 and "usv1 is live" in res.stderr, res
    # refused by the fleet (exit 1) where only the world can tell: offsets that do not close the
    # ring with those in force, a drone sent on a 2-D path, a resume of a running fleet
    res = gs("formation", "offsets.usv2.usv1=1.0")
    assert res.returncode == 1 and "rejected by the fleet: inconsistent formation offsets" in res.stderr, res
    res = gs("path", "--vehicle", "uav1", "family=circle", "center=[0,0]", "radius=5")
    assert res.returncode == 1 and "rejected by the fleet" in res.stderr and "3-D path" in res.stderr, res
    res = gs("resume")
    assert res.returncode == 1 and "rejected by the fleet: the fleet is not paused" in res.stderr, res

    # what the command line cannot check, the world does: an unknown vehicle, a link table that fails
    station = GroundStation(fleet, Transport(mode="client", config_file=str(run / "secure" / "ground.json5")),
                            name="api")
    station.open()
    try:
        assert station.wait_for_status(10)
        a = station.command("kill", vehicle="nobody")
        assert (a.outcome, a.code) == ("rejected", 1) and "no vehicle 'nobody'" in a.reply.reason
        a = station.command("link", link={"loss": 7.0}, at=-1.0)
        assert a.outcome == "rejected" and "loss" in a.reply.reason
        a = station.command("set_gains", gains={"c": 2.0}, vehicle="uav2")
        assert a.outcome == "applied" and a.reply.by == "gs:api" and a.reply.tick > 0

        # a vehicle's credentials: the router denies the command (it said "stop sent" before)
        res = run_cli([*gs_args(fleet, port, run, role="vehicle-usv1"), "stop"], timeout=60)
        assert res.returncode == 4 and "denied" in res.stderr and "ground.json5" in res.stderr, res
        assert "'vehicle-usv1'" in res.stderr

        # two ground stations at once, each with its own answer; the event log names each
        both = [popen([*base, "--name", who, "gains", f"c={c}"]) for who, c in (("alice", 2.0), ("bob", 2.5))]
        for p in both:
            code, out, err = finish(p)
            assert code == 0 and "applied from tick" in out, (out, err)

        # a ground station killed while it waits for its answer changes nothing: the restart
        # under way holds the next fault (the victim's) until the new process is up; the victim
        # dies with its query sent and unanswered; the world carries the fault out whole, and the
        # fleet goes on
        assert station.command("restart", vehicle="uav2").outcome == "applied"
        victim = subprocess.Popen([sys.executable, "-c", VICTIM, fleet, str(run / "secure" / "ground.json5")],
                                  cwd=ROOT, stdout=subprocess.PIPE, text=True, start_new_session=True)
        assert victim.stdout.readline().strip() == "asking"
        time.sleep(0.5)  # the query is out (loopback): now it waits for the restart
        os.killpg(victim.pid, signal.SIGKILL)
        victim.wait()
        t0 = station.sim_time() or 0.0
        deadline = time.monotonic() + 90
        # the killed station's pause was carried out once, whole, or (killed before its query left,
        # under load) not at all; either way the fleet goes on
        while (station.sim_time() or 0.0) < t0 + 10:
            assert time.monotonic() < deadline, ("the fleet did not go on after a ground station died",
                                                 station.view.events[-5:])
            time.sleep(0.2)
        paused = sum("pause of usv1 by gs:victim" in e.text for e in station.view.events)
        assert paused <= 1, station.view.events[-5:]
        if paused:
            assert station.command("resume_vehicle", vehicle="usv1").outcome == "applied"

        # watch: JSON lines, a status line and the events as they come, ended by Ctrl-C
        watcher = popen([*base, "watch", "--jsonl", "--interval", "0.5"])
        lines = []
        reader = threading.Thread(target=lambda: lines.extend(json.loads(ln) for ln in watcher.stdout), daemon=True)
        reader.start()
        deadline = time.monotonic() + 60
        while not lines:  # it is watching
            assert time.monotonic() < deadline and watcher.poll() is None, watcher.stderr.read()
            time.sleep(0.1)
        assert station.command("set_gains", gains={"c": 2.0}, vehicle="").outcome == "applied"
        while not any(ln["kind"] == "event" and "by gs:api" in ln["event"]["text"] for ln in list(lines)):
            assert time.monotonic() < deadline, lines
            time.sleep(0.1)
        os.killpg(watcher.pid, signal.SIGINT)
        try:
            code = watcher.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(watcher.pid, signal.SIGKILL)
            raise
        reader.join(timeout=10)
        assert code == 0, watcher.stderr.read()
        assert all(ln["v"] == 1 for ln in lines) and {ln["kind"] for ln in lines} >= {"status", "event"}, lines
        assert any(ln["kind"] == "event" and "by gs:api" in ln["event"]["text"] for ln in lines), lines
    finally:
        station.close()

    res = gs("stop")
    assert res.returncode == 0 and "applied from tick" in res.stdout, res
    assert la.wait(timeout=120) == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    texts = [e.text for e in m.events]
    for who in ("gs:alice", "gs:bob", "gs:api", "gs:op"):
        assert any(f"by {who}" in t for t in texts), (who, texts)
    assert not any("stopped by" in t and "usv1" in t for t in texts)  # the denied stop never arrived
    victims = [e for e in m.events if "by gs:victim" in e.text]
    assert [(e.kind, e.vehicle) for e in victims] == [("fault", "usv1")], victims  # once, whole
    assert "Traceback" not in (run / "logs" / "world.log").read_text()
    assert not fleet_processes(fleet)
