"""The launcher's supervision ([supervision]: restart policy, max_restarts, back-off), with
tiny stand-in processes and the launcher's clock in the test's hands: no Zenoh, no fleet,
no wall-clock assertions."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading

import pytest

from cdus.commands.vehicle import Kill
from cdus.app.launcher import Child, LaunchOptions, Launcher
from cdus.scenario.config import load_scenario
from cdus.sim.runmetrics import Metrics
from cdus.scenario.model import MAX_BACKOFF_S, Supervision
from cdus.wire.transport import Transport

EXIT_3 = [sys.executable, "-c", "import sys; sys.exit(3)"]
EXIT_0 = [sys.executable, "-c", "pass"]
SLEEP = [sys.executable, "-c", "import time; time.sleep(600)"]


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def make(tmp_path):
    made: list[Launcher] = []

    def make(restart: str, argv: list[str], max_restarts: int = 2, backoff_s: float = 1.0) -> tuple[Launcher, Child, FakeClock, list[str]]:
        sc = load_scenario("configs/lake_circle.toml", {"supervision.max_restarts": max_restarts,
                                                         "supervision.backoff_s": backoff_s})
        lines: list[str] = []
        clock = FakeClock()
        la = Launcher(sc, tmp_path / "run", Transport(mode="peer", listen=("tcp/127.0.0.1:0",)),
                      LaunchOptions(fleet="t", restart=restart), log=lines.append, clock=clock)
        c = la.children["usv1"] = Child("usv1", argv, la.logs / "usv1.log")
        c.start(la.env)
        made.append(la)
        return la, c, clock, lines

    yield make
    for la in made:  # nothing outlives the test
        for c in la.children.values():
            if c.running():
                c.signal_group(signal.SIGKILL)
                c.proc.wait()
            c.poll()


def exited(c: Child) -> None:
    """Wait for the stand-in process to exit (it exits at once or was killed)."""
    c.proc.wait(timeout=60)


def test_on_failure_restarts_after_a_doubling_backoff_and_gives_up_after_max_restarts(make):
    la, c, clock, lines = make("on-failure", EXIT_3, max_restarts=2, backoff_s=1.0)
    starts = []
    for n, wait in enumerate([1.0, 2.0]):  # backoff(0), backoff(1)
        exited(c)
        la._watch_agents()
        assert c.exit_code == 3 and c.restart_at == clock.now + wait
        assert f"restarting it in {wait:g} s" in lines[-1]
        pid = c.proc.pid
        clock.now += wait - 0.01
        la._watch_agents()
        assert c.proc.pid == pid  # not before its back-off is over
        assert la._wait_s() == pytest.approx(0.01)  # the watch loop sleeps no longer than that
        clock.now += 0.01
        la._watch_agents()
        assert c.proc.pid != pid and c.supervised_restarts == n + 1
        starts.append(c.proc.pid)
    exited(c)
    la._watch_agents()
    assert c.given_up and c.restart_at is None and c.supervised_restarts == 2
    assert "gives up on it (supervision.max_restarts = 2)" in lines[-1] and "usv1 exited with status 3" in lines[-1]
    clock.now += 1000
    la._watch_agents()
    assert c.proc.pid == starts[-1] and c.restarts == 2  # it stays down


def test_the_backoff_is_capped():
    sv = Supervision("always", 50, 0.5)
    assert [sv.backoff(n) for n in range(4)] == [0.5, 1.0, 2.0, 4.0]
    assert sv.backoff(40) == MAX_BACKOFF_S


def test_on_failure_leaves_a_clean_exit_down(make):
    la, c, clock, lines = make("on-failure", EXIT_0)
    exited(c)
    la._watch_agents()
    assert c.exit_code == 0 and c.restart_at is None and not c.given_up
    assert "it stays down" in lines[-1]


def test_always_restarts_a_clean_exit_too(make):
    la, c, clock, lines = make("always", EXIT_0, backoff_s=0.5)
    exited(c)
    la._watch_agents()
    assert c.restart_at == clock.now + 0.5


def test_never_restarts_nothing(make):
    la, c, clock, lines = make("never", EXIT_3)
    exited(c)
    la._watch_agents()
    clock.now += 1000
    la._watch_agents()
    assert c.restarts == 0 and c.restart_at is None and "restart policy never" in lines[-1]


def test_a_vehicle_killed_by_a_signal_is_a_failure(make):
    la, c, clock, lines = make("on-failure", SLEEP)
    c.signal_group(signal.SIGKILL)
    exited(c)
    la._watch_agents()
    assert "was killed by signal 9; restarting it" in lines[-1] and c.restart_at is not None


def test_zero_max_restarts_gives_up_at_the_first_exit(make):
    la, c, clock, lines = make("always", EXIT_3, max_restarts=0)
    exited(c)
    la._watch_agents()
    assert c.given_up and c.restart_at is None and "gives up" in lines[-1]


def test_a_scheduled_kill_is_not_restarted_by_the_policy(make):
    la, c, clock, lines = make("always", SLEEP)
    c.intended_exit = True  # what a scheduled kill marks
    c.signal_group(signal.SIGKILL)
    exited(c)
    la._watch_agents()
    assert c.restart_at is None and lines == []


def test_nothing_is_restarted_once_the_run_is_stopping(make):
    la, c, clock, lines = make("always", EXIT_3)
    la.finished = True  # the world ended the run: agents exiting is expected
    exited(c)
    la._watch_agents()
    assert c.restart_at is None and c.exit_code is None and lines == []


def test_the_policy_comes_from_the_options_and_the_limits_from_the_scenario(make):
    la, c, clock, lines = make("on-failure", EXIT_0, max_restarts=4, backoff_s=2.5)
    assert (la.supervision.restart, la.supervision.max_restarts, la.supervision.backoff_s) == ("on-failure", 4, 2.5)


# ---------------------------------------------------------------- what reaches the launcher over the wire

import json  # noqa: E402
import math  # noqa: E402

import msgpack  # noqa: E402
from hypothesis import given, settings, strategies as st  # noqa: E402

from cdus.app.launcher import COMMAND_HZ, OMEGA_MARGIN, WORLD_LOST  # noqa: E402
from cdus.wire.messages import LAUNCHER_OPS, encode_control  # noqa: E402
from cdus.wire.schemas import FleetEvent, encode_event, encode_status, status_signature  # noqa: E402
from cdus.sim.reports import ConsoleQuota, link_state_event, scheduled_fault  # noqa: E402


class Sample:
    def __init__(self, payload: bytes, key: str = "cdus/t/to/+launcher+/cmd", attachment: bytes | None = None):
        self.payload = type("P", (), {"to_bytes": lambda _self: payload})()
        self.key_expr = key
        self.attachment = None if attachment is None else type("A", (), {"to_bytes": lambda _self: attachment})()


def world_says(la: Launcher, payload: bytes) -> None:
    """A status from the world this launcher started: signed with the key it was handed."""
    la._on_status(Sample(payload, "cdus/t/world/status", status_signature(la.status_key, payload)))


def quiet_launcher(tmp_path, **opts) -> tuple[Launcher, list[str]]:
    lines: list[str] = []
    sc = load_scenario("configs/lake_circle.toml")
    la = Launcher(sc, tmp_path / "run", Transport(mode="router", listen=("tcp/127.0.0.1:0",)),
                  LaunchOptions(fleet="t", **opts), log=lines.append)
    return la, lines


def test_the_launchers_key_moves_the_scenarios_own_vehicles_only(tmp_path):
    la, lines = quiet_launcher(tmp_path, remote=("uav3",))
    for vid in ("usv1", "usv2", "uav3"):
        if vid != "uav3":
            la.children[vid] = Child(vid, SLEEP, la.logs / f"{vid}.log")
    la.children["world"] = Child("world", SLEEP, la.logs / "world.log")
    for op in LAUNCHER_OPS:
        la._on_fault_request(Sample(encode_control(op, vehicle="world")))
    la._on_fault_request(Sample(encode_control("kill", vehicle="uav3")))  # remote: not ours to kill
    la._on_fault_request(Sample(encode_control("kill", vehicle="\x1b]0;pwned\x07")))
    la._on_fault_request(Sample(b"\x92\x01"))
    la._on_fault_request(Sample(encode_control("kill", vehicle="usv2")))
    assert la.requests == [Kill("usv2")]
    assert la.rejected == {"command not_a_vehicle": 5, "command remote": 1, "command malformed": 1}
    assert len(lines) == 3 and not any("\x1b" in ln or "\x07" in ln for ln in lines), lines


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.binary(max_size=300),
                 st.builds(lambda op, v: encode_control(op, vehicle=v),
                           st.sampled_from([*LAUNCHER_OPS, "stop", "grant"]), st.one_of(st.text(max_size=80),
                                                                                        st.sampled_from(["world", "usv1", "launcher"]))),
                 st.builds(lambda d: msgpack.packb(d), st.dictionaries(st.text(max_size=5),
                                                                        st.one_of(st.integers(-2**63, 2**64 - 1), st.text(max_size=5),
                                                                                  st.floats()), max_size=4))))
def test_no_message_on_the_launchers_key_escapes_or_goes_uncounted(tmp_path_factory, payload):
    la, _ = quiet_launcher(tmp_path_factory.mktemp("l"))
    la.children["usv1"] = Child("usv1", SLEEP, la.logs / "usv1.log")
    la.children["world"] = Child("world", SLEEP, la.logs / "world.log")
    la._on_fault_request(Sample(payload))
    assert len(la.requests) + sum(la.rejected.values()) == 1
    assert all(fault.vehicle == "usv1" for fault in la.requests)


def status(t: float) -> bytes:
    return encode_status(t, 250.0, "lockstep", ["usv1"], ["usv1"], None, None, [], False)


def test_a_world_status_with_a_time_that_is_not_a_plausible_number_is_dropped(tmp_path):
    la, lines = quiet_launcher(tmp_path)
    world_says(la, status(12.5))
    for bad in (math.nan, math.inf, 1e308, -5.0):
        raw = msgpack.unpackb(status(0.0))
        raw["t"] = bad
        world_says(la, msgpack.packb(raw))
    world_says(la, b"junk")
    assert la.status.t == 12.5
    assert sum(la.rejected.values()) == 5 and la.rejected["status malformed"] == 1, la.rejected
    # 1e308 and -5 s are numbers: the status decoder refuses them as out of range, or the
    # launcher's own check of the run's time does
    assert la.rejected.get("status t", 0) + la.rejected.get("status range", 0) == 2, la.rejected


def test_events_are_printed_escaped(tmp_path):
    la, lines = quiet_launcher(tmp_path)
    la._on_event(Sample(encode_event(FleetEvent.of(1.0, "fleet", "paused\x1b[2J\r\nt = 99 s: all good"))))
    la._print_events(final=True)
    assert lines and all("\x1b" not in ln and "\n" not in ln and "\r" not in ln for ln in lines), lines
    assert "\\x1b[2J\\r\\n" in lines[0]


def test_events_are_printed_in_time_order_a_link_change_as_one_line(tmp_path):
    """Issue 27: a ground station's `link loss=0.1` printed 12 lines, one per link, and a second
    late (the links' states come with the agents' counters), after a kill stamped later. The
    launcher holds each event HOLD_S of its clock, then prints what is due in time order."""
    now = [100.0]
    la, lines = quiet_launcher(tmp_path)
    la.clock = lambda: now[0]

    def hear(e):
        la._on_event(Sample(encode_event(e)))

    hear(FleetEvent.of(10.0, "link_changed", "link loss=0.1 by gs:alice"))
    hear(scheduled_fault(515, 0.02, "kill", "usv2"))  # t = 10.3 s, heard before the links' states
    now[0] += 0.5
    for j, (a, b) in enumerate([("usv1", "usv2"), ("usv2", "usv1"), ("usv2", "usv3"), ("usv3", "usv2"),
                                ("usv3", "uav1"), ("uav1", "usv3"), ("uav1", "uav2"), ("uav2", "uav1"),
                                ("uav2", "uav3"), ("uav3", "uav2"), ("uav3", "usv1"), ("usv1", "uav3")]):
        hear(link_state_event(10.02 + 0.02 * (j % 3), f"{a}->{b}", "lossy"))
    la._print_events()
    assert lines == []  # nothing held HOLD_S yet
    now[0] += ConsoleQuota.HOLD_S
    la._print_events()
    assert lines == [
        "  event: t = 10.00 s: link loss=0.1 by gs:alice",
        "  event: t = 10.02 s: 12 links lossy (from t = 10.02 s): usv1->usv2, usv3->usv2, uav1->uav2, uav3->uav2 "
        "and 8 more",
        "  event: t = 10.30 s: scheduled kill of usv2 (t = 10.3 s)"], lines
    hear(link_state_event(20.0, "usv1->usv2", "down"))
    la._print_events(final=True)  # the run is over: what is held, at once
    assert lines[-1] == "  event: t = 20.00 s: link usv1->usv2 down (from t = 20.00 s)"


def test_rate_limits_are_set_for_realtime_runs_only(tmp_path):
    la, _ = quiet_launcher(tmp_path, clock="lockstep")
    assert "downsampling" not in dict(la.router.extra)
    la, _ = quiet_launcher(tmp_path / "rt", clock="realtime")
    (ds,) = json.loads(dict(la.router.extra)["downsampling"])
    assert ds["flows"] == ["ingress"] and ds["messages"] == ["put"]
    rules = {r["key_expr"]: r["freq"] for r in ds["rules"]}
    assert rules == {**{f"cdus/t/to/*/omega/{v}": OMEGA_MARGIN * 50.0 for v in la.scenario.ids},
                     "cdus/t/to/*/cmd/*": COMMAND_HZ}


def test_a_world_that_died_leaves_metrics_that_say_so(tmp_path):
    la, _ = quiet_launcher(tmp_path, duration=40.0)
    world_says(la, status(12.5))
    la.alive = {"world", "usv1", "usv2"}
    m = la.write_world_lost(-9, 3.0)
    assert Metrics.read(la.metrics_out) == m
    assert m.completed is False and m.completion == WORLD_LOST and m.written_by == "launcher"
    assert m.world_lost.world_exit == -9 and m.world_lost.last_status_t == 12.5
    assert m.world_lost.alive_tokens == ("usv1", "usv2")
    assert m.duration_s == 12.5  # the top-level fields say what the world last said, not 0
    assert m.final_path_error_max == m.world_lost.last_status["path_error_max"]
    assert m.events[-1].text.startswith("the world process was killed by signal 9")
    from cdus.app.report import summary_table

    table = summary_table(m, la.scenario.vehicles)
    assert "lake_circle (lockstep" in table  # the CLI prints it as any other
    assert "NOT COMPLETED (world_lost)" in table  # and says it is not a finished run


def test_a_world_lost_before_its_first_tick_ran_no_simulated_time_not_a_negative_one(tmp_path):
    # attack: SIGKILL of the world just after "fleet up" (lockstep, its status at t = -T before tick
    # 0): metrics.json said duration_s -0.02 and the summary "-0.0 s simulated ... (-0x real time)"
    la, _ = quiet_launcher(tmp_path, duration=40.0)
    world_says(la, status(-0.02))
    m = la.write_world_lost(-9, 5.8)
    assert m.world_lost.last_status_t == -0.02  # what the world said, kept as it said it
    assert m.duration_s == 0.0 and m.realtime_factor == 0.0, m


def test_a_process_still_starting_at_the_ready_timeout_is_told_how_to_wait_longer(tmp_path):
    # attack: six 10,000-waypoint splines (each process checks and builds them: 12 s of CPU at
    # load 9) -> "uav3 did not come up within 30 s; its log ... (empty log)": nothing said the
    # process was alive and only slow, nor that --ready-timeout gives it longer
    from cdus.app.children import Child

    la, _ = quiet_launcher(tmp_path)
    log = tmp_path / "uav3.log"
    log.write_text("")
    la.children["uav3"] = Child("uav3", [], log)  # never started: poll() is None, as a process still running
    text = str(la._fail_start(["uav3"], 30.0))
    assert "did not come up within 30 s, still starting" in text and "--ready-timeout" in text, text


def test_the_summary_of_a_lost_world_says_what_is_not_known_not_never(tmp_path):
    """Review of issue 18: after the world died the summary said settle "never" next to a final
    |Φ| of 0.0235 m. The trace is lost with the world: the settle times are not known, the
    errors are those of its last status. The metrics' fields keep their meaning (null settle
    times, completion "world_lost")."""
    from cdus.app.report import summary_table

    la, _ = quiet_launcher(tmp_path, duration=40.0)
    ids = list(la.scenario.ids)
    world_says(la, encode_status(12.5, 40.0, "lockstep", ids[:-1], ids, 0.0235, 0.0012, [], False))
    m = la.write_world_lost(-9, 3.0)
    assert (m.path_settle_s, m.coord_settle_s, m.final_path_error_max) == (None, None, 0.0235)
    table = summary_table(m, la.scenario.vehicles)
    assert "never" not in table, table
    assert "NOT COMPLETED (world_lost): the world was lost at t = 12.5 s and the run's trace with it: the settle " \
           "times are not known, the errors below are those of the world's last status" in table
    assert "path settle (worst |Φ| < 0.1 m):             not known: the world was lost at t = 12.5 s" in table
    assert "coordination settle (worst edge < 0.05 rad): not known: the world was lost at t = 12.5 s" in table
    assert "worst |Φ| 0.0235 m, worst coordination error 0.0012 rad at the world's last status (t = 12.5 s)" in table
    assert "final worst" not in table
    gone = next(line for line in table.splitlines() if line.lstrip().startswith(ids[-1]))
    assert gone.endswith("(not live at the world's last status, t = 12.5 s)")
    # a world lost before its first status: nothing of the run is known
    la, _ = quiet_launcher(tmp_path / "early", duration=40.0)
    table = summary_table(la.write_world_lost(1, 2.0), la.scenario.vehicles)
    assert "never" not in table and "0.0 s simulated" not in table and "killed or paused" not in table, table
    assert "2.0 s wall; how far the run got is not known" in table
    assert "path settle (worst |Φ| < 0.1 m):             not known: the world was lost before its first status" \
        in table
    assert "worst |Φ| and coordination error: not known (the world was lost before its first status)" in table


def test_stop_ends_a_paused_vehicle_with_sigterm_not_after_the_grace_with_sigkill(tmp_path):
    la, lines = quiet_launcher(tmp_path, grace=2.0)
    c = la.children["usv1"] = Child("usv1", SLEEP, la.logs / "usv1.log")
    c.start(la.env)
    c.signal_group(signal.SIGSTOP)  # what a pause_vehicle fault does
    try:
        la.stop()
        assert c.proc.returncode == -signal.SIGTERM, (c.proc.returncode, lines)
    finally:
        if c.running():
            c.signal_group(signal.SIGKILL)
            c.proc.wait()


def test_stop_does_not_wait_out_the_grace_for_a_vehicle_that_never_came_up(tmp_path):
    """The world's stop reaches the processes that came up; one that never did (waiting for a
    neighbour's link that never came: a remote vehicle that did not connect) cannot hear it. The
    ladder waits for the others only, then SIGTERMs it: it used to run out the whole grace (5 s
    by default) first."""
    la, lines = quiet_launcher(tmp_path, grace=30.0)
    world = la.children["world"] = Child("world", [sys.executable, "-c", "pass"], la.logs / "world.log")
    up = la.children["usv1"] = Child("usv1", [sys.executable, "-c", "import time; time.sleep(0.5)"],
                                     la.logs / "usv1.log")  # stops on the world's word (here: by itself)
    never = la.children["uav1"] = Child("uav1", SLEEP, la.logs / "uav1.log")
    for c in (world, up, never):
        c.start(la.env)
    world.proc.wait()
    la.finished = True  # the world ended the run
    la.ever_alive |= {"world", "usv1"}
    waited: list[set[str]] = []
    real_wait = la._wait_exit

    def wait_exit(seconds, names=None):
        waited.append({n for n, c in la.children.items() if c.running() and (names is None or n in names)})
        real_wait(seconds) if names is None else real_wait(seconds, names)

    la._wait_exit = wait_exit
    try:
        la.stop()
        assert waited[0] == {"usv1"}, (waited, lines)  # the grace is for the ones told to stop
        assert up.proc.returncode == 0  # it was let finish
        assert never.proc.returncode == -signal.SIGTERM, (never.proc.returncode, lines)
    finally:
        for c in (up, never):
            if c.running():
                c.signal_group(signal.SIGKILL)
                c.proc.wait()


from tests.fullfs import full_fs  # noqa: E402,F401  (the fixture)


class PutLog:
    """The router's session as the stop ladder uses it: what was put, and whether the world had
    come up (declared its token) when it was."""

    def __init__(self, la: Launcher) -> None:
        self.la, self.puts = la, []

    def put(self, key, payload, **kw) -> None:
        self.puts.append((key, "world" in self.la.ever_alive))

    def close(self) -> None:
        pass


def test_a_ctrl_c_while_the_world_starts_waits_for_it_to_listen_before_asking_it_to_stop(tmp_path):
    """A Ctrl-C right after `cdus launch`: the world is still starting, not yet subscribed, and
    a stop put then is heard by no one: the ladder ran out the whole grace (5 s) before its
    SIGTERM. It now waits for the world's token (up to the grace), then asks it."""
    la, lines = quiet_launcher(tmp_path, grace=30.0)
    world = la.children["world"] = Child("world", [sys.executable, "-c", "import time; time.sleep(0.6)"],
                                         la.logs / "world.log")  # up at 0.2 s below, then stops (here: by itself)
    world.start(la.env)
    la.session = log = PutLog(la)

    def comes_up() -> None:
        with la.cond:
            la.alive.add("world")
            la.ever_alive.add("world")
            la.cond.notify_all()

    timer = threading.Timer(0.2, comes_up)
    timer.start()
    try:
        la.stop()
        assert log.puts and all(up for _, up in log.puts), (log.puts, lines)  # asked once it listens
        assert world.proc.returncode == 0, (world.proc.returncode, lines)  # and let finish, not SIGTERMed
    finally:
        timer.cancel()
        if world.running():
            world.signal_group(signal.SIGKILL)
            world.proc.wait()


def test_a_lost_world_on_a_full_disk_leaves_its_metrics_in_the_run_directory_or_printed(full_fs, tmp_path,
                                                                                        monkeypatch):
    """Issue 27, broken 2: the launcher's world_lost metrics died in a second traceback on the
    full disk. They are kept in the run directory; where nothing takes them, printed."""
    la, lines = quiet_launcher(tmp_path, duration=40.0, metrics_out=full_fs / "metrics.json")
    world_says(la, status(12.5))
    m = la.write_world_lost(-9, 3.0)
    assert la.metrics_at == la.run_dir / "metrics.json" and Metrics.read(la.metrics_at) == m
    assert lines[0] == f"error: could not write the metrics to {full_fs / 'metrics.json'}: No space left on device"
    # nothing takes them (the run directory and the temporary directory full too): the terminal does
    la, lines = quiet_launcher(tmp_path / "again", duration=40.0, metrics_out=full_fs / "metrics.json")
    la.run_dir = full_fs
    monkeypatch.setattr("tempfile.tempdir", str(full_fs))
    m = la.write_world_lost(-9, 3.0)
    assert la.metrics_at is None
    assert lines[-2] == "the metrics could be written nowhere; here they are:"
    assert json.loads(lines[-1]) == m.to_dict()


def test_the_world_metrics_kept_elsewhere_are_found_there_not_taken_for_a_lost_world(tmp_path):
    """The world exits METRICS_ELSEWHERE_EXIT having kept its metrics at a fallback: the launcher
    finds them there (changed since the run began), and a stale file of an earlier run is not
    taken for them."""
    la, _ = quiet_launcher(tmp_path, metrics_out=tmp_path / "elsewhere" / "metrics.json")
    w = la.children["world"] = Child("world", EXIT_0, la.logs / "world.log")
    w.start(la.env)
    exited(w)
    (la.run_dir / "metrics.json").write_text('{"stale": true}')
    marks = {p: la.metrics_mark(p) for p in (la.metrics_out, *la.world_fallbacks())}
    assert la.world_fallbacks()[0] == la.run_dir / "metrics.json"
    assert la.find_world_metrics(marks) is None  # the stale one is not this run's
    (la.run_dir / "metrics.json").unlink()
    (la.run_dir / "metrics.json").write_text('{"completed": true}')
    assert la.find_world_metrics(marks) == la.run_dir / "metrics.json"


def test_a_run_directory_in_use_is_refused_and_a_dead_launchers_is_free_again(tmp_path):
    """Issue 27, broken 5: two `cdus launch` with one --logs overwrote each other (logs, metrics,
    the first's ground credentials). One holds the directory while it runs; another is refused
    before anything is written; once the holder is gone, even SIGKILLed, it is free."""
    from cdus.app.launcher import RunDirInUse, RunDirLock

    run = tmp_path / "run"
    with RunDirLock(run):
        with pytest.raises(RunDirInUse, match=f"another `cdus launch` is running into {run} now"):
            RunDirLock(run)
    RunDirLock(run).release()  # released: free again
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from pathlib import Path; "
                               "from cdus.app.launcher import RunDirLock; l = RunDirLock(Path(sys.argv[1])); "
                               "print('held', flush=True); time.sleep(600)", str(run)],
                              stdout=subprocess.PIPE, text=True, start_new_session=True)
    try:
        assert holder.stdout.readline() == "held\n"
        with pytest.raises(RunDirInUse):  # another process's hold
            RunDirLock(run)
    finally:
        os.killpg(holder.pid, signal.SIGKILL)
        holder.wait()
    with RunDirLock(run):  # a dead launcher's directory is reusable
        pass


def test_only_the_statuses_of_the_world_started_here_are_believed(tmp_path):
    """Issue 27: on an open fleet a forged world/status, then a SIGKILL of the world, put the
    forged values into the launcher's world_lost metrics. The launcher hands its world a key
    (STATUS_KEY_ENV, in its environment only); a status not signed with it, or replayed from
    earlier in the run, is counted and dropped."""
    la, lines = quiet_launcher(tmp_path, duration=3000.0)
    world_says(la, status(12.5))
    forged = status(2999.0)
    la._on_status(Sample(forged, "cdus/t/world/status"))  # unsigned
    la._on_status(Sample(forged, "cdus/t/world/status", status_signature(b"another key", forged)))
    la._on_status(Sample(forged, "cdus/t/world/status", status_signature(la.status_key, status(12.5))))  # another's
    world_says(la, status(3.0))  # a genuine one replayed, older than the newest
    assert la.status.t == 12.5
    assert la.rejected == {"status unsigned": 3, "status stale": 1}, la.rejected
    assert la.write_world_lost(-9, 3.0).world_lost.last_status_t == 12.5
    world_says(la, status(13.0))
    assert la.status.t == 13.0


def test_the_key_goes_to_the_world_alone(tmp_path, monkeypatch):
    from cdus.wire.schemas import STATUS_KEY_ENV

    monkeypatch.setenv(STATUS_KEY_ENV, "00" * 16)  # one in our own environment reaches no agent
    la, _ = quiet_launcher(tmp_path)
    assert la.world_env()[STATUS_KEY_ENV] == la.status_key.hex() and len(la.status_key) == 16
    assert STATUS_KEY_ENV not in la.env  # what the agents are started with
    assert quiet_launcher(tmp_path / "b")[0].status_key != la.status_key  # one per run


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=200), st.one_of(st.none(), st.binary(max_size=40)), st.booleans())
def test_no_status_is_believed_unless_signed_and_none_raises(tmp_path_factory, payload, attachment, sign):
    la, _ = quiet_launcher(tmp_path_factory.mktemp("s"))
    if sign:
        attachment = status_signature(la.status_key, payload)
    la._on_status(Sample(payload, "cdus/t/world/status", attachment))
    signed = attachment is not None and attachment == status_signature(la.status_key, payload)
    assert sum(la.rejected.values()) + (la.status is not None) == 1
    assert la.status is None or signed
def test_the_ros2_bridge_is_no_vehicle_to_restart_and_exists_only_when_asked(make, tmp_path):
    la, c, clock, lines = make("always", EXIT_0)
    bridge = la.children["ros2"] = Child("ros2", EXIT_3, la.logs / "ros2.log")
    bridge.start(la.env)
    exited(c)
    bridge.proc.wait(timeout=60)
    la._watch_agents()
    assert c.restart_at is not None and bridge.restart_at is None and not any("vehicle ros2" in ln for ln in lines)
    # said once (before, nothing: a SIGKILLed bridge's ROS 2 topics stopped with no word from the launcher)
    said = [ln for ln in lines if "ROS 2 bridge" in ln]
    assert said == [f"  the ROS 2 bridge exited with status 3: the ROS 2 topics stop, the run goes on; its log: "
                    f"{la.logs / 'ros2.log'}"]
    la._watch_agents()
    assert len([ln for ln in lines if "ROS 2 bridge" in ln]) == 1
    argv = la._bridge().argv
    assert argv[1:3] == ["-m", "cdus.ros2"] and argv[argv.index("--fleet") + 1] == "t"
