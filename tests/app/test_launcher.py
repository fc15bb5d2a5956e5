"""The launcher's supervision ([supervision]: restart policy, max_restarts, back-off), with
tiny stand-in processes and the launcher's clock in the test's hands: no Zenoh, no fleet,
no wall-clock assertions."""

from __future__ import annotations

import signal
import sys

import pytest

from cdus.app.launcher import Child, LaunchOptions, Launcher
from cdus.scenario.config import load_scenario
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
