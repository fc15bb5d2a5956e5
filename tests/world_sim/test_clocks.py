"""The world's two clocks (world_sim/clocks.py): picked once, and one effect-tick rule for
every run-time change."""

from __future__ import annotations

import math

import pytest

from cdus.sim.lockstep import GRANT_WINDOW, MAX_GRANT_WINDOW

from world_sim.clocks import EFFECT_LEAD_S, HORIZON_S, LockstepClock, RealtimeClock, pick_clock

from .test_commands import ask
from .test_world import started, world

CHANGES = [
    ("set_gains", {"gains": {"c": 2.0}, "vehicle": ""}),
    ("set_gains", {"gains": {"c": 3.0}, "vehicle": "usv1"}),
    ("formation", {"phases": {"usv2": 1.0}, "offsets": []}),
    ("path", {"vehicle": "usv1", "path": {"family": "circle", "center": [0, 0], "radius": 5}}),
    ("link", {"link": {"loss": 0.1}, "at": -1.0}),  # as soon as possible
    ("link", {"link": {"loss": 0.2}, "at": 0.0}),  # a time already past: as soon as possible
]


def test_the_clock_is_picked_by_name_once_and_an_unknown_one_is_refused():
    assert isinstance(world().clock, LockstepClock) and world().clock.name == "lockstep"
    assert isinstance(world(clock="realtime").clock, RealtimeClock) and str(world(clock="realtime").clock) == "realtime"
    with pytest.raises(ValueError, match="'sundial' is no clock; choose lockstep or realtime"):
        pick_clock("sundial", world())


def test_lockstep_every_change_applies_from_the_first_tick_nobody_was_granted():
    w = world()
    for vid in w.ids:
        w.alive(vid, True)
    w.started = True
    w.lockstep.granted = 300
    ticks = {(op, str(f)): ask(w, op, **f).answer.tick for op, f in CHANGES}
    assert set(ticks.values()) == {301}, ticks


def test_realtime_every_change_applies_from_one_tick_the_lead_ahead_of_the_wall_clock():
    """Realtime gains applied from the wall clock's next tick, formation and path 0.5 s ahead,
    link and radio from the next tick's time: a vehicle that had stepped the next tick already
    applied the gains later than the others. Now one rule: EFFECT_LEAD_S ahead, for all."""
    w = world(clock="realtime")
    for vid in w.ids:
        w.alive(vid, True)
    w.started = True
    w.clock.tick_now = lambda: 300
    lead = math.ceil(EFFECT_LEAD_S / w.period)
    assert lead == 25  # 0.5 s at 50 Hz
    answers = {(op, str(f)): ask(w, op, **f).answer for op, f in CHANGES}
    assert all(a.applied for a in answers.values()), answers
    assert {a.tick for a in answers.values()} == {300 + lead}, answers
    links = [a for (op, _), a in answers.items() if op == "link"]
    assert all(a.t == (300 + lead) * w.period for a in links)  # the effect tick's start, as in lockstep


def test_realtime_a_link_change_asked_for_later_keeps_its_time():
    w = world(clock="realtime")
    for vid in w.ids:
        w.alive(vid, True)
    w.started = True
    w.clock.tick_now = lambda: 300
    a = ask(w, "link", link={"loss": 0.1}, at=9.0).answer
    assert a.applied and a.t == 9.0 and a.tick == 450


def test_the_grant_window_is_about_horizon_s_of_the_fleets_speed():
    w = started(world())
    assert w.lockstep.window == GRANT_WINDOW
    w.next_tick = 1000  # 1000 ticks recorded in the last 0.5 s: 2000 ticks/s
    mark = w.clock.widen_horizon(10.5, (10.0, 0))
    assert mark == (10.5, 1000)
    assert w.lockstep.window == int(2000 * HORIZON_S) and w.lockstep.grant_step == w.lockstep.window // 4
    w.clock.widen_horizon(11.0, mark)  # nothing recorded meanwhile (paused, a fault): back to the least
    assert w.lockstep.window == GRANT_WINDOW
    w.next_tick = 10**6
    w.clock.widen_horizon(12.0, (11.0, 1000))
    assert w.lockstep.window == MAX_GRANT_WINDOW
