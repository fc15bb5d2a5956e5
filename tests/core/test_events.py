"""The roster scheduled faults make: every runner derives the same ticks from the same events."""

from __future__ import annotations

from cdus.core.events import Event, RosterChange, event_tick, plan_roster

IDS = ["a", "b", "c"]
T = 0.02


def test_an_event_lands_on_the_first_tick_at_or_after_its_time():
    assert event_tick(1.0, T) == 50
    assert event_tick(1.001, T) == 51
    assert event_tick(0.0, T) == 0


def test_kill_is_gone_for_good():
    assert plan_roster([Event(1.0, "kill", "b")], IDS, T) == (RosterChange(50, 1, "gone"),)


def test_restart_is_gone_and_back_fresh_on_one_tick():
    assert plan_roster([Event(2.0, "restart", "a")], IDS, T) == (
        RosterChange(100, 0, "gone"), RosterChange(100, 0, "live", fresh=True))


def test_a_short_pause_is_held_a_long_one_lapses_with_the_lease():
    short = plan_roster([Event(1.0, "pause", "c"), Event(1.5, "resume", "c")], IDS, T)
    assert short == (RosterChange(50, 2, "paused"), RosterChange(75, 2, "live"))
    long = plan_roster([Event(1.0, "pause", "c"), Event(5.0, "resume", "c")], IDS, T, lease=1.0)
    assert long == (RosterChange(50, 2, "paused"), RosterChange(100, 2, "gone"), RosterChange(250, 2, "live"))
    never = plan_roster([Event(1.0, "pause", "c")], IDS, T, lease=0.5)
    assert never == (RosterChange(50, 2, "paused"), RosterChange(75, 2, "gone"))


def test_events_that_change_nothing_are_ignored():
    assert plan_roster([Event(1.0, "resume", "a")], IDS, T) == ()  # not paused
    assert plan_roster([Event(1.0, "kill", "a"), Event(2.0, "kill", "a")], IDS, T) == (RosterChange(50, 0, "gone"),)
    assert plan_roster([Event(1.0, "kill", "a"), Event(2.0, "pause", "a")], IDS, T) == (RosterChange(50, 0, "gone"),)


def test_a_killed_vehicle_can_be_restarted():
    assert plan_roster([Event(3.0, "restart", "b"), Event(1.0, "kill", "b")], IDS, T) == (
        RosterChange(50, 1, "gone"), RosterChange(150, 1, "gone"), RosterChange(150, 1, "live", fresh=True))
