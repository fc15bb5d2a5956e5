"""vehicle_agent.lockstep: a lockstep agent steps each granted tick once its neighbours' broadcasts
are in, waits for nothing the roster says is gone, and no hostile sample changes its run."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from cdus.sim.build import listeners_of
from cdus.wire import keys
from cdus.wire.messages import decode_omega, decode_states
from cdus.wire.schemas import decode_stats
from tests.vehicle_agent.fake_session import FLEET, ME, ctl, forged, granted, omega_from, stop_when_idle
from vehicle_agent import lockstep


def test_a_lockstep_run_steps_each_granted_tick_once_its_neighbours_broadcasts_are_in(fake):
    a, s, lines = fake(duration=0.1)  # ticks 0..5 at 50 Hz
    assert a.last_tick == 5
    ctl(s, "join", tick=0)
    ctl(s, "grant", until=5)
    for seq in range(5):  # tick n needs each neighbour's broadcast of tick n - 1
        omega_from(s, a, "usv2", seq)
        omega_from(s, a, "uav3", seq)
    stop_when_idle(s)
    assert a.run() == 6
    sent = [decode_omega(p) for p in s.pubs[keys.omega(FLEET, ME, listeners_of(a.scenario, ME))].puts]
    assert [m.seq for m in sent] == list(range(5))  # none at the last tick: nobody would use it
    assert all(m.sender == 0 for m in sent)
    rows = [r for p in s.pubs[keys.state(FLEET, ME)].puts for r in decode_states(p)]
    assert [r.tick for r in rows] == list(range(6))
    assert a.node.counters.delivered == 10 and not a.rejected
    stats = decode_stats(s.pubs[keys.stats(FLEET, ME)].puts[-1])
    assert stats.id == ME and stats.tick == 6 and stats.delivered == 10


def test_a_lockstep_agent_does_not_step_past_its_grant(fake):
    a, s, lines = fake(duration=0.1)
    granted(s, a, until=2)
    with pytest.raises(AssertionError, match="empty inbox"):
        a.run()  # it waits for a grant beyond tick 2 that never comes
    assert a.ticks_done == 3


def test_a_lockstep_agent_waits_for_a_missing_neighbour(fake):
    a, s, lines = fake(duration=0.1)
    ctl(s, "join", tick=0)
    ctl(s, "grant", until=5)
    omega_from(s, a, "usv2", 0)  # uav3's tick-0 broadcast never comes
    with pytest.raises(AssertionError, match="empty inbox"):
        a.run()
    assert a.ticks_done == 1  # tick 0 needs nothing; tick 1 needs uav3's seq 0


def test_a_neighbour_gone_by_the_roster_is_not_awaited(fake):
    a, s, lines = fake(duration=0.1)
    ctl(s, "join", tick=0)
    ctl(s, "roster", vehicle="uav3", tick=1, state="gone", fresh=False)
    ctl(s, "grant", until=5)
    omega_from(s, a, "uav3", 0)  # sent at tick 0, while live: tick 1 needs it
    for seq in range(5):
        omega_from(s, a, "usv2", seq)
    stop_when_idle(s)
    assert a.run() == 6
    assert any("neighbour uav3 gone from tick 1" in ln for ln in lines)


def _lockstep_run(fake, hostile) -> list:
    """A lockstep run of 6 ticks with ``hostile(s, a, seq)`` samples before each genuine pair."""
    a, s, lines = fake(duration=0.1)
    ctl(s, "join", tick=0)
    ctl(s, "grant", until=5)
    for seq in range(5):
        hostile(s, a, seq)
        omega_from(s, a, "usv2", seq)
        omega_from(s, a, "uav3", seq)
    stop_when_idle(s)
    assert a.run() == 6
    return [r for p in s.pubs[keys.state(FLEET, ME)].puts for r in decode_states(p)], a


_FIXTURE = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@_FIXTURE
@given(data=st.data())
def test_hostile_samples_out_of_window_or_malformed_never_change_a_lockstep_agents_run(fake, data):
    clean, _ = _lockstep_run(fake, lambda s, a, seq: None)
    n_hostile = [0]

    def hostile(s, a, seq):
        for _ in range(data.draw(st.integers(0, 3))):
            vid = data.draw(st.sampled_from(["usv2", "uav3"]))
            how = data.draw(st.sampled_from(["future", "inconsistent", "stale", "bytes", "ctl"]))
            w = data.draw(st.floats(allow_nan=False))
            n_hostile[0] += 1
            if how == "future":
                q = data.draw(st.integers(5 + lockstep.LOCKSTEP_SEQ_MARGIN + 1, 2**32 - 1))
                forged(s, a, vid, q, q * a.period, w)
            elif how == "inconsistent":
                forged(s, a, vid, seq, data.draw(st.floats().filter(lambda t: t != seq * a.period)), w)
            elif how == "stale" and seq > 0:
                q = data.draw(st.integers(0, seq - 1))
                forged(s, a, vid, q, q * a.period, w)
            elif how == "ctl":  # a control message out of range
                ctl(s, "grant", until=data.draw(st.integers(6, 2**40)))
            else:
                omega_from(s, a, vid, seq, payload=data.draw(st.binary(max_size=40)))

    rows, a = _lockstep_run(fake, hostile)
    assert rows == clean
    assert sum(a.rejected.values()) == n_hostile[0]


def test_a_lockstep_agent_reports_its_first_tick_after_a_join_or_a_resume_at_once(fake):
    """The world says a caught-up process's catch-up again while it has reported no tick
    (world_sim CATCHUP_RESEND, 1 s); rows go in batches of 50, and a fleet slower than 50 ticks
    a second then heard the catch-up again after stepping past it (a replay must change nothing,
    but better that it reach only a process that has not stepped)."""
    a, s, lines = fake(duration=1.0)
    ctl(s, "join", tick=0)
    ctl(s, "roster", vehicle=ME, tick=3, state="paused", fresh=False)
    ctl(s, "roster", vehicle=ME, tick=8, state="live", fresh=False)
    ctl(s, "grant", until=20)
    for seq in range(20):
        omega_from(s, a, "usv2", seq)
        omega_from(s, a, "uav3", seq)
    with pytest.raises(AssertionError, match="empty inbox"):
        a.run()  # waits for a grant past 20
    batches = [[r.tick for r in decode_states(p)] for p in s.pubs[keys.state(FLEET, ME)].puts]
    assert batches == [[0], [1, 2, 8], list(range(9, 21))], batches
