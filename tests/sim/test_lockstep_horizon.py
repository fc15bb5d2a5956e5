"""Horizon grants (cdus.sim.lockstep): a wide window sized to the fleet's speed, grants sent
only when they move by ``grant_step``, and always up to a limit (a fault, a sensor sample,
the end) at once, roster changes before the grant covering them."""

from __future__ import annotations

from cdus.core.events import Event
from cdus.sim.lockstep import GRANT_WINDOW, MAX_GRANT_WINDOW, Grant, Lockstep, Roster, horizon_window

IDS = ("a", "b", "c")
T = 0.1


def started(events=(), last_tick=10_000, window=400, step=100, **kw) -> Lockstep:
    ls = Lockstep(IDS, T, last_tick, events, window=window, grant_step=step, **kw)
    for j in range(len(IDS)):
        ls.on_alive(j, True)
    ls.start()
    return ls


def grants(actions) -> list[int]:
    return [a.until for a in actions if isinstance(a, Grant)]


def report(ls, upto):
    for j in range(len(IDS)):
        ls.on_report(j, upto)


def test_a_grant_moves_only_by_a_step_or_more():
    ls = started()
    assert grants(ls.poll()) == [399]
    report(ls, 50)
    assert grants(ls.poll()) == []  # 450 is only 51 past 399
    report(ls, 99)
    assert grants(ls.poll()) == [499]
    report(ls, 100)
    assert grants(ls.poll()) == []


def test_a_grant_up_to_a_limit_goes_at_once():
    ls = started(last_tick=420)
    assert grants(ls.poll()) == [399]
    report(ls, 25)
    assert grants(ls.poll()) == [420]  # only 21 more, but the end: no vehicle waits for a step that never comes
    ls = started([Event(41.0, "kill", "b")])  # tick 410
    assert grants(ls.poll()) == [399]
    report(ls, 15)
    assert grants(ls.poll()) == [409]  # the tick before the fault
    ls = started(sense_every=50, sense_latency=1)
    assert grants(ls.poll()) == [0]  # tick 0's contacts are used at tick 1


def test_scheduled_roster_changes_go_before_the_wide_grant_that_covers_them():
    ls = started([Event(30.0, "pause", "b"), Event(31.0, "resume", "b")], window=1000, step=250)
    out = ls.poll()
    kinds = [type(a).__name__ for a in out if isinstance(a, (Roster, Grant))]
    assert grants(out) == [299]  # the pause at tick 300 is a fault: the grant stops before it
    assert "Grant" in kinds and kinds.index("Grant") == len(kinds) - 1


def test_the_window_follows_the_fleets_speed():
    assert horizon_window(0.0, 0.25) == GRANT_WINDOW
    assert horizon_window(2000.0, 0.25) == 500
    assert horizon_window(1e9, 0.25) == MAX_GRANT_WINDOW
    assert horizon_window(10.0, 0.25) == GRANT_WINDOW
