"""The world answers every command asked as a query (world/cmd/<from>): applied from a tick, or
rejected with the reason; a lockstep vehicle fault once Lockstep has decided it. No network:
the queries are asked through World.ask, which records the replies."""

from __future__ import annotations

import copy

import msgpack
import pytest
from hypothesis import given, settings, strategies as hs

from cdus.core.linkspec import Delay
from cdus.commands.gains import Gains
from cdus.wire.rejected import Rejected
from cdus.core.schedule import delivery_tick
from cdus.scenario.events import check_path
from cdus.scenario.link import merge_link_tables, validate_link
from cdus.wire import keys
from cdus.wire.messages import CTL_OPS, LAUNCHER_OPS, decode_control, encode_control
from world_sim.asking import Asked
from tests.scenario.test_bounds_walk import EXTREMES, numbers

from .test_world import FLEET, ctl_ops, row, send_rows, started, world


def ask(w, op: str, sender: str = keys.GROUND, raw: bytes | None = None, **fields) -> Asked:
    """Command ``op`` asked as ``sender`` through the world's public door, and answered."""
    return w.ask(keys.world_command(FLEET, sender), encode_control(op, **fields) if raw is None else raw)


def report_through(w, n: int) -> None:
    """Every vehicle reports ticks 0..n."""
    for j, vid in enumerate(w.ids):
        for a in range(0, n + 1, 50):
            send_rows(w, vid, [row(j, k) for k in range(a, min(n, a + 49) + 1)])


def test_fleet_commands_are_applied_from_the_first_tick_not_granted_or_rejected_when_moot():
    w = started(world())
    g = w.lockstep.granted
    r = ask(w, "pause", name="alice").answer
    assert (r.status, r.op, r.tick, r.t, r.by) == ("applied", "pause", g + 1, (g + 1) * w.period, "gs:alice")
    assert w.events[-1].text == "fleet paused by gs:alice"  # the event log names who
    r = ask(w, "pause").answer
    assert (r.status, r.reason, r.tick) == ("rejected", "the fleet is already paused", None)
    assert ask(w, "resume").answer.applied
    assert ask(w, "resume").answer.reason == "the fleet is not paused"
    r = ask(w, "stop").answer
    assert r.applied and r.tick == max(0, w.next_tick - 1) and w.stop_requested
    assert r.t == w.events[-1].t and w.events[-1].text == "fleet stopped by gs"  # the answer's time is the event's
    for op, fields in [("pause", {}), ("stop", {}), ("set_gains", {"gains": {"c": 2.0}, "vehicle": ""})]:
        r = ask(w, op, **fields).answer
        assert (r.status, r.reason) == ("rejected", "the run is stopping"), op


def test_gains_and_link_are_answered_with_their_tick_or_why_they_were_refused():
    w = started(world())
    g = w.lockstep.granted
    r = ask(w, "set_gains", gains={"k": [1.0, 2.0, 3.0]}, vehicle="usv1").answer  # a boat has 2 axes
    assert r.status == "rejected" and "k: must be 2 numbers" in r.reason
    r = ask(w, "set_gains", gains={"k": 1e6}, vehicle="").answer  # beyond what the controller takes
    assert r.status == "rejected" and r.reason
    r = ask(w, "set_gains", gains={"c": 1.0}, vehicle="nobody").answer
    assert r.status == "rejected" and "no vehicle 'nobody'" in r.reason
    r = ask(w, "set_gains", gains={"c": 2.0}, vehicle="").answer
    assert (r.status, r.tick) == ("applied", g + 1)
    assert decode_control(w.session.puts[-1][1], CTL_OPS).fields["tick"] == g + 1
    r = ask(w, "link", link={"loss": 7.0}, at=-1.0).answer  # a table the agents would refuse
    assert r.status == "rejected" and "loss" in r.reason
    r = ask(w, "link", link={"loss": 0.1}, at=-1.0).answer
    assert r.applied and (r.tick, r.t, r.reason) == (g + 1, (g + 1) * w.period, "")  # the effect tick, as gains
    # an --at already past is moved, and the answer says so (it said nothing: rev18-user)
    r = ask(w, "link", link={"loss": 0.2}, at=0.0).answer
    assert r.applied and r.t > 0 and r.reason.startswith("t = 0 s asked had passed"), r
    r = ask(w, "link", link={"loss": 0.2}, at=w.duration - 1).answer
    assert r.applied and r.t == w.duration - 1 and r.reason == ""
    # one at or past the end would never apply: refused, not "applied" (rev18-user)
    r = ask(w, "link", link={"loss": 0.3}, at=w.duration).answer
    assert r.status == "rejected" and "not before the end of the run" in r.reason, r
    assert w.st.rejects["gains"] == 3 and w.st.rejects["link"] == 2


def test_a_link_or_radio_change_without_a_time_applies_from_the_effect_tick_as_gains_do():
    """One rule for every run-time change in both clocks (cdus.commands.effect): a link or radio
    change with no --at applies from the tick past the grant, as gains does; before the first
    grant, from tick 0. The world's own rule made it 0.5 s after the newest tick recorded, in
    lockstep too, and a change before tick 0 applied from t = 0.5 s."""
    from .test_radio_rerun import _radio_world

    for w in (world(), _radio_world()):
        radio = w.radio is not None
        change = ("radio", {"radio": {"tx_power": 3.0}}) if radio else ("link", {"link": {"loss": 0.1}})
        assert w.lockstep.granted == -1  # not started: nobody was granted a tick
        r = ask(w, change[0], **change[1], at=-1.0).answer
        assert r.applied and (r.tick, r.t, r.reason) == (0, 0.0, ""), (change, r)
        w = started(w)
        w.lockstep.granted, w.next_tick = 40, 30
        r = ask(w, change[0], **change[1], at=-1.0).answer
        assert r.applied and (r.tick, r.t, r.reason) == (41, 41 * w.period, ""), (change, r)
        assert r.tick == ask(w, "set_gains", gains={"c": 2.0}, vehicle="").answer.tick


def test_a_lockstep_vehicle_fault_is_answered_when_it_lands_on_its_tick():
    w = started(world())
    g = w.lockstep.granted
    q = ask(w, "kill", vehicle="usv2")
    assert q.replies == [] and not q.done  # held: Lockstep decides it when the fleet reaches its tick
    assert ask(w, "kill", vehicle="nobody").answer.reason.startswith("no vehicle 'nobody' in this fleet")
    report_through(w, g)
    w.clock.act(w.lockstep.poll())
    r = q.answer
    assert (r.status, r.op, r.tick) == ("applied", "kill", g + 1)
    c = decode_control(w.pub_launcher.puts[-1], LAUNCHER_OPS)
    assert (c.op, c.fields["vehicle"]) == ("kill", "usv2")


def test_a_lockstep_vehicle_fault_with_nothing_to_do_is_answered_rejected():
    w = started(world())
    g = w.lockstep.granted
    q = ask(w, "resume_vehicle", vehicle="usv3")  # it is live
    report_through(w, g)
    w.clock.act(w.lockstep.poll())
    r = q.answer
    assert r.status == "rejected" and "usv3 is live" in r.reason and "nothing done" in r.reason


def test_a_fault_still_waiting_at_the_end_is_answered_rejected():
    w = started(world())
    q = ask(w, "restart", vehicle="usv1")
    assert q.replies == []
    w._answer_the_rest("the run is over")
    r = q.answer
    assert r.status == "rejected" and r.reason.startswith("the run is over (before its tick")


def launcher_done(w, vid: str) -> None:
    """The launcher says it carried out a fault on ``vid`` (as cdus.app.launcher puts it)."""
    w.feed(keys.world_cmd(FLEET, keys.LAUNCHER), encode_control("fault_done", vehicle=vid))


def test_realtime_vehicle_faults_are_answered_when_the_launcher_has_carried_them_out():
    """They were answered "applied" when the world asked the launcher: a vehicle the launcher
    does not run (--remote) was said killed and never was."""
    w = world(clock="realtime")
    for vid in w.ids:
        w.alive(vid, True)
    q = ask(w, "pause_vehicle", vehicle="uav1")
    assert q.answer is None and decode_control(w.pub_launcher.puts[-1], LAUNCHER_OPS).op == "pause_vehicle"
    launcher_done(w, "usv1")  # another vehicle's: not this one's answer
    assert q.answer is None
    launcher_done(w, "uav1")
    assert q.answer.applied and q.answer.op == "pause_vehicle" and q.answer.tick == 0


def test_realtime_a_fault_the_launcher_never_confirms_is_answered_not_carried_out():
    import time  # noqa: PLC0415

    from world_sim.world import RT_FAULT_CONFIRM  # noqa: PLC0415

    w = world(clock="realtime")
    for vid in w.ids:
        w.alive(vid, True)
    q1, q2 = ask(w, "kill", vehicle="usv2"), ask(w, "restart", vehicle="uav3")
    w.clock.faults_unconfirmed(time.monotonic())
    assert q1.answer is None and q2.answer is None  # not yet
    launcher_done(w, "uav3")
    w.clock.faults_unconfirmed(time.monotonic() + RT_FAULT_CONFIRM + 0.1)
    assert q2.answer.applied
    r = q1.answer
    assert r.status == "rejected" and "did not say it carried out the kill of usv2" in r.reason and "--remote" in r.reason
    assert any(e.kind == "fault_missed" and e.vehicle == "usv2" for e in w.events)
    launcher_done(w, "usv2")  # a late word changes nothing: the query was answered once
    assert len(q1.replies) == 1


def test_realtime_a_fault_with_nothing_to_do_is_rejected_as_in_lockstep():
    """Tried as a newcomer (rev18-user): in realtime a second kill of a killed vehicle, or a
    second pause of a paused one, was answered "applied" and logged as a fault again."""
    w = world(clock="realtime")
    for vid in w.ids:
        w.alive(vid, True)
    asked = lambda: [(c.op, c.fields["vehicle"]) for c in (decode_control(p, LAUNCHER_OPS)
                                                           for p in w.pub_launcher.puts)]
    steps = [("kill", "usv2", True), ("kill", "usv2", False), ("pause_vehicle", "usv2", False),
             ("resume_vehicle", "usv2", False), ("restart", "usv2", True),
             ("pause_vehicle", "uav1", True), ("pause_vehicle", "uav1", False), ("kill", "uav1", True),
             ("resume_vehicle", "usv3", False), ("restart", "uav1", True), ("pause_vehicle", "uav1", True),
             ("resume_vehicle", "uav1", True), ("resume_vehicle", "uav1", False)]
    for op, vid, applied in steps:
        if op == "restart" or op == "resume_vehicle" and applied:
            w.alive(vid, True)
        q = ask(w, op, vehicle=vid)
        if applied:
            launcher_done(w, vid)
        r = q.answer
        assert r.applied == applied, (op, vid, r)
        if not applied:
            assert r.reason.endswith("(nothing done)") and vid in r.reason, r
        if op in ("kill", "pause_vehicle") and applied:
            w.alive(vid, False)  # the token lapses
    assert asked() == [(op, vid) for op, vid, applied in steps if applied]
    ask(w, "pause_vehicle", vehicle="usv3")
    w.alive("usv3", False)  # its token lapses: the status says paused, not gone
    ask(w, "kill", vehicle="usv1")
    w.alive("usv1", False)
    states = dict(zip(w.ids, w._status_extra().states))
    assert states == {**{vid: "live" for vid in w.ids}, "usv3": "paused", "usv1": "gone"}
    q = ask(w, "kill", vehicle="usv2")
    launcher_done(w, "usv2")
    assert q.answer.applied  # restarted: live again
    assert ask(w, "kill", vehicle="usv2").answer.reason == "usv2 is killed (nothing done)"
    assert [e.kind for e in w.events if e.kind in ("fault", "rejected")].count("rejected") == 7


def test_only_the_launcher_reports_a_fault_done_and_unreadable_commands_are_answered():
    w = started(world())
    r = ask(w, "fault_done", vehicle="usv1").answer
    assert r.status == "rejected" and "only the launcher" in r.reason
    r = ask(w, "", raw=b"\xc1").answer
    assert (r.status, r.op, r.reason) == ("rejected", "?", "the command could not be read: malformed")
    r = ask(w, "", raw=encode_control("pause", name="bad name!")).answer
    assert r.reason == "the command could not be read: name"
    q = w.ask(keys.world_command(FLEET, keys.GROUND))  # a query with no payload
    assert q.answer.status == "rejected"
    assert w.st.rejects["sender"] == 1 and w.st.rejects["malformed"] == 2 and w.st.rejects["name"] == 1


def test_by_query_only_ground_stations_command_not_a_launcher_or_a_vehicle():
    w = started(world())
    for sender in (keys.LAUNCHER, "usv1", "bad name"):
        r = ask(w, "stop", sender=sender).answer
        assert r.status == "rejected" and "asked as 'gs'" in r.reason
    assert not w.stop_requested and w.st.rejects["sender"] == 3


def test_a_flood_of_queries_is_answered_busy_past_what_waits_and_counted():
    from cdus.core.quota import Quota
    from world_sim.world import ANSWERS_PER_PASS, MAX_QUEUED_QUERIES
    w = started(world())
    w._command_quota = Quota(1e9, 10**6)  # the rate is another test's: here, only the queue's bound
    # Zenoh's thread: the main thread is busy elsewhere, it answers none yet
    qs = [w.ask(keys.world_command(FLEET, keys.GROUND), encode_control("set_gains", gains={"c": 2.0}, vehicle=""),
                answer=False) for _ in range(MAX_QUEUED_QUERIES + 5)]
    assert all(q.answer.reason.startswith("busy") for q in qs[MAX_QUEUED_QUERIES:])
    w.feed(keys.wake(FLEET, keys.WORLD))  # one pass answers ANSWERS_PER_PASS, the oldest first; the others wait their turn
    assert [q.answer is not None for q in qs[:MAX_QUEUED_QUERIES]] == [True] * ANSWERS_PER_PASS + [False] * (
        MAX_QUEUED_QUERIES - ANSWERS_PER_PASS)
    while w._queries:
        w.feed(keys.wake(FLEET, keys.WORLD))
    assert all(q.answer.applied for q in qs[:MAX_QUEUED_QUERIES])
    assert w.st.rejects["busy"] == 5


def test_the_put_path_still_carries_commands_out():
    """The launcher's commands and older clients put on to/+world+/cmd/<from>: no answer, same effect."""
    w = started(world())
    w.feed(keys.world_cmd(FLEET, keys.GROUND), encode_control("pause"))
    assert w.lockstep.paused
    w.feed(keys.world_cmd(FLEET, keys.GROUND), encode_control("kill", vehicle="usv2"))
    assert w.lockstep._queue[-1].vehicle == 1 and w.lockstep._queue[-1].ref is None


def test_new_ops_plug_into_the_handlers():
    """A handler is found by the command's type (parsed once, cdus.commands.parse) and is given
    the typed command, its sender and the asking query's ref; it answers with None (applied from
    the next tick), a reason (rejected) or a Verdict."""
    from cdus.commands.fleet import Pause
    from cdus.wire import messages
    w = started(world())
    seen = []
    w.command_handlers[Pause] = lambda c, by, ref: seen.append((c, by, ref is not None)) or None
    assert ask(w, "pause").answer.tick == w.lockstep.granted + 1
    w.command_handlers[Pause] = lambda c, by, ref: "not today"
    assert ask(w, "pause").answer.reason == "not today"
    assert seen == [(Pause(), "gs", True)] and "pause" in messages.COMMAND_OPS


ops = hs.sampled_from(["pause", "resume", "stop", "set_gains", "link", "kill", "pause_vehicle", "resume_vehicle",
                       "restart", "fault_done", "explode", 7, None])
values = hs.recursive(hs.none() | hs.booleans() | hs.integers(-2**63, 2**64 - 1) | hs.floats() | hs.text(max_size=20),
                      lambda c: hs.lists(c, max_size=4) | hs.dictionaries(hs.text(max_size=8), c, max_size=4),
                      max_leaves=12)


@settings(max_examples=300, deadline=None)
@given(op=ops, fields=hs.dictionaries(hs.sampled_from(["gains", "vehicle", "link", "at", "name", "k"]), values,
                                      max_size=4),
       sender=hs.sampled_from(["gs", "launcher", "usv1", "x" * 70, "a b"]), clock=hs.sampled_from(["lockstep",
                                                                                                    "realtime"]),
       junk=hs.binary(max_size=40))
def test_every_query_is_answered_once_never_raises_and_counts_what_it_refuses(op, fields, sender, clock, junk):
    w = world(clock=clock)
    if clock == "lockstep":
        started(w)
    for payload in (msgpack.packb({"v": 1, "op": op, **fields}), junk):
        before = w.st.rejected
        q = w.ask(f"cdus/{FLEET}/world/cmd/{sender}", payload)
        if not q.replies:  # held: a lockstep vehicle fault, decided later
            assert q.key_expr in {qq.key_expr for qq, _, _ in w._waiting.values()}
            continue
        r = q.answer
        if r.status == "rejected" and r.reason.startswith("the command could not be read"):
            assert w.st.rejected == before + 1
    w._answer_the_rest("the run is over")
    assert not w._waiting and not w._queries


def test_lockstep_a_vehicle_paused_by_a_fault_stays_paused_in_the_status_after_its_lease():
    """The lockstep roster says gone once a paused process's token lapses; `gs status` and the
    console showed the vehicle the operator paused as gone / lost, with a "vehicle lost" alarm
    (rev18-user). The status says paused until it is resumed, killed or restarted."""
    w = started(world())
    g = w.lockstep.granted
    q = ask(w, "pause_vehicle", vehicle="usv3")
    report_through(w, g)
    w.clock.act(w.lockstep.poll())
    assert q.answer.applied
    j = w.ids.index("usv3")
    w.feed(keys.world_cmd(FLEET, keys.LAUNCHER), encode_control("fault_done", vehicle="usv3"))
    w.alive("usv3", False)  # the token lapses
    for n in range(g + 50, g + 400, 50):  # the others step on: past the lease the roster makes it gone
        for k, vid in enumerate(w.ids):
            if vid != "usv3":
                send_rows(w, vid, [row(k, m) for m in range(max(0, n - 49), n + 1)])
        w.clock.act(w.lockstep.poll())
    later = w.lockstep.granted
    assert w.lockstep.state_at(j, later) == "gone", (later, g)
    w.next_tick = later + 1
    states = dict(zip(w.ids, w._status_extra().states))
    assert states["usv3"] == "paused" and states["usv1"] == "live", states
    w._note_fault("usv3", "kill")  # a kill of the paused vehicle: gone
    assert dict(zip(w.ids, w._status_extra().states))["usv3"] == "gone"


@settings(max_examples=60, deadline=None)
@given(at=hs.floats(allow_nan=False, allow_infinity=False))
def test_a_link_change_at_any_time_is_relayed_as_the_agents_take_it_or_refused_with_nothing_changed(at):
    """A link change dated beyond what the agents take (they drop at > MAX_LINK_AT as
    link_range) was relayed, logged as a change and kept as the world's table, then answered
    'internal error' (OverflowError at 1e308): every agent dropped it while the world thought it
    in force. Now: relayed with an `at` every agent takes, or refused with nothing changed."""
    from cdus.wire.messages import MAX_LINK_AT

    w = started(world())
    puts, table = len(w.session.puts) + len(w.pub_ctl.puts), dict(w._link_table)
    r = ask(w, "link", link={"loss": 0.1}, at=at).answer
    assert w.st.rejects["internal"] == 0
    relayed = [decode_control(p, CTL_OPS) for p in w.pub_ctl.puts]
    relayed = [c for c in relayed if c.op == "link"]
    if r.applied:
        assert relayed and 0.0 <= relayed[-1].fields["at"] <= MAX_LINK_AT and r.t == relayed[-1].fields["at"]
        assert w.events[-1].kind == "link_changed"
    else:
        assert (at > MAX_LINK_AT and f"at: must be a finite number <= {MAX_LINK_AT:g}" in r.reason
                or at >= w.duration and "not before the end of the run" in r.reason), r  # never applies
        assert w.st.rejects["link"] == 1
        assert not relayed and len(w.session.puts) + len(w.pub_ctl.puts) == puts and w._link_table == table
        assert not [e for e in w.events if e.kind == "link_changed"]


def test_a_flood_of_refused_commands_is_answered_and_counted_but_not_amplified_into_as_many_events():
    """Every refused gains/link/formation/path command was also a 'rejected' event: published
    on world/events, a line of world.log, an entry of metrics.json. 5000 bad queries from a
    ground station made 5000 of each (world.log grew by 1 MB in a second). Now every one is
    answered and counted, the event log takes a burst then one a second, and the next one
    logged says how many it left out."""
    import world_sim.world as ws
    from cdus.core.quota import Quota

    w = started(world())
    w._command_quota = Quota(1e9, 10**6)  # past the ground credentials' rate: another test's
    for _ in range(500):
        r = ask(w, "set_gains", gains={"k": -1.0}, vehicle="").answer
        assert r.status == "rejected" and "k: must be" in r.reason
    assert w.st.rejects["gains"] == 500
    logged = [e for e in w.events if e.kind == "rejected"]
    assert ws.REJECTED_EVENTS_BURST <= len(logged) <= ws.REJECTED_EVENTS_BURST + 2
    w._event_quotas["rejected"].at -= 1.0 / ws.REJECTED_EVENTS_PER_S  # a second later: one more, saying
    # what was left out
    ask(w, "set_gains", gains={"k": -2.0}, vehicle="")
    last = w.events[-1]
    assert last.kind == "rejected" and "got -2 " in last.text and "refused commands since the last one logged" in last.text
    assert len(last.text) <= 300
    assert w.st.rejects["gains"] == 501
    # an applied command is an event as ever
    assert ask(w, "set_gains", gains={"c": 2.0}, vehicle="").answer.applied and w.events[-1].kind == "gains_changed"


def test_realtime_a_scheduled_faults_word_from_the_launcher_does_not_answer_a_ground_stations(tmp_path):
    """The launcher says `fault_done` for each fault it is asked, in order, the scenario's too: the
    scheduled kill of usv2 done answered a ground station's restart of usv2 asked after it
    "applied" before the launcher had restarted anything."""
    from .test_world import EVENTS  # noqa: PLC0415  usv2 killed at 1 s

    w = world(tmp_path, clock="realtime", events=EVENTS)
    for vid in w.ids:
        w.alive(vid, True)
    w.clock.scheduled_faults(1.0)  # the launcher is asked to kill usv2
    q = ask(w, "restart", vehicle="usv2")
    assert [decode_control(p, LAUNCHER_OPS).op for p in w.pub_launcher.puts] == ["kill", "restart"]
    launcher_done(w, "usv2")  # the kill
    assert q.answer is None
    launcher_done(w, "usv2")  # the restart
    assert q.answer is not None and q.answer.applied and q.answer.op == "restart"
    # a scheduled fault the launcher never confirms (a --remote vehicle) goes quietly: its own log says
    import time  # noqa: PLC0415

    from world_sim.world import RT_FAULT_CONFIRM  # noqa: PLC0415
    w.clock.scheduled_faults(10.0)  # uav1 paused at 2 s
    q = ask(w, "kill", vehicle="uav1")
    w.clock.faults_unconfirmed(time.monotonic() + RT_FAULT_CONFIRM + 0.1)
    assert q.answer.status == "rejected" and "kill of uav1" in q.answer.reason
    assert [e.kind for e in w.events].count("fault_missed") == 1 and not any(w.clock.asked.values())


def test_the_settings_query_says_every_change_made_the_phases_and_the_link_table_in_force():
    from cdus.wire.schemas import decode_settings

    w = started(world())
    q = w.ask(keys.world_settings(FLEET))
    first = decode_settings(q.replies[0][1], w.ids)
    assert q.replies[0][0] == keys.world_settings(FLEET) and first["changes"] == [] and first["link"] == {}
    assert ask(w, "set_gains", gains={"k": 2.0}, vehicle="usv1").answer.applied
    assert ask(w, "link", link={"loss": 0.2}, at=-1.0).answer.applied
    assert ask(w, "formation", phases={"usv2": 1.5}, offsets=[]).answer.applied
    assert not ask(w, "set_gains", gains={"k": -1.0}, vehicle="").answer.applied  # refused: not a change
    q = w.ask(keys.world_settings(FLEET))
    got = decode_settings(q.replies[0][1], w.ids)
    assert [(c["seq"], c["op"], c["vehicle"]) for c in got["changes"]] == [(0, "gains", "usv1"), (1, "link", None),
                                                                         (2, "formation", None)]
    assert got["link"] == {"loss": 0.2} and got["phases"]["usv2"] == 1.5
    assert got["phases"]["usv1"] == first["phases"]["usv1"]


def test_a_status_query_is_answered_with_the_newest_status_and_none_before_the_first():
    from cdus.wire.schemas import decode_status

    w = started(world())
    q = w.ask(keys.world_status(FLEET))
    assert q.replies == []  # nothing published yet: the asker waits for the first
    w._publish_status()
    w.next_tick = 5
    w._publish_status()
    q = w.ask(keys.world_status(FLEET))
    assert q.replies == [(keys.world_status(FLEET), w.pub_status.puts[-1])]
    assert decode_status(q.replies[0][1]).t == 4 * w.period


def test_a_fleet_pause_is_in_the_status_a_query_is_answered_at_once():
    """The status query answers the newest status published: a pause is published with it (a
    ground station attaching right after a pause was answered the status before it)."""
    from cdus.wire.schemas import decode_status

    w = started(world())
    w._publish_status()
    assert ask(w, "pause").answer.applied
    q = w.ask(keys.world_status(FLEET))
    assert decode_status(q.replies[0][1]).paused is True
    assert ask(w, "resume").answer.applied
    q = w.ask(keys.world_status(FLEET))
    assert decode_status(q.replies[0][1]).paused is False


def test_a_link_value_past_its_bound_is_refused_by_name_and_never_relayed():
    """Issue 27: `link delay.base=1e308` was answered "applied from tick 1851" and every agent died
    (OverflowError in cdus.core.schedule.needed_seq). Every number of a link table has its bound
    (cdus.wire.bounds): the world checks the merged table with it, names the field, counts it."""
    w = started(world())
    table0, links0 = dict(w._link_table), [c for c in ctl_ops(w) if c.op == "link"]
    for table, field in [({"delay": {"base": 1e308}}, "link.delay.base"), ({"delay": {"jitter": 1e300}}, "link.delay.jitter"),
                         ({"timeout": 1e308}, "link.timeout"), ({"delay": {"base": -0.5}}, "link.delay.base"),
                         ({"override": [{"src": "usv1", "delay": {"base": 3601.0}}]}, "link.override[0].delay.base"),
                         ({"down": [{"from": 2e9, "to": 3e9}]}, "link.down[0].from")]:
        before = w.st.rejects["link"]
        q = ask(w, "link", link=table, at=-1.0)
        assert q.answer.status == "rejected" and field.removeprefix("link.") in q.answer.reason, (table, q.answer)
        assert w.st.rejects["link"] == before + 1
    assert w._link_table == table0 and [c for c in ctl_ops(w) if c.op == "link"] == links0  # nothing relayed
    q = ask(w, "link", link={"delay": {"base": 3600.0}}, at=-1.0)  # the bound itself is a value
    assert q.answer.status == "applied", q.answer


#: each run-time command that carries numbers, with values that apply; the walk below puts each
#: extreme into each of its numbers (radio: lake_circle has no [radio]; its numbers are the
#: scenario's, walked in tests/scenario/test_bounds_walk.py)
NUMERIC_COMMANDS = [
    ("link", {"link": {"delay": {"base": 0.1, "jitter": 0.01}, "timeout": 1.0, "loss": 0.1, "duplicate": 0.1,
                       "burst": {"p": 0.1, "r": 0.5}, "override": [{"src": "usv1", "delay": {"base": 0.1}}],
                       "down": [{"from": 1.0, "to": 2.0}]}, "at": 1.0}),
    ("set_gains", {"gains": {"k": 1.5, "c": 2.0}, "vehicle": ""}),
    ("set_gains", {"gains": {"k": [1.5, 1.5]}, "vehicle": "usv1"}),
    ("formation", {"phases": {"usv2": 2.0, "uav1": 0.5}, "offsets": []}),
    ("path", {"vehicle": "uav1", "path": {"family": "circle", "center": [0.0, 0.0, 20.0], "radius": 5.0, "speed": 1.0}}),
]


WALK = [(op, fields, path) for op, fields in NUMERIC_COMMANDS for path in numbers(fields)]


@pytest.mark.parametrize("op, fields, path", WALK, ids=[f"{op}:{'.'.join(map(str, p))}" for op, _, p in WALK])
def test_every_number_of_a_command_at_its_extremes_is_refused_by_name_or_applied_within_its_bound(op, fields, path):
    """Issue 27: a command the world answered "applied" crashed every agent. Each number of each
    command at 1e308, -1e308, 1e-308, ±inf, nan, -0.0, -1: the world refuses it naming the key
    (a non-finite float field of the command map itself: the decoder's non_finite), or applies a
    value the agents' own checks take and whose delivery tick is a number."""
    key = next(str(k) for k in reversed(path) if isinstance(k, str))
    for value in EXTREMES:
        w = started(world())
        sent = copy.deepcopy(fields)
        node = sent
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = value
        r = ask(w, op, **sent).answer
        if r.status == "rejected":
            assert key in r.reason or (len(path) == 1 and "non_finite" in r.reason), (value, r.reason)
            continue
        assert r.status == "applied", r
        payloads = w.pub_ctl.puts + [p for k, p in w.session.puts if "/ctl" in k]  # to all, to some
        relayed = [c for c in map(lambda p: decode_control(p, CTL_OPS), payloads)
                   if c.op == {"set_gains": "gains"}.get(op, op)][-1]
        if op == "link":
            spec = validate_link(merge_link_tables(w.scenario.link_table, relayed.fields["link"]), w.ids, "agent")
            for d in [spec.delay] + [Delay(**dict(o.delay)) for o in spec.overrides]:
                assert isinstance(delivery_tick(0, d.base + d.jitter, w.period), int)
        elif op == "set_gains":
            relayed_gains = Gains.parse({"gains": relayed.fields["gains"], "vehicle": "usv1"})  # as the agent parses it
            assert not isinstance(relayed_gains.for_vehicle(2, (1.0, 1.0), 1.0, **w.scenario.gain_context("usv1")),
                                  Rejected)
        elif op == "path":
            assert not isinstance(check_path(relayed.fields["path"], 3), tuple)
        else:
            assert all(abs(x) <= 1e9 for x in relayed.fields["phases"].values())
