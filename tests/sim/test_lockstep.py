"""The world's lockstep decisions (cdus.sim.lockstep.Lockstep), without a world process.

A tiny driver plays the vehicles: each live one reports every tick it is granted, and
the launcher acknowledges faults when a test says so. Period 0.1 s, so an event at
t = 1.0 s lands on tick 10 and the 1 s liveliness lease is 10 ticks.
"""

from __future__ import annotations

from cdus.core.events import Event, RosterChange, plan_roster
from cdus.sim.lockstep import Decided, Fault, Grant, Join, Lockstep, Roster
from cdus.wire.schemas import FleetEvent

IDS = ("a", "b", "c")
T = 0.1


def started(events=(), last_tick=100, window=5, ids=IDS) -> Lockstep:
    ls = Lockstep(ids, T, last_tick, events, window=window)
    for j in range(len(ids)):
        ls.on_alive(j, True)
    ls.start()
    return ls


def grants(actions) -> list[int]:
    return [a.until for a in actions if isinstance(a, Grant)]


def rosters(actions) -> list[RosterChange]:
    return [a.change for a in actions if isinstance(a, Roster) and a.to is None]


def faults(actions) -> list[Fault]:
    return [a for a in actions if isinstance(a, Fault)]


def events(actions) -> list[tuple[str, str | None]]:
    return [(a.kind, a.vehicle) for a in actions if isinstance(a, FleetEvent)]


def step(ls: Lockstep, who=None, rounds: int = 200) -> list:
    """Vehicles in ``who`` (default: all) report every tick they are live at up to their
    grant (as an agent does: a paused one skips to where it resumes) until nothing new is
    granted; returns every action polled on the way."""
    who = range(len(ls.ids)) if who is None else who
    out = ls.poll()
    for _ in range(rounds):
        for j in who:
            for n in range(ls.acked.get(j, -1) + 1, ls.granted + 1):
                if ls.state_at(j, n) == "live":
                    ls.on_report(j, n)
        new = ls.poll()
        out += new
        if not new:
            break
    return out


# ---------------------------------------------------------------------- grants


def test_the_start_joins_everyone_at_tick_0_and_grants_one_window():
    ls = started(window=5)
    acts = ls.poll()
    assert [a for a in acts if isinstance(a, Join)] == [Join(0, 0), Join(1, 0), Join(2, 0)]
    assert grants(acts) == [4]  # ticks 0..4: window ticks ahead of "nothing reported yet"
    assert ls.poll() == []  # nothing reported: nothing new


def test_grants_stay_within_the_window_of_the_slowest_vehicle():
    ls = started(window=5)
    ls.poll()
    for n in range(5):
        ls.on_report(0, n)
        ls.on_report(1, n)
    assert ls.poll() == []  # c has reported nothing: the fleet may not run ahead of it
    ls.on_report(2, 1)
    assert grants(ls.poll()) == [6]  # c's newest tick + window
    for n in range(2, 5):
        ls.on_report(2, n)
    assert grants(ls.poll()) == [9]


def test_grants_stop_at_the_last_tick():
    ls = started(window=50, last_tick=20)
    acts = step(ls)
    assert max(grants(acts)) == 20
    assert all(ls.acked[j] == 20 for j in range(3))
    assert ls.recordable(20)


def test_a_paused_fleet_gets_no_grants_until_it_is_resumed():
    ls = started(window=5)
    ls.poll()
    ls.pause()
    for j in range(3):
        for n in range(5):
            ls.on_report(j, n)
    assert grants(ls.poll()) == []
    ls.resume()
    assert grants(ls.poll()) == [9]


def test_a_tick_is_recordable_once_every_live_vehicle_reported_it():
    ls = started()
    ls.poll()
    ls.on_report(0, 3)
    ls.on_report(1, 3)
    assert not ls.recordable(0)
    ls.on_report(2, 2)
    assert ls.recordable(2) and not ls.recordable(3)
    ls.on_report(2, 1)  # an old report does not move a vehicle back
    assert ls.acked[2] == 2


# ---------------------------------------------------------------------- scheduled faults


def test_a_scheduled_kill_is_held_on_its_tick_until_the_launcher_acknowledges():
    ls = started([Event(1.0, "kill", "b")], window=7)
    acts = step(ls)
    assert max(grants(acts)) == 9  # everyone steps up to the tick before the kill
    assert faults(acts) == [Fault("kill", 1)]
    assert ("fault", "b") in events(acts)
    assert RosterChange(10, 1, "gone") not in rosters(acts)  # not yet: tick 10 is not granted
    assert step(ls) == []  # no acknowledgement: held
    ls.on_fault_done(1)
    acts = step(ls, who=[0, 2])
    first = next(i for i, a in enumerate(acts) if isinstance(a, Grant))
    # the roster change goes out before the grant that covers its tick
    assert Roster(RosterChange(10, 1, "gone")) in acts[:first] and acts[first].until >= 10
    assert max(grants(acts)) == 100  # the fleet goes on without b
    assert ls.recordable(100) and ls.acked[1] == 9


def test_a_fault_is_carried_out_once_everyone_has_reported_the_tick_before():
    ls = started([Event(1.0, "kill", "b")], window=20)
    assert grants(ls.poll()) == [9]
    for j in (0, 1):
        for n in range(10):
            ls.on_report(j, n)
    assert faults(ls.poll()) == []  # c has not reported tick 9 yet
    for n in range(10):
        ls.on_report(2, n)
    assert faults(ls.poll()) == [Fault("kill", 1)]


def test_the_kills_liveliness_loss_is_expected_not_news():
    ls = started([Event(1.0, "kill", "b")])
    step(ls)
    ls.on_fault_done(1)
    ls.on_alive(1, False)
    acts = step(ls, who=[0, 2])
    assert ("vehicle_lost", "b") not in events(acts)
    assert sum(ch == RosterChange(10, 1, "gone") for ch in ls.changes) == 1


def test_an_acknowledgement_for_another_vehicle_or_stage_is_ignored():
    ls = started([Event(1.0, "kill", "b")])
    step(ls)
    ls.on_fault_done(0)  # not the fault in progress
    assert step(ls) == []
    ls.on_fault_done(1)
    ls.on_fault_done(1)  # twice: harmless
    assert max(grants(step(ls, who=[0, 2]))) == 100


def test_a_scheduled_restart_waits_for_the_new_process_and_joins_it_on_its_tick():
    ls = started([Event(1.0, "restart", "b")], window=5)
    acts = step(ls)
    assert faults(acts) == [Fault("restart", 1)]
    ls.on_fault_done(1)
    ls.on_alive(1, False)  # the old process goes...
    assert step(ls) == []  # ...and the fleet waits for the new one
    ls.on_alive(1, True)
    acts = step(ls)
    assert ("vehicle_back", "b") in events(acts)
    assert Join(1, 10) in acts
    catch_up = [a.change for a in acts if isinstance(a, Roster) and a.to == 1]
    assert catch_up == ls.changes[:len(catch_up)]  # the joiner hears every change sent so far
    assert max(grants(acts)) == 100 and ls.acked[1] == 100
    # the changes are the scheduled plan's: the same as the in-process fleet's
    assert set(ls.changes) == set(plan_roster([Event(1.0, "restart", "b")], IDS, T))


def test_a_restart_whose_token_came_back_before_the_acknowledgement_joins_at_once():
    ls = started([Event(1.0, "restart", "b")])
    step(ls)
    ls.on_alive(1, False)
    ls.on_alive(1, True)
    assert Join(1, 10) not in ls.poll()  # not acknowledged yet
    ls.on_fault_done(1)
    assert Join(1, 10) in ls.poll()


def test_a_scheduled_pause_then_resume_keeps_the_vehicle_and_sends_the_plan():
    evs = [Event(1.0, "pause", "b"), Event(1.5, "resume", "b")]
    ls = started(evs, window=5)
    acts = step(ls)
    assert faults(acts) == [Fault("pause_vehicle", 1)]
    ls.on_fault_done(1)
    acts = step(ls)
    assert faults(acts) == [Fault("resume_vehicle", 1)]  # held on tick 15
    assert max(grants(acts)) == 14
    assert rosters(acts) == [RosterChange(10, 1, "paused")]
    ls.on_fault_done(1)  # its token never lapsed: resumed at once
    acts = step(ls)
    assert rosters(acts) == [RosterChange(15, 1, "live")]
    assert max(grants(acts)) == 100 and ls.acked[1] == 100


def test_a_paused_vehicle_whose_token_lapses_is_gone_with_the_lease():
    ls = started([Event(1.0, "pause", "b")], window=5)
    step(ls)
    ls.on_fault_done(1)
    ls.on_alive(1, False)  # the frozen process's token lapses: expected, not news
    acts = step(ls, who=[0, 2])
    assert ("vehicle_lost", "b") not in events(acts)
    assert RosterChange(20, 1, "gone") in rosters(acts)  # paused at 10, lease 10 ticks
    assert ls.state_at(1, 19) == "paused" and ls.state_at(1, 20) == "gone"
    assert ls.recordable(100)


def test_a_fault_nobody_carries_out_is_given_up_with_an_event():
    ls = started([Event(1.0, "kill", "b")])
    step(ls)
    ls.give_up(0)  # not the vehicle in question: nothing
    assert ls.poll() == []
    ls.give_up(1)
    acts = step(ls, who=[0, 2])
    assert ("fault_missed", "b") in events(acts)
    assert max(grants(acts)) == 100


# ---------------------------------------------------------------------- unscheduled


def test_a_crash_takes_the_vehicle_out_from_the_first_tick_it_did_not_report():
    ls = started(window=5)
    ls.poll()
    for n in range(4):
        ls.on_report(1, n)
    ls.on_alive(1, False)
    assert ls.poll() == [] and ls.pending == {1}  # not decided at once: the others may follow
    assert ls.decide_drops() == "lost"
    acts = ls.poll()
    assert rosters(acts) == [RosterChange(4, 1, "gone")] and ls.lost == {1}
    assert ("vehicle_lost", "b") in events(acts)
    acts = step(ls, who=[0, 2])
    assert max(grants(acts)) == 100 and ls.recordable(100)
    assert ls.acked[1] == 3


def test_a_crashed_vehicle_that_comes_back_joins_at_the_first_ungranted_tick_as_a_new_process():
    ls = started(window=5)
    ls.poll()
    ls.on_alive(1, False)
    ls.decide_drops()
    step(ls, who=[0, 2], rounds=2)  # the others run on for a bit
    b = ls.granted + 1
    ls.on_alive(1, True)
    acts = ls.poll()
    assert ls.lost == set()
    assert Join(1, b) in acts
    assert RosterChange(b, 1, "gone") in rosters(acts) and RosterChange(b, 1, "live", fresh=True) in rosters(acts)
    assert ("vehicle_back", "b") in events(acts)
    assert ls.acked[1] == b - 1
    # the new process hears every change so far, its own crash included
    assert [a.change for a in acts if isinstance(a, Roster) and a.to == 1] == ls.changes
    assert ls.changes[0] == RosterChange(0, 1, "gone")
    acts = step(ls)
    assert max(grants(acts)) == 100 and ls.acked[1] == 100


def test_a_late_report_from_a_crashed_vehicle_does_not_bring_it_back():
    ls = started(window=5)
    ls.poll()
    ls.on_alive(1, False)
    ls.decide_drops()
    ls.poll()
    ls.on_report(1, 2)  # an in-flight report after the loss
    assert ls.state_at(1, 50) == "gone"
    assert max(grants(step(ls, who=[0, 2]))) == 100


def test_liveliness_before_the_start_is_not_news():
    ls = Lockstep(IDS, T, 100, ())
    ls.on_alive(1, True)
    ls.on_alive(1, False)
    ls.on_alive(1, True)
    assert ls.poll() == [] and ls.changes == []


def test_a_repeated_liveliness_report_is_ignored():
    ls = started()
    ls.poll()
    ls.on_alive(1, True)
    assert ls.poll() == []


# ---------------------------------------------------------------------- a ground station's faults


def test_a_ground_stations_kill_lands_on_the_first_ungranted_tick():
    ls = started(window=5)
    ls.poll()
    ls.vehicle_fault("kill", 2)
    acts = step(ls)
    assert grants(acts) == [] and ls.granted == 4  # nothing further until the kill is done
    assert faults(acts) == [Fault("kill", 2)]
    assert rosters(acts) == [RosterChange(5, 2, "gone")]  # decided here, before tick 5 is granted
    ls.on_fault_done(2)
    ls.on_alive(2, False)
    acts = step(ls, who=[0, 1])
    assert ("vehicle_lost", "c") not in events(acts)
    assert max(grants(acts)) == 100


def test_a_ground_stations_pause_lapses_to_gone_after_the_lease_unless_resumed():
    ls = started(window=5)
    ls.poll()
    ls.vehicle_fault("pause", 1)
    step(ls)
    ls.on_fault_done(1)
    acts = step(ls, who=[0, 2])
    assert RosterChange(5, 1, "paused") in ls.changes
    assert RosterChange(15, 1, "gone") in rosters(acts)


def test_a_second_pause_of_a_paused_vehicle_whose_lease_lapsed_says_it_was_paused():
    """`cdus gs pause-vehicle usv3` twice answered "usv3 is gone at tick 18180": gone reads as
    killed; the answer now says it was paused, and when, and that the lease lapsing made it gone."""
    ls = started(window=5)
    ls.poll()
    ls.vehicle_fault("pause", 1, by="gs1")
    step(ls)
    ls.on_fault_done(1)
    step(ls, who=[0, 2], rounds=3)
    assert RosterChange(15, 1, "gone") in ls.changes  # paused at 5, lease 10 ticks
    tick = ls.vehicle_fault("pause", 1, by="gs1", ref="again")
    acts = step(ls, who=[0, 2], rounds=1)
    [d] = [a for a in acts if isinstance(a, Decided)]
    assert d.reason == (f"b is gone at tick {tick} (paused at tick 5; gone once its liveliness lease lapsed), "
                        "where this pause would land (nothing done)")
    ls.vehicle_fault("kill", 1, by="gs1")  # a killed one is said killed, with no word of the pause
    step(ls, who=[0, 2], rounds=1)
    ls.on_fault_done(1)
    step(ls, who=[0, 2], rounds=1)
    ls.vehicle_fault("pause", 1, by="gs1", ref="third")
    acts = step(ls, who=[0, 2], rounds=1)
    [d] = [a for a in acts if isinstance(a, Decided)]
    assert "is killed at tick" in d.reason and "paused at" not in d.reason


def test_a_ground_stations_pause_and_resume():
    ls = started(window=5)
    ls.poll()
    ls.vehicle_fault("pause", 1)
    step(ls)
    ls.on_fault_done(1)
    step(ls, who=[0, 2], rounds=1)
    at = ls.granted + 1
    assert ls.state_at(1, at) == "paused"
    ls.vehicle_fault("resume", 1, by="gs1")
    acts = step(ls)
    assert faults(acts) == [Fault("resume_vehicle", 1)]
    said = [a.text for a in acts if isinstance(a, FleetEvent) and a.kind == "fault"]
    assert said == [f"resume of b by gs1 (t = {at * T:g} s)"]  # not "scheduled"
    assert RosterChange(at, 1, "live") in rosters(acts)  # decided here, before tick `at` is granted
    assert ls.granted == at - 1
    ls.on_fault_done(1)
    acts = step(ls)
    assert all(c.state != "gone" for c in ls.changes)  # resumed before the lease ran out
    assert max(grants(acts)) == 100 and ls.acked[1] == 100


def test_a_vehicle_resumed_after_its_session_lapsed_hears_again_what_it_missed():
    """SIGSTOPped past the lease, its session was closed: the roster changes and grants sent
    meanwhile never reached it. When its token is back it gets them again (the hang of a
    ground station's pause and resume in lockstep)."""
    ls = started(window=5)
    ls.poll()
    ls.vehicle_fault("pause", 1)
    step(ls)
    ls.on_fault_done(1)
    ls.on_alive(1, False)  # the lease ran out
    step(ls, who=[0, 2], rounds=5)
    assert 15 < ls.granted < 50
    assert any(c.vehicle == 1 and c.state == "gone" for c in ls.changes)
    ls.vehicle_fault("resume", 1)
    step(ls, who=[0, 2], rounds=2)
    ls.on_fault_done(1)  # SIGCONT sent; the token is not back yet
    assert not [a for a in ls.poll() if isinstance(a, Roster) and a.to == 1]
    before = ls.granted
    ls.on_alive(1, True)
    acts = ls.poll()
    caught_up = [a.change for a in acts if isinstance(a, Roster) and a.to == 1]
    assert caught_up == ls.changes[:len(caught_up)] and caught_up[-1].state == "live" and caught_up[-1].vehicle == 1
    assert grants(acts)[0] == before  # the grant it missed, again
    step(ls)
    assert ls.granted == 100 and ls.acked[1] == 100


def test_a_ground_stations_restart_sends_gone_and_fresh_live_on_one_tick():
    ls = started(window=5)
    ls.poll()
    ls.vehicle_fault("restart", 0)
    acts = step(ls)
    assert rosters(acts) == [RosterChange(5, 0, "gone"), RosterChange(5, 0, "live", fresh=True)]
    ls.on_fault_done(0)
    ls.on_alive(0, False)
    ls.on_alive(0, True)
    acts = step(ls)
    assert Join(0, 5) in acts
    assert max(grants(acts)) == 100


def test_a_ground_stations_fault_with_nothing_to_act_on_is_refused_without_holding_the_fleet():
    ls = started(window=5)
    ls.poll()
    ls.vehicle_fault("resume", 1, by="gs1")  # it is live
    ls.vehicle_fault("kill", 2, by="gs1")
    acts = step(ls)
    ls.on_fault_done(2)
    acts += step(ls, who=[0, 1])
    ls.vehicle_fault("kill", 2, by="gs1")  # again
    ls.vehicle_fault("resume", 2, by="gs1")  # a killed vehicle comes back with a restart only
    acts += step(ls, who=[0, 1])
    said = [a.text for a in acts if isinstance(a, FleetEvent) and a.kind == "rejected"]
    assert said == ["resume of b by gs1: it is live (nothing done)", "kill of c by gs1: it is killed (nothing done)",
                    "resume of c by gs1: it is killed (nothing done)"]
    assert faults(acts) == [Fault("kill", 2)]
    assert ls.granted == 100  # nobody waited for a launcher that was never asked


def test_the_answer_to_a_moot_fault_says_the_tick_is_where_it_would_land():
    """`cdus gs kill usv2` twice said "usv2 is killed at tick 13199 (nothing done)" of a vehicle
    killed at tick 9500: the tick is where the second kill would land, not when it was killed."""
    ls = started(window=5)
    ls.poll()
    ls.vehicle_fault("kill", 2, by="gs1")
    step(ls)
    ls.on_fault_done(2)
    step(ls, who=[0, 1])
    tick = ls.vehicle_fault("kill", 2, by="gs1", ref="second")
    acts = step(ls, who=[0, 1])
    [d] = [a for a in acts if isinstance(a, Decided)]
    assert (d.ref, d.tick) == ("second", tick)
    assert d.reason == f"c is killed at tick {tick}, where this kill would land (nothing done)"


# ---------------------------------------------------------------------- the whole fleet at once


def test_every_vehicle_dropping_at_once_is_an_outage_waited_for_without_roster_changes():
    ls = started(window=5)
    step(ls, rounds=2)
    granted = ls.granted
    for j in range(3):
        ls.on_alive(j, False)
    assert ls.decide_drops() == "outage" and ls.outage == {0, 1, 2}
    acts = ls.poll()
    assert rosters(acts) == [] and ("fleet", None) in events(acts) and ls.granted == granted
    assert not ls.recordable(granted + 1)  # nothing is recorded for them meanwhile
    for j in range(3):
        ls.on_alive(j, True)
    acts = ls.poll()
    assert Grant(granted) in acts and ls.outage == set() and ls.lost == set()
    assert not any(isinstance(a, Join) for a in acts)  # the same processes: they go on where they were
    assert max(grants(step(ls))) == 100 and ls.changes == []


def test_an_outage_given_up_loses_every_vehicle_still_away():
    ls = started(window=5)
    step(ls)
    for j in range(3):
        ls.on_alive(j, False)
    ls.decide_drops()
    ls.on_alive(0, True)
    ls.end_outage()
    acts = ls.poll()
    assert ls.lost == {1, 2} and {ch.vehicle for ch in rosters(acts)} == {1, 2}
    assert ("vehicle_lost", "b") in events(acts) and ("vehicle_lost", "c") in events(acts)


def test_a_vehicle_back_before_its_loss_was_decided_is_the_same_process():
    ls = started(window=5)
    step(ls)
    ls.on_alive(1, False)
    ls.on_alive(1, True)
    assert ls.decide_drops() is None
    assert rosters(ls.poll()) == []
    assert ls.pending == set() and ls.changes == [] and ls.lost == set()


def test_a_faults_liveliness_news_belongs_to_the_tick_of_its_roster_change():
    """What the world stamps the news' events with (the graph event): the change's tick, not
    the newest tick recorded (the tick before)."""
    ls = started([Event(1.0, "restart", "b"), Event(2.0, "kill", "a"), Event(3.0, "pause", "c")])
    step(ls)
    ls.on_fault_done(1)
    ls.on_alive(1, False)
    assert ls.news_tick == 10 and ls.granted == 9
    ls.on_alive(1, True)
    assert ls.news_tick == 10
    acts = step(ls)
    assert [(e.kind, e.vehicle, e.t) for e in acts if isinstance(e, FleetEvent) and e.kind == "vehicle_back"] \
        == [("vehicle_back", "b", 1.0)]
    ls.on_fault_done(0)
    ls.on_alive(0, False)
    assert ls.news_tick == 20
    step(ls, who=[1, 2])
    ls.on_fault_done(2)
    ls.on_alive(2, False)  # a paused process's token lapses: gone from the lease's end, tick 40
    assert ls.news_tick == 40
    ls.on_alive(0, False)  # no news: a repeat
    assert ls.news_tick is None
