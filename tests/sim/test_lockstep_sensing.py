"""Lockstep's proximity-sensor decisions: contacts of a sample tick s are sent (Sense)
once every vehicle live at s has reported it, and no vehicle is granted past
s + latency - 1 before they are."""

import pytest

from cdus.core.events import Event
from cdus.sim.lockstep import GRANT_WINDOW, Grant, Lockstep, Sense

IDS = ("a", "b", "c")
T = 0.02


def grants(actions):
    return [a.until for a in actions if isinstance(a, Grant)]


def senses(actions):
    return [a.tick for a in actions if isinstance(a, Sense)]


def started(**kw) -> Lockstep:
    ls = Lockstep(IDS, T, 500, **kw)
    ls.start()
    return ls


def report(ls, upto, who=range(3)):
    for j in who:
        ls.on_report(j, upto)


def test_without_a_sensor_grants_run_a_window_ahead():
    ls = started()
    assert grants(ls.poll()) == [GRANT_WINDOW - 1]
    report(ls, 10)
    out = ls.poll()
    assert grants(out) == [10 + GRANT_WINDOW] and senses(out) == []


@pytest.mark.parametrize("every, latency", [(5, 1), (5, 3), (1, 1), (10, 7)])
def test_grants_stop_before_the_first_use_of_contacts_not_sent(every, latency):
    ls = started(sense_every=every, sense_latency=latency)
    out = ls.poll()
    assert senses(out) == [] and grants(out) == [latency - 1]  # tick 0's contacts are used from tick latency
    sent = -1
    for _ in range(30):
        report(ls, ls.granted)
        out = ls.poll()
        new = senses(out)
        assert new == list(range(sent + every if sent >= 0 else 0, ls.sensed + 1, every))
        sent = ls.sensed
        # never granted to a tick that needs a sample whose contacts are not out, and no less
        assert ls.granted == min(sent + every + latency - 1, sent + GRANT_WINDOW + 1)
    assert ls.sensed > 0


def test_a_sample_waits_for_every_live_vehicle_and_the_sense_comes_before_the_grant():
    ls = started(sense_every=5, sense_latency=2)
    ls.poll()  # grant 1
    report(ls, 1)
    out = ls.poll()
    assert senses(out) == [0] and out.index(Sense(0)) < out.index(Grant(6))
    report(ls, 5, who=[0, 1])  # c has not reported tick 5 yet
    ls.on_report(2, 4)
    out = ls.poll()
    assert senses(out) == [] and grants(out) == []
    ls.on_report(2, 6)
    out = ls.poll()
    assert senses(out) == [5] and grants(out) == [11]


def test_a_killed_vehicle_does_not_hold_the_sensor():
    """c is killed at 0.1 s (tick 5): tick 5 is complete without it, so its sample goes out."""
    ls = Lockstep(IDS, T, 500, (Event(0.1, "kill", "c"),), sense_every=5, sense_latency=1)
    ls.start()
    ls.poll()
    report(ls, 0)
    ls.poll()  # Sense(0), grant up to 4 (the kill waits at 4)
    report(ls, 4)
    ls.poll()  # the kill is asked of the launcher
    ls.on_fault_done(2)
    assert grants(ls.poll()) == [5]  # tick 5's sample is used from tick 6
    report(ls, 5, who=[0, 1])
    out = ls.poll()
    assert senses(out) == [5] and grants(out) == [10]


def test_bad_sensor_schedule():
    with pytest.raises(ValueError, match="sense_latency"):
        Lockstep(IDS, T, 10, sense_every=5, sense_latency=0)
