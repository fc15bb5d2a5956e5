"""A flood of valid commands or of queries: what the world bounds (docs/ground_station.md, "A
flood"). 18,144 `gains c=2` from ground credentials held a lockstep fleet to 35 simulated s in
240 s: each command cost more than the one before (the settings reply encoded whole at each
change, the whole history sent to a restarted vehicle), every one was an event, and the world
answered every query waiting before its next grant. No network: queries asked through World.ask, a fake clock."""

from __future__ import annotations

from hypothesis import given, settings, strategies as hs

import world_sim.asking as asking
import world_sim.world as ws
from cdus.core.quota import Quota
from cdus.sim.lockstep import CatchUp
from cdus.wire import keys
from cdus.wire.messages import CTL_OPS, decode_control, encode_control
from cdus.wire.schemas import decode_settings

from .test_world import FLEET, started, world
from world_sim.asking import Asked

from .test_commands import ask


class Clock:
    """The quotas' clock, moved by hand."""

    def __init__(self):
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def clocked(w):
    w._quota_clock = clock = Clock()
    for q in (w._command_quota, *w._query_quotas.values(), *w._event_quotas.values()):
        q.at = clock.now
    return w, clock


def unlimited(w) -> None:
    """No rate on commands (another test's)."""
    w._command_quota = Quota(1e9, 10**6)


def gains(w, c: float = 2.0, vehicle: str = "") -> Asked:
    return ask(w, "set_gains", gains={"c": c}, vehicle=vehicle, name="flood")


def test_commands_past_the_ground_credentials_rate_are_refused_busy_saying_so_and_counted():
    w, clock = clocked(started(world()))
    answers = [gains(w).answer for _ in range(ws.COMMANDS_BURST + 30)]
    assert all(a.applied for a in answers[:ws.COMMANDS_BURST])
    refused = answers[ws.COMMANDS_BURST:]
    assert all(a.status == "rejected" and a.reason == ws.RATE_REFUSAL for a in refused)
    assert f"at most {ws.COMMANDS_PER_S:g} commands per second" in ws.RATE_REFUSAL
    assert w.st.rejects["rate"] == 30 and len(w._commands) == 1  # one grant: one gains change listed
    clock.now += 1.0  # a second later: that many more pass
    answers = [gains(w).answer for _ in range(int(ws.COMMANDS_PER_S) + 5)]
    assert [a.applied for a in answers] == [True] * int(ws.COMMANDS_PER_S) + [False] * 5
    # the ground credentials' puts (older clients) share the rate: counted, nothing done
    before = len(w.pub_ctl.puts)
    w.feed(keys.world_cmd(FLEET, keys.GROUND), encode_control("pause"))
    assert not w.lockstep.paused and len(w.pub_ctl.puts) == before and w.st.rejects["rate"] == 36
    # a query on another key (world/**, which the router may let a vehicle ask) does not spend it
    clock.now += 1.0
    for _ in range(ws.COMMANDS_BURST + 5):
        q = w.ask(keys.world_command(FLEET, "usv1"), encode_control("pause"))
        assert "asked as 'gs'" in q.answer.reason
    assert gains(w).answer.applied
    # the launcher's own are not the ground station's: never limited
    w.feed(keys.world_cmd(FLEET, keys.LAUNCHER), encode_control("stop"))
    assert w.stop_requested


def test_a_flood_of_gains_in_one_grant_is_one_change_and_its_events_are_bounded():
    """Each applied gains change was a `gains_changed` event (3.5 MB of them in metrics.json) and
    an entry of the settings (500 KB): now the changes a command makes are logged as refused ones
    are (a burst, then one a second, the next saying how many were not), and a gains change for
    the same vehicles on the same tick replaces the one before in the list."""
    w, clock = clocked(started(world()))
    unlimited(w)  # the rate is the test above's
    for i in range(500):
        assert gains(w, c=2.0 + (i % 3)).answer.applied
    assert len(w._commands) == 1 and decode_control(w._commands[0].payload, CTL_OPS).fields["gains"] == {"c": 3.0}
    assert [key for key, _ in w.session.puts].count(keys.ctl(FLEET, w.ids)) == 500  # each sent: the last applies
    changed = [e for e in w.events if e.kind == "gains_changed"]
    assert len(changed) == ws.CHANGE_EVENTS_BURST
    w.lockstep.granted += 7
    clock.now += 1.0
    assert gains(w, vehicle="usv1").answer.applied and gains(w).answer.applied
    g = w.lockstep.granted
    assert [(c.kept_for, c.tick) for c in w._commands] == [(None, g - 6), ("usv1", g + 1), (None, g + 1)]
    last = [e for e in w.events if e.kind == "gains_changed"][-1]
    assert f"({500 - ws.CHANGE_EVENTS_BURST} changes by command since the last one logged were not" in last.text
    assert len([e for e in w.events if e.kind == "gains_changed"]) == ws.CHANGE_EVENTS_BURST + 1


def test_a_change_encodes_no_settings_reply_a_query_does_once():
    """The settings reply was encoded whole (up to 10,000 changes) at every change, on the main
    thread: a flood of commands was quadratic. Now a query makes it, once per change."""
    made = []
    real = asking.encode_settings
    asking.encode_settings = lambda *a, **k: made.append(1) or real(*a, **k)
    try:
        w, _ = clocked(started(world()))
        unlimited(w)
        for i in range(300):
            w.lockstep.granted += 1  # each on a tick of its own: 300 changes listed
            assert gains(w, c=2.0 + i % 2).answer.applied
        assert made == []
        replies = []
        for _ in range(3):
            q = w.ask(keys.world_settings(FLEET), answer=False)
            replies.append(q.replies[0][1])
        assert len(made) == 1 and replies[0] == replies[1] == replies[2]
        got = decode_settings(replies[0], w.ids)
        assert got["total"] == 300 and [c["seq"] for c in got["changes"]] == list(range(300))
        assert ask(w, "link", link={"loss": 0.1}, at=-1.0).answer.applied  # a change: made again, once
        q = w.ask(keys.world_settings(FLEET), answer=False)
        assert len(made) == 2 and decode_settings(q.replies[0][1], w.ids)["link"] == {"loss": 0.1}
    finally:
        asking.encode_settings = real


def test_a_restarted_vehicle_is_sent_the_gains_in_force_and_those_to_come_not_the_history():
    """A restarted vehicle was sent every command of the run again: after 18,144 gains changes it
    spent 10 s of CPU on them and stepped no tick. It applies every change due before its first
    step at that step, the last last: the last of those is sent, and every one after."""
    w, _ = clocked(started(world()))
    unlimited(w)
    for i in range(400):
        w.lockstep.granted += 1
        assert gains(w, c=2.0 + i % 5).answer.applied
    assert ask(w, "link", link={"loss": 0.1}, at=-1.0).answer.applied
    j = w.index["usv2"]
    w.lockstep.acked[j] = w.lockstep.granted - 11  # its first step: granted - 10; 11 changes come after it
    before = len(w.session.puts)
    w.clock.act([CatchUp(j)])
    sent = [decode_control(p, CTL_OPS) for key, p in w.session.puts[before:] if key == keys.ctl(FLEET, ["usv2"])]
    first = w.lockstep.granted - 10
    assert [c.fields["tick"] for c in sent if c.op == "gains"] == list(range(first, w.lockstep.granted + 2))
    assert [c.op for c in sent][-1] == "link"
    in_force = next(c for c in w._commands if c.tick == first)
    assert sent[0].fields == decode_control(in_force.payload, CTL_OPS).fields


@settings(max_examples=60, deadline=None)
@given(hs.lists(hs.tuples(hs.integers(0, 3), hs.sampled_from(["", "usv2", "usv1"]), hs.floats(1.0, 4.0)),
                min_size=1, max_size=25),
       hs.integers(0, 12))
def test_a_joiner_sent_the_coalesced_list_ends_with_the_gains_of_the_whole_history(steps, first_acked):
    """Whatever the changes (ticks moving or not, for everyone or one vehicle) and wherever the
    joiner starts: replaying what it is sent as an agent does (each change due at its first step
    applied in order, the last last) gives the gains of the whole history at every tick."""
    w, _ = clocked(started(world()))
    unlimited(w)
    base = w.lockstep.granted
    history = []
    for dt, vid, c in steps:
        w.lockstep.granted += dt
        assert gains(w, c=c, vehicle=vid).answer.applied
        if vid in ("", "usv2"):
            history.append((w.lockstep.granted + 1, c))
    j = w.index["usv2"]
    w.lockstep.acked[j] = base + first_acked
    before = len(w.session.puts)
    w.clock.act([CatchUp(j)])
    sent = [decode_control(p, CTL_OPS).fields for key, p in w.session.puts[before:] if key == keys.ctl(FLEET, ["usv2"])]
    got = [(f["tick"], f["gains"]["c"]) for f in sent]

    def in_force(changes, n):  # the agent: every change due by n, in the order heard, the last wins
        due = sorted((t, i, c) for i, (t, c) in enumerate(changes) if t <= n)
        return due[-1][2] if due else None

    start = base + first_acked + 1
    for n in range(start, w.lockstep.granted + 3):
        assert in_force(got, n) == in_force(history, n), (n, got, history)


def test_queries_of_status_settings_and_every_vehicles_last_past_their_rate_are_refused_saying_so():
    """Any member may ask them (a vehicle's credentials too: 14-52 k/s slowed a lockstep run
    1.4-1.6x). Past QUERIES_PER_S on a key: an error reply that says so, counted."""
    w, clock = clocked(started(world()))
    w._publish_status()
    for name, key in (("status", keys.world_status(FLEET)), ("settings", keys.world_settings(FLEET)),
                      ("last", keys.world_last(FLEET, "*"))):
        qs = [w.ask(key, answer=False) for _ in range(ws.QUERIES_BURST + 7)]  # Zenoh's threads only
        assert all(not q.errors for q in qs[:ws.QUERIES_BURST]), name
        assert all(q.errors == [f"busy: at most {ws.QUERIES_PER_S:g} queries per second on {key} (a flood); "
                                f"try again".encode()] and not q.replies for q in qs[ws.QUERIES_BURST:]), name
    w.feed(keys.wake(FLEET, keys.WORLD))
    assert w.st.rejects["query_rate"] == 21
    # a restarting vehicle's own key is never refused (a flood there must not keep it from where it was)
    from tests.world_sim.test_world import row, send_rows  # noqa: PLC0415
    send_rows(w, "usv1", [row(0, 0)])
    for _ in range(ws.QUERIES_BURST + 5):
        q = w.ask(keys.world_last(FLEET, "usv1"), answer=False)
        assert len(q.replies) == 1 and not q.errors
    clock.now += 1.0  # a second later, that many more
    q = w.ask(keys.world_status(FLEET), answer=False)
    assert len(q.replies) == 1


@settings(max_examples=40, deadline=None)
@given(hs.lists(hs.tuples(hs.sampled_from(["status", "settings", "last", "last_one", "command"]),
                          hs.floats(0.0, 0.2)), max_size=200))
def test_any_mix_of_queries_gets_one_answer_each_and_no_key_more_than_its_rate(asks):
    """Whatever the mix and pace: every query is answered once (a reply, or an error that says
    busy), no key answers more than its burst plus its rate over the time gone, what is refused
    is counted, and a vehicle's own world/last/<id> is always answered."""
    w, clock = clocked(started(world()))
    w._publish_status()
    from tests.world_sim.test_world import row, send_rows  # noqa: PLC0415
    send_rows(w, "usv1", [row(0, 0)])
    handlers = {"status": keys.world_status(FLEET), "settings": keys.world_settings(FLEET),
                "last": keys.world_last(FLEET, "*"), "last_one": keys.world_last(FLEET, "usv1")}
    start, answered, refused = clock.now, {k: 0 for k in handlers}, 0
    commands = []
    for kind, gap in asks:
        clock.now += gap
        if kind == "command":
            commands.append(gains(w))
            continue
        q = w.ask(handlers[kind], answer=False)
        assert (len(q.replies) >= 1) != (len(q.errors) == 1), (kind, q.replies, q.errors)
        answered[kind] += bool(q.replies)
        refused += len(q.errors)
    w.feed(keys.wake(FLEET, keys.WORLD))
    elapsed = clock.now - start
    for kind in ("status", "settings", "last"):
        assert answered[kind] <= ws.QUERIES_BURST + ws.QUERIES_PER_S * elapsed + 1e-6
    assert answered["last_one"] == sum(1 for kind, _ in asks if kind == "last_one")
    assert w.st.rejects["query_rate"] == refused
    passed = sum(1 for q in commands if q.answer.reason != ws.RATE_REFUSAL)
    assert all(q.answer is not None for q in commands)
    assert passed <= ws.COMMANDS_BURST + ws.COMMANDS_PER_S * elapsed + 1e-6
    assert w.st.rejects["rate"] == len(commands) - passed
