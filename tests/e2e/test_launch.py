"""End to end: the fleet as one OS process per vehicle over Zenoh (loopback only)."""

from __future__ import annotations

import signal
import time

import pytest
import zenoh

from cdus.sim.runmetrics import Metrics
from cdus.wire import keys
from cdus.wire.schemas import decode_event
from cdus.scenario.config import load_scenario
from cdus.wire.transport import Transport, free_tcp_port, open_session
from cdus.sim.fleet import InProcessFleet
from cdus.core.metrics import METRICS_FIELDS
from cdus.wire.rejected import Rejected

from .conftest import assert_same_trace, fleet_processes, run_cli, unique_fleet


@pytest.mark.parametrize("links", ["router", "direct"])
def test_lockstep_reproduces_the_in_process_run(tmp_path, launches, links):
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", "10", "--seed", "3",
                   "--logs", str(run), "--trace-out", str(tmp_path / "trace.npz"), "-q", "--links", links, *(["--insecure"] if links == "direct" else [])], fleet)
    assert la.wait() == 0, la.output()
    sc = load_scenario("configs/lake_circle.toml", {"scenario.duration": 10.0, "scenario.seed": 3})
    ref = InProcessFleet(sc).run()
    assert_same_trace(tmp_path / "trace.npz", ref)
    metrics = Metrics.read(run / "metrics.json")
    assert metrics.mode == "lockstep" and metrics.completed is True
    # nothing of the ROS 2 face in a fleet that did not ask for it (docs/ros2.md): no bridge, no role
    assert not (run / "logs" / "ros2.log").exists() and not (run / "secure" / "ros2-client.json5").exists()
    for field in ("duration_s", "path_settle_s", "coord_settle_s", "final_path_error_max",
                  "final_coord_error_max", "omega_rate_final"):
        assert getattr(metrics, field) == pytest.approx(getattr(ref.metrics, field), abs=1e-9), field
    assert not fleet_processes(fleet)


def test_realtime_run_converges(tmp_path, launches):
    fleet = unique_fleet()
    run = tmp_path / "run"
    # 10 s (it was 15, then 12): it settles at 8.38 s in process, and at 8.38 s in real time under two
    # busy loops and load 10 (path 6.88 s); settle times count only if it stays settled to the end
    la = launches(["configs/concentric_circles.toml", "--clock", "realtime", "--duration", "10",
                   "--logs", str(run), "-q"], fleet)
    assert la.wait() == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    assert m.mode == "realtime"
    assert m.coord_settle_s is not None and m.final_coord_error_max < 0.05, m
    assert m.path_settle_s is not None, m
    assert m.link.delivered > 0
    assert not fleet_processes(fleet)


def test_a_killed_agent_is_reported_with_the_graph_it_leaves(tmp_path, launches):
    fleet = unique_fleet()
    port = free_tcp_port()
    la = launches(["configs/lake_circle.toml", "--clock", "realtime", "--duration", "120",
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(tmp_path / "run"), "-q", "--insecure"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    events: list[tuple[float, str]] = []
    session = open_session(Transport(mode="client", connect=(f"tcp/127.0.0.1:{port}",)))
    try:
        sub = session.declare_subscriber(keys.world_events(fleet), zenoh.handlers.FifoChannel(64))
        victim = [ln for ln in fleet_processes(fleet) if "--id usv2" in ln]
        assert victim, fleet_processes(fleet)
        pid = int(victim[0].split()[0])
        t_kill = time.monotonic()
        import os
        os.kill(pid, signal.SIGKILL)
        deadline = t_kill + 10.0
        while time.monotonic() < deadline:
            sample = sub.try_recv()
            if sample is None:
                time.sleep(0.005)
                continue
            event = decode_event(sample.payload.to_bytes())
            assert not isinstance(event, Rejected), event
            events.append((time.monotonic() - t_kill, event))
            if event.kind == "graph":
                break
    finally:
        session.close()
    lost = [dt for dt, e in events if e.kind == "vehicle_lost" and e.vehicle == "usv2"]
    assert lost, events  # how soon is a figure for bench/failure_detection.py, not an assertion here
    # right after: the ring without usv2 is a chain, which still has a spanning tree
    graph = [e for _, e in events if e.kind == "graph"]
    assert graph and "still has a spanning tree" in graph[0].text and graph[0].severity == "info", events
    la.proc.send_signal(signal.SIGINT)
    assert la.wait() == 130
    assert not fleet_processes(fleet)


def test_ctrl_c_leaves_no_process_and_a_complete_metrics_file(tmp_path, launches):
    """Started as a script's `cdus launch ... &` starts it, with SIGINT ignored (the shell does
    that for background jobs, and Python keeps it): SIGINT still stops the fleet cleanly."""
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", "3000",
                   "--logs", str(run)], fleet, prefix=["sh", "-c", 'trap "" INT; exec "$@"', "sh"])
    la.wait_for(f"fleet '{fleet}' up")
    la.proc.send_signal(signal.SIGINT)
    assert la.wait(timeout=60) == 130, la.output()
    assert not fleet_processes(fleet)
    m = Metrics.read(run / "metrics.json")
    assert set(METRICS_FIELDS) <= set(m.to_dict())  # a whole file, every field written
    assert m.completed is False
    assert "metrics:" in la.output()


def test_a_config_error_starts_nothing(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text((open("configs/lake_circle.toml").read()).replace("radius = 10.0", "radius = -10.0", 1))
    fleet = unique_fleet()
    run = tmp_path / "run"
    res = run_cli(["launch", str(bad), "--fleet", fleet, "--logs", str(run)], timeout=60)
    assert res.returncode == 2
    assert "path.radius" in res.stderr and "must be > 0" in res.stderr
    assert "nothing was started" in res.stderr
    assert not run.exists()
    assert not fleet_processes(fleet)


def test_an_agent_that_dies_at_start_is_named_with_its_log_and_nothing_is_left(tmp_path, monkeypatch):
    import sys

    from cdus.app.launcher import LaunchOptions, Launcher, launch
    from cdus.wire.transport import local_router

    sc = load_scenario("configs/offset_circles.toml", {"scenario.duration": 30.0})
    fleet = unique_fleet()
    lines: list[str] = []

    class Broken(Launcher):
        def _agent(self, vid):
            child = super()._agent(vid)
            if vid == "uav1":  # this vehicle's program fails before it is ready
                child.argv = [sys.executable, "-c", "import sys; print('boom: no radio'); sys.exit(3)"]
            return child

    import cdus.app.launcher as launcher_mod

    monkeypatch.setattr(launcher_mod, "Launcher", Broken)
    status, la = launch(sc, tmp_path / "run", local_router(),
                        LaunchOptions(fleet=fleet, ready_timeout=20.0, quiet=True), log=lines.append)
    text = "\n".join(lines)
    assert status == 1
    assert "uav1 exited with status 3 during start-up" in text, text
    assert "boom: no radio" in text  # its log tail
    assert not fleet_processes(fleet)


def test_launch_and_sim_print_the_same_event_lines_at_the_same_times(tmp_path, launches):
    """One printer for both (cdus.sim.reports.ConsoleQuota.printed): the links lossy by design
    in one line, the scheduled kill, and the graph event, stamped with the kill's tick in
    lockstep too (it said 0.98 s for a kill at 1.00 s: the newest tick recorded)."""
    cfg = tmp_path / "kill.toml"
    cfg.write_text(open("configs/lake_circle.toml").read()
                   + '\n[[event]]\nat = 1.0\naction = "kill"\nvehicle = "usv2"\n')
    # 9 s after the kill: the world hears the killed process's token go (wall-clock news) before the
    # run ends; news after the end is not reported (a 2 s run lost the graph line under load)
    common = ["--duration", "10", "--set", "link.loss=0.1", "--rerun", "off"]
    sim = run_cli(["sim", str(cfg), *common, "--runs-dir", str(tmp_path / "runs")])
    assert sim.returncode == 0, sim.stderr
    printed = [ln for ln in sim.stdout.splitlines() if ln.startswith("  event: ")]
    assert printed == ["  event: t = 0.00 s: link faults from t = 0: loss 0.1 on 12 links (all)",
                       "  event: t = 1.00 s: scheduled kill of usv2 (t = 1 s)",
                       "  event: t = 1.00 s: the live graph (5 vehicles) still has a spanning tree"]
    fleet = unique_fleet()
    la = launches([str(cfg), *common, "--clock", "lockstep", "--logs", str(tmp_path / "run")], fleet)
    assert la.wait() == 0, la.output()
    # in the same order too: the launcher heard the t = 0 line with the agents' stats, a wall
    # second in, and printed it after the kill's lines (t = 1.00 s, then t = 0.00 s)
    assert [ln for ln in la.output().splitlines() if ln.startswith("  event: ")] == printed, la.output()
    assert not fleet_processes(fleet)


def test_a_remote_vehicle_that_never_came_up_is_named_so_in_the_summary(tmp_path):
    """It was listed as "not live at the end: killed or paused" with the run "interrupted"."""
    run = tmp_path / "run"
    r = run_cli(["launch", "configs/lake_circle.toml", "--remote", "uav2", "--ready-timeout", "4", "--rerun", "off",
                 "--logs", str(run), "-q", "--fleet", unique_fleet()])
    assert r.returncode == 1, r.stdout + r.stderr
    assert "uav2 (started elsewhere) did not connect within 4 s" in r.stdout
    # its neighbours' agents wait for its link before they declare themselves up: they never came up either
    assert "NOT STARTED: uav1, uav2, uav3 never came up" in r.stdout and "killed or paused" not in r.stdout, r.stdout
    rows = {ln.split()[0]: ln for ln in r.stdout.splitlines() if ln.startswith(("  usv", "  uav"))}
    assert rows["uav2"].endswith("(never came up)")
    assert rows["usv1"].endswith("(up, waiting for the others: the run never started)")
    m = Metrics.read(run / "metrics.json")
    assert m.completion == "not_started" and m.never_up == ("uav1", "uav2", "uav3")


from tests.fullfs import full_fs  # noqa: E402,F401  (the fixture)


def test_a_full_disk_at_the_end_keeps_a_completed_run(tmp_path, full_fs):
    """Issue 27, broken 2: with the metrics, the trace and the recording on a full file system,
    the world died in write_json at the end, the launcher took it for a lost world and died in a
    second traceback (exit 1, no metrics, no summary). Now: the run's own metrics (completed) in
    the run directory, the summary, which file failed and why, no recording path that does not
    exist, and no process left."""
    fleet = unique_fleet()
    run = tmp_path / "run"
    res = run_cli(["launch", "configs/lake_circle.toml", "--fleet", fleet, "--logs", str(run), "--duration", "2",
                   "-q", "--metrics-out", str(full_fs / "metrics.json"), "--trace-out", str(full_fs / "trace.npz"),
                   "--rerun", f"save:{full_fs / 'rec.rrd'}"], timeout=120)
    out = res.stdout + res.stderr
    assert res.returncode == 1, out
    assert "Traceback" not in out and "world_lost" not in out, out
    m = Metrics.read(run / "metrics.json")
    assert m.completed is True and m.written_by != "launcher", m
    assert f"metrics: {run / 'metrics.json'} (not {full_fs / 'metrics.json'}: it could not be written)" in res.stdout
    assert "lake_circle (lockstep, seed 1): 2.0 s simulated" in res.stdout  # the summary
    assert f"could not write the metrics to {full_fs / 'metrics.json'}: No space left on device" in out
    assert f"could not write the trace to {full_fs / 'trace.npz'}: No space left on device" in out
    assert f"recording: none; {full_fs / 'rec.rrd'} was not written" in res.stdout
    assert not fleet_processes(fleet)


def test_a_second_launch_into_a_running_fleets_directory_is_refused_and_changes_nothing(tmp_path, launches):
    """Issue 27, broken 5, against a launched fleet: two `cdus launch` with one --logs overwrote
    each other (logs interleaved, one metrics.json replacing the other, the second replacing the
    first's secure/ground.json5 while the first ran: its printed ground-station line stopped
    working). The second is refused before it writes anything; the first runs to its end with
    its own credentials, logs and metrics."""
    fleet = unique_fleet()
    run = tmp_path / "run"
    # realtime, 5 s (it was 8): still running while the second one tries (refused within 1 s of "up")
    la = launches(["configs/lake_circle.toml", "--clock", "realtime", "--duration", "5", "--logs", str(run),
                   "--rerun", "off", "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    ground = (run / "secure" / "ground.json5").read_bytes()
    logs = {p.name: p.stat().st_size for p in (run / "logs").iterdir()}
    second = run_cli(["launch", "configs/lake_circle.toml", "--fleet", fleet + "b", "--duration", "2",
                      "--logs", str(run), "--rerun", "off", "-q"], timeout=60)
    assert second.returncode == 2, second.stdout + second.stderr
    assert f"another `cdus launch` is running into {run}" in second.stderr and "nothing was started" in second.stderr
    assert (run / "secure" / "ground.json5").read_bytes() == ground
    assert not fleet_processes(fleet + "b")
    assert la.wait() == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    assert m.completed is True and m.duration_s == pytest.approx(5.0, abs=0.1)
    assert set(p.name for p in (run / "logs").iterdir()) == set(logs)  # no second fleet's logs among them
    assert all(fleet + "b" not in (run / "logs" / name).read_text(errors="replace") for name in logs)
