"""The command line: how flags and the scenario file combine (no process is started here)."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

from cdus.app.cli import build_parser, launch_options, main
from cdus.scenario.config import ConfigError, load_scenario, parse_overrides
from cdus.scenario.model import RESTART_POLICIES
from cdus.sim.runmetrics import Metrics

CONFIG = "configs/lake_circle.toml"


def options(*flags: str, **overrides):
    args = build_parser().parse_args(["launch", CONFIG, *flags])
    return args, launch_options(args, load_scenario(CONFIG, overrides))


def test_the_restart_policy_comes_from_the_scenario_unless_the_flag_is_given():
    args, opts = options()
    assert args.restart is None and opts.restart == "never"
    _, opts = options(**{"supervision.restart": "always"})
    assert opts.restart == "always"
    _, opts = options("--restart", "on-failure", **{"supervision.restart": "always"})
    assert opts.restart == "on-failure"


def test_the_restart_flag_takes_the_scenarios_vocabulary(capsys):
    for policy in RESTART_POLICIES:
        assert build_parser().parse_args(["launch", CONFIG, "--restart", policy]).restart == policy
    with pytest.raises(SystemExit):
        build_parser().parse_args(["launch", CONFIG, "--restart", "sometimes"])
    assert "invalid choice: 'sometimes'" in capsys.readouterr().err


def test_other_launch_options_come_from_the_flags():
    _, opts = options("--fleet", "f1", "--clock", "realtime", "--duration", "5", "--policy", "extrapolate")
    assert (opts.fleet, opts.clock, opts.duration, opts.policy) == ("f1", "realtime", 5.0, "extrapolate")
    _, opts = options()
    assert opts.fleet == "lake_circle" and opts.metrics_out is None


def test_remote_vehicles_are_checked_and_take_router_links():
    _, opts = options()
    assert opts.remote == () and opts.links == "router"  # the default
    _, opts = options("--remote", "usv1,usv2", "--remote", "uav3", "--remote", "usv1")
    assert opts.remote == ("usv1", "usv2", "uav3") and opts.links == "router"
    with pytest.raises(ConfigError, match=r"--remote: no vehicle 'usv9' in lake_circle; ids are usv1, "):
        options("--remote", "usv1,usv9")


@pytest.mark.parametrize("flag", [[], ["--secure"], ["--tls"]])
def test_direct_links_need_insecure_because_they_would_skip_the_routers_access_control(flag):
    _, opts = options(*flag)
    assert opts.links == "router"
    with pytest.raises(ConfigError, match="--links: direct links skip the router and its access control.* add "
                                          "--insecure to run an open fleet with direct links"):
        options(*flag, "--links", "direct")
    _, opts = options("--links", "direct", "--insecure")
    assert opts.links == "direct"


def test_direct_links_are_refused_with_remote_vehicles_even_when_open():
    with pytest.raises(ConfigError, match="--links: direct links .* with --remote use --links router"):
        options("--remote", "usv1", "--links", "direct", "--insecure")


def test_scheduled_faults_after_the_end_are_named_not_silently_skipped(capsys, tmp_path):
    code = main(["sim", "configs/lake_circle.toml", "--rerun", "off", "-q", "--duration", "2",
                 "--metrics-out", str(tmp_path / "m.json"), "--set", 'event=[{at=100.0,action="kill",vehicle="usv2"}]'])
    assert code == 0
    assert "note: event[0] (kill usv2 at 100 s) is past the run's end (2 s): it will not apply" in \
        capsys.readouterr().err


LATE = ('event=[{at=1.0,action="kill",vehicle="usv1"},{at=0.5,action="pause",vehicle="usv2",duration=5.0},'
        '{at=3.0,action="path",vehicle="usv3",path={family="circle",center=[0,0],radius=10}},'
        '{at=2.5,action="formation",phases={usv1=0.5}},{at=2.0,action="kill",vehicle="uav1"}]')


def test_every_kind_of_event_past_the_end_is_said_once_where_cdus_sim_starts(capsys, tmp_path):
    """Issue 17 review: a path or formation change past the run's end was accepted in silence
    (the note named scheduled faults only). An event at the end itself applies: no note."""
    code = main(["sim", "configs/lake_circle.toml", "--rerun", "off", "-q", "--set", "scenario.duration=2",
                 "--metrics-out", str(tmp_path / "m.json"), "--set", LATE])
    assert code == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if line.startswith("note:")]
    assert notes == [
        "note: event[1] (pause usv2 at 0.5 s for 5 s) ends past the run's end (2 s): its resume at 5.5 s will not "
        "apply",
        "note: event[2] (path of usv3 at 3 s) is past the run's end (2 s): it will not apply",
        "note: event[3] (formation at 2.5 s) is past the run's end (2 s): it will not apply",
    ]


def test_the_launcher_s_opening_notes_the_same_lines_from_its_run_s_duration():
    """`cdus launch` prints late_event_lines(scenario) after its "launching" line (cmd_launch);
    the lines come from the scenario as --duration/--set left it, or a duration given."""
    from cdus.scenario.config import load_scenario
    from cdus.sim.reports import LATE_NAMED, late_event_lines

    s = load_scenario("configs/lake_circle.toml", {"scenario.duration": 2.0, **parse_overrides([LATE])})
    assert late_event_lines(s) == late_event_lines(s, 2.0) and len(late_event_lines(s)) == 3
    assert late_event_lines(s, 10.0) == []
    assert late_event_lines(s, 0.75) == [
        "note: event[0] (kill usv1 at 1 s) is past the run's end (0.75 s): it will not apply",
        "note: event[1] (pause usv2 at 0.5 s for 5 s) ends past the run's end (0.75 s): its resume at 5.5 s will "
        "not apply",
        "note: event[2] (path of usv3 at 3 s) is past the run's end (0.75 s): it will not apply",
        "note: event[3] (formation at 2.5 s) is past the run's end (0.75 s): it will not apply",
        "note: event[4] (kill uav1 at 2 s) is past the run's end (0.75 s): it will not apply",
    ]
    radio = load_scenario("configs/range_out.toml", parse_overrides(['event=[{at=200.0,action="radio",tx_power=5.0}]']))
    assert late_event_lines(radio) == [
        "note: event[0] (radio at 200 s) is past the run's end (112 s): it will not apply"]
    many = load_scenario("configs/lake_circle.toml", parse_overrides(
        ["event=[" + ",".join(f'{{at={100 + j}.0,action="formation",phases={{usv1={j / 10}}}}}' for j in range(12))
         + "]"]))
    lines = late_event_lines(many, 5.0)
    assert len(lines) == LATE_NAMED + 1 and lines[-1] == "note: and 2 more events past the run's end (5 s): they " \
                                                         "will not apply"


# ---------------------------------------------------------------- safe by default: who may reach the router

from cdus.wire.transport import Transport, exposed_endpoints, is_local_endpoint  # noqa: E402


@pytest.mark.parametrize("ep", ["tcp/127.0.0.1:7447", "tcp/127.1.2.3:7447", "tcp/[::1]:7447", "tls/127.0.0.1:1",
                                "udp/127.0.0.1:7447#iface=lo", "unixsock-stream//tmp/cdus.sock", "unixpipe/cdus"])
def test_loopback_and_unix_sockets_are_local(ep):
    assert is_local_endpoint(ep)


@pytest.mark.parametrize("ep", ["tcp/0.0.0.0:7447", "tcp/[::]:7447", "tcp/192.168.1.10:7447", "tls/10.0.0.1:7447",
                                "tcp/localhost:7447", "tcp/example.org:7447", "vsock/VMADDR_CID_ANY:7447",
                                "quic/[::ffff:127.0.0.1]:7447"])
def test_wildcards_lan_addresses_and_host_names_are_not(ep):
    assert not is_local_endpoint(ep)


def test_a_router_config_file_without_endpoints_listens_where_zenoh_does_by_default(tmp_path):
    f = tmp_path / "r.json5"
    f.write_text("{}")
    assert exposed_endpoints(Transport(mode="router", config_file=str(f))) == ("tcp/[::]:7447",)
    f.write_text('{listen: {endpoints: ["tcp/127.0.0.1:7447", "tcp/0.0.0.0:7448"]}}')
    assert exposed_endpoints(Transport(mode="router", config_file=str(f))) == ("tcp/0.0.0.0:7448",)
    f.write_text('{listen: {endpoints: {router: ["unixsock-stream//tmp/x.sock"]}}}')
    assert exposed_endpoints(Transport(mode="router", config_file=str(f))) == ()


def _started(monkeypatch):
    """Replace the fleet by a recorder of the routers it would have been started with."""
    import cdus.app.cli as cli
    import cdus.app.launcher as launcher  # cmd_launch imports launch where it runs

    started = []
    monkeypatch.setattr(cli, "check_listen", lambda eps: None)  # 7447 may be busy here; no router is opened
    monkeypatch.setattr(launcher, "launch", lambda scenario, run, router, opts: (started.append((router, opts)),
                                                                                  (0, _NoRun(run)))[1])
    return started


def _auth(router):
    import json

    value = dict(router.extra).get("transport/auth/usrpwd/dictionary_file")
    return None if value is None else json.loads(value)


@pytest.mark.parametrize("flags", [[], ["--listen", "tcp/127.0.0.1:7447"], ["--listen", "tcp/0.0.0.0:7447"],
                                   ["--listen", "tcp/192.168.1.10:7447"], ["--secure"]])
def test_a_launch_is_secured_by_default_on_loopback_and_beyond(flags, tmp_path, capsys, monkeypatch):
    started = _started(monkeypatch)
    run = tmp_path / "run"
    main(["launch", CONFIG, "--logs", str(run), "--rerun", "off", *flags])
    (router, opts), = started
    assert _auth(router) == str((run / "secure" / "passwords").resolve())
    assert "access_control" in dict(router.extra)
    assert opts.zenoh_configs["world"] == str(run / "secure" / "world.json5")
    assert set(opts.zenoh_configs) == {"world", "usv1", "usv2", "usv3", "uav1", "uav2", "uav3"}
    out, err = capsys.readouterr()
    assert "secured (password): credentials in" in out and "WARNING" not in err
    # the printed ground-station line carries the ground station's credentials
    gs = next(ln for ln in out.splitlines() if "attach a ground station:" in ln)
    assert gs.endswith(f"--zenoh-config {run / 'secure' / 'ground.json5'} status")
    assert " -e tcp/" in gs and "ENDPOINT" not in gs


def test_insecure_runs_open_on_loopback_and_says_what_it_allows(tmp_path, capsys, monkeypatch):
    started = _started(monkeypatch)
    main(["launch", CONFIG, "--logs", str(tmp_path / "run"), "--rerun", "off", "--insecure"])
    (router, opts), = started
    assert _auth(router) is None and "access_control" not in dict(router.extra) and opts.zenoh_configs == {}
    assert not (tmp_path / "run" / "secure").exists()
    out, err = capsys.readouterr()
    assert "WARNING: --insecure: anyone who reaches this router (tcp/127.0.0.1:" in err
    assert "any process of this host) can, without any credential: stop" in err
    assert "change its gains, link faults, formation and paths" in err  # issue 18's commands too
    assert "--zenoh-config" not in out and "secured" not in out


def test_a_router_config_without_listen_needs_insecure_and_says_so(tmp_path, capsys, monkeypatch):
    started = _started(monkeypatch)
    (tmp_path / "empty.json5").write_text("{}")
    runs = tmp_path / "runs"
    assert main(["launch", CONFIG, "--runs-dir", str(runs), "--rerun", "off", "--zenoh-config",
                 str(tmp_path / "empty.json5")]) == 2
    err = capsys.readouterr().err
    assert "--zenoh-config: a secured fleet (the default) needs the router's endpoints" in err
    assert "or add --insecure to run an open fleet" in err and "nothing was started" in err
    assert not runs.exists() and not started
    # with --insecure it runs open, and says the config's (Zenoh's default) endpoint is reachable
    main(["launch", CONFIG, "--runs-dir", str(runs), "--rerun", "off", "--zenoh-config",
          str(tmp_path / "empty.json5"), "--insecure"])
    assert len(started) == 1
    assert "WARNING: --insecure: anyone who reaches tcp/[::]:7447 can" in capsys.readouterr().err


def test_insecure_is_refused_with_secure_and_says_what_it_allows(tmp_path, capsys, monkeypatch):
    assert main(["launch", CONFIG, "--runs-dir", str(tmp_path), "--listen", "tcp/0.0.0.0:7447", "--secure",
                 "--insecure"]) == 2
    assert "--insecure: contradicts --secure" in capsys.readouterr().err
    started = _started(monkeypatch)
    main(["launch", CONFIG, "--logs", str(tmp_path / "run"), "--rerun", "off", "--listen", "tcp/192.168.1.10:7447",
          "--insecure"])
    assert started and started[0][0].listen == ("tcp/192.168.1.10:7447",)
    err = capsys.readouterr().err
    assert "WARNING: --insecure: anyone who reaches tcp/192.168.1.10:7447 can, without any credential: stop" in err


class _NoRun:
    def __init__(self, run):
        from pathlib import Path

        self.metrics_out = Path(run) / "absent.json"
        self.metrics_at = None
        self.logs = Path(run) / "logs"


KILL = """
[[event]]
at = 1.0
action = "kill"
vehicle = "usv2"
"""


def test_sim_prints_the_fleets_events_as_launch_does(tmp_path, capsys):
    """`cdus sim` printed no events; it prints them as the launcher does (ConsoleQuota.printed),
    the links lossy by design in one line; -q prints none."""
    from cdus.app.cli import main

    cfg = tmp_path / "kill.toml"
    cfg.write_text(open("configs/lake_circle.toml").read() + KILL)
    args = ["sim", str(cfg), "--duration", "2", "--set", "link.loss=0.1", "--rerun", "off", "--runs-dir",
            str(tmp_path / "runs")]
    assert main(args) == 0
    out = capsys.readouterr().out
    events = [line for line in out.splitlines() if line.startswith("  event: ")]
    assert events == ["  event: t = 0.00 s: link faults from t = 0: loss 0.1 on 12 links (all)",
                      "  event: t = 1.00 s: scheduled kill of usv2 (t = 1 s)",
                      "  event: t = 1.00 s: the live graph (5 vehicles) still has a spanning tree"]
    assert main([*args, "-q"]) == 0
    assert "event:" not in capsys.readouterr().out


def test_sim_prints_a_change_of_many_links_as_one_line(tmp_path, capsys):
    """Issue 27: a change of every link (a down window, a partition) was a line per link, twelve
    on lake_circle. Now one line per change, in time order, as the launcher prints it."""
    from cdus.app.cli import main

    cfg = tmp_path / "down.toml"
    cfg.write_text(open("configs/lake_circle.toml").read() + """
[[link.partition]]
from = 1.0
to = 2.0
groups = [["usv1", "usv2", "usv3"], ["uav1", "uav2", "uav3"]]

[[link.down]]
from = 3.0
to = 3.5
""")
    assert main(["sim", str(cfg), "--duration", "5", "--rerun", "off", "--runs-dir", str(tmp_path / "runs")]) == 0
    events = [line for line in capsys.readouterr().out.splitlines()
              if line.startswith("  event: ") and "dropped in a row" not in line]
    assert events == [
        "  event: t = 1.00 s: 4 links down (from t = 1.00 s): uav3->usv1, uav1->usv3, usv3->uav1, usv1->uav3",
        "  event: t = 2.00 s: 4 links up (from t = 2.00 s): uav3->usv1, uav1->usv3, usv3->uav1, usv1->uav3",
        "  event: t = 3.00 s: 12 links down (from t = 3.00 s): usv2->usv1, uav3->usv1, usv1->usv2, usv3->usv2 "
        "and 8 more",
        "  event: t = 3.50 s: 12 links up (from t = 3.50 s): usv2->usv1, uav3->usv1, usv1->usv2, usv3->usv2 "
        "and 8 more"], events


def test_cdus_launch_says_the_events_past_the_end_once_where_it_starts(tmp_path, capsys, monkeypatch):
    started = _started(monkeypatch)
    main(["launch", CONFIG, "--logs", str(tmp_path / "run"), "--rerun", "off", "--insecure", "--duration", "2",
          "--set", LATE])
    assert len(started) == 1
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if line.startswith("note:")]
    assert notes == [line for line in err.splitlines() if "past the run's end" in line] and len(notes) == 3
    assert "note: event[3] (formation at 2.5 s) is past the run's end (2 s): it will not apply" in notes


def test_a_launch_into_a_run_directory_in_use_starts_nothing_and_touches_nothing(tmp_path, capsys, monkeypatch):
    """Issue 27, broken 5: a second `cdus launch` with the first's --logs replaced its
    secure/ground.json5 (its printed ground-station line stopped working), its logs and its
    metrics. Refused with exit 2 before anything is written; free again once the first ends."""
    from cdus.app.launcher import RunDirLock

    started = _started(monkeypatch)
    run = tmp_path / "run"
    main(["launch", CONFIG, "--logs", str(run), "--rerun", "off"])
    ground = (run / "secure" / "ground.json5").read_bytes()
    capsys.readouterr()
    with RunDirLock(run):  # the first launcher, still running
        assert main(["launch", CONFIG, "--logs", str(run), "--rerun", "off"]) == 2
        out, err = capsys.readouterr()
        assert f"--logs: another `cdus launch` is running into {run} now" in err
        assert "give another --logs" in err and "nothing was started" in err and not out
        assert (run / "secure" / "ground.json5").read_bytes() == ground and len(started) == 1
    main(["launch", CONFIG, "--logs", str(run), "--rerun", "off"])  # it ended: the directory is free
    assert len(started) == 2


@pytest.mark.parametrize("bad", ["symlink", "directory", "fifo", "run_is_a_file"])
def test_a_run_directory_that_cannot_be_held_starts_nothing_and_says_why(tmp_path, capsys, monkeypatch, bad):
    """A lock file that is a symlink was followed (its target, outside the run directory, created);
    one that is a directory, or a run directory that cannot be made (read-only, under a file), was
    an OSError traceback from RunDirLock. Each is an error naming the path, exit 1, nothing started."""
    started = _started(monkeypatch)
    run = tmp_path / "run"
    run.mkdir()
    lock = run / ".launch.lock"
    target = tmp_path / "elsewhere"
    if bad == "symlink":
        lock.symlink_to(target)
    elif bad == "directory":
        lock.mkdir()
    elif bad == "fifo":
        os.mkfifo(lock)
    else:
        (tmp_path / "file").write_text("")
        run = tmp_path / "file" / "run"
    assert main(["launch", CONFIG, "--logs", str(run), "--rerun", "off"]) == 1
    out, err = capsys.readouterr()
    assert f"cannot hold the run directory {run}" in err and "nothing was started" in err, err
    assert "Traceback" not in err and not started and not target.exists()
    assert "symbolic link" in err if bad == "symlink" else True
    assert not (run / "secure").exists() if bad != "run_is_a_file" else True


@pytest.mark.parametrize("argv, meant", [
    (["sim", CONFIG, "--set", "link.loss", "0.2"], "--set link.loss=0.2"),
    (["launch", CONFIG, "--set=link.loss", "0.2", "-q"], "--set link.loss=0.2"),
    (["sim", "--set", "vehicle.usv1.gains.k", "-1", CONFIG], "--set vehicle.usv1.gains.k=-1"),
    (["sweep", CONFIG, "--out", "x", "--set", "link.loss", "0,0.2"], "--set link.loss=0,0.2"),
])
def test_a_set_with_a_space_for_the_equals_says_what_was_meant(argv, meant, capsys):
    """Issue 27: `--set link.loss 0.2` printed the top-level usage and "unrecognized arguments:
    0.2". It says what was meant, and starts nothing."""
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert f"did you mean {meant}?" in err and "nothing was started" in err and "usage: cdus [-h]" not in err
    assert not out


def test_a_set_whose_next_word_is_the_config_is_not_taken_for_its_value(capsys):
    assert main(["sim", "--set", "link.loss", CONFIG, "-q"]) == 2  # the value is missing: the config parser says so
    assert "did you mean" not in capsys.readouterr().err


from tests.fullfs import full_fs  # noqa: E402,F401  (the fixture)


def test_cdus_sim_on_a_full_disk_says_so_and_keeps_its_metrics(full_fs, tmp_path, capsys, monkeypatch):
    """Issue 27, broken 2, for cdus sim: the metrics write on a full disk was a traceback and the
    run was lost. The failure is said (which file, why), the metrics kept in the temporary
    directory, else printed; exit 1."""
    assert main(["sim", CONFIG, "--duration", "1", "-q", "--rerun", "off", "--metrics-out", str(full_fs / "m.json"),
                 "--trace-out", str(full_fs / "t.npz")]) == 1
    out, err = capsys.readouterr()
    assert f"error: could not write the metrics to {full_fs / 'm.json'}: No space left on device" in err
    assert f"error: could not write the trace to {full_fs / 't.npz'}: No space left on device" in err
    kept = next(ln for ln in out.splitlines() if ln.startswith("  metrics: "))
    where = Path(kept.split()[1])
    assert kept.endswith(f"(not {full_fs / 'm.json'}: it could not be written)") and json.loads(where.read_text())
    where.unlink()
    assert "trace:" not in out and not (full_fs / "t.npz").exists()
    monkeypatch.setattr("tempfile.tempdir", str(full_fs))  # nowhere to keep them: printed
    assert main(["sim", CONFIG, "--duration", "1", "-q", "--rerun", "off", "--metrics-out", str(full_fs / "m.json")]) == 1
    out, _ = capsys.readouterr()
    assert json.loads(out.split("  metrics (no file could take them):\n")[1])["duration_s"] == 1.0


def test_a_launch_into_a_full_disk_starts_nothing_and_says_why(full_fs, capsys):
    assert main(["launch", CONFIG, "--logs", str(full_fs / "run"), "--rerun", "off"]) == 1
    err = capsys.readouterr().err
    assert f"error: cannot write the run's credentials into {full_fs / 'run' / 'secure'}: No space left on device; " \
           "nothing was started" in err
    assert main(["launch", CONFIG, "--logs", str(full_fs / "run2"), "--rerun", "off", "--insecure"]) == 1
    assert f"error: cannot write into the run directory {full_fs / 'run2'}: No space left on device" \
        in capsys.readouterr().err


def test_the_completions_a_launch_fails_on_are_completions():
    from cdus.app.cli import NOT_COMPLETED_FAILS
    from cdus.wire.schemas import COMPLETED, COMPLETIONS

    assert set(NOT_COMPLETED_FAILS) < set(COMPLETIONS) and COMPLETED not in NOT_COMPLETED_FAILS


def test_a_world_that_dies_while_the_fleet_comes_up_leaves_metrics_that_say_so(tmp_path, capsys, monkeypatch):
    """Attacker review: a world killed before it had finished starting left no metrics.json at
    all. The launcher writes world_lost metrics (completed: false) as for a world lost mid-run."""
    from cdus.app import launcher as launcher_mod

    def dying_world(self):
        argv = [sys.executable, "-c", "import os, signal; os.kill(os.getpid(), signal.SIGKILL)"]
        return launcher_mod.Child("world", argv, self.logs / "world.log")

    monkeypatch.setattr(launcher_mod.Launcher, "_world", dying_world)
    run = tmp_path / "run"
    assert main(["launch", CONFIG, "--logs", str(run), "--rerun", "off", "--duration", "2", "-q"]) == 1
    out, err = capsys.readouterr()
    m = Metrics.read(run / "metrics.json")
    assert (m.completed, m.completion, m.written_by) == (False, "world_lost", "launcher"), m
    assert m.world_lost.world_exit == -9 and m.world_lost.last_status_t is None
    assert "the fleet did not come up" in out + err and "Traceback" not in out + err


class _Wrote(_NoRun):
    """A launch that ended with its world's metrics file at ``at``."""

    def __init__(self, run, at):
        super().__init__(run)
        self.metrics_out = self.metrics_at = at


@pytest.mark.parametrize("damage, says", [
    (lambda text: text, None),
    (lambda text: text.replace('"seed": 1', '"seed": "1"'), "metrics: seed: expected an integer, got '1'"),
    (lambda text: text[:200], "not a metrics JSON"),
])
def test_a_launch_reads_its_metrics_file_once_and_names_what_is_wrong_with_it(damage, says, tmp_path, capsys,
                                                                              monkeypatch):
    """`cdus launch` prints the summary of the world's metrics.json, read once into Metrics; a
    file that is not one (cut short by a full disk, a field of another version) is an error
    naming the file and the field, exit 1, never a traceback."""
    import cdus.app.cli as cli
    from cdus.sim.fleet import InProcessFleet

    sc = load_scenario(CONFIG, {"scenario.duration": 0.2})
    at = tmp_path / "metrics.json"
    at.write_text(damage(json.dumps(InProcessFleet(sc).run().metrics.to_dict())))
    monkeypatch.setattr(cli, "check_listen", lambda eps: None)
    import cdus.app.launcher as launcher  # cli imports launch where it runs it (its start-up stays light)
    monkeypatch.setattr(launcher, "launch", lambda scenario, run, router, opts: (0, _Wrote(run, at)))
    code = main(["launch", CONFIG, "--logs", str(tmp_path / "run"), "--rerun", "off", "--insecure"])
    out, err = capsys.readouterr()
    if says is None:
        assert code == 0 and "lake_circle (inproc, seed 1)" in out and f"metrics: {at}" in out
    else:
        assert code == 1 and f"error: the run's metrics cannot be read: {at}: " in err and says in err
        assert "Traceback" not in err and "seed 1)" not in out
