"""The vehicle agent's shell logic without a network: a fake Zenoh session whose inbox is a
scripted list of samples (the agent's one subscription), publishers that record puts."""

from __future__ import annotations

import time
from collections import deque

import msgpack
import pytest

from cdus.scenario.config import load_scenario
from cdus.sim.build import listeners_of
from cdus.wire import keys
from cdus.wire.messages import (
    OmegaMsg, decode_omega, decode_states, encode_control, encode_omega,
)
from cdus.wire.schemas import decode_stats, encode_stats
from cdus.wire.transport import Transport
from tests.fakes import Payload, Sample
from vehicle_agent import agent as agent_module
from vehicle_agent.agent import Agent
from vehicle_agent import intake as intake_module, lockstep, realtime
from vehicle_agent.waker import Waker

FLEET = "tfake"
ME = "usv1"  # listens to usv2 and uav3 on the lake ring


class Inbox:
    """The agent's subscription: samples in the order a test scripts them; ``then``: samples
    that arrive only once the agent blocks on an empty inbox (e.g. the world's stop)."""

    def __init__(self) -> None:
        self.q: deque[Sample] = deque()
        self.then: deque[Sample] = deque()

    def recv(self) -> Sample:
        if not self.q and self.then:
            self.q.append(self.then.popleft())
        if not self.q:
            raise AssertionError("the agent waited on an empty inbox (it would block for ever)")
        return self.q.popleft()

    def try_recv(self) -> Sample | None:
        return self.q.popleft() if self.q else None


class Pub:
    def __init__(self, key: str):
        self.key = key
        self.puts: list[bytes] = []

    def put(self, payload) -> None:
        self.puts.append(bytes(payload))


class Reply:
    ok = b""


class Token:
    def undeclare(self) -> None:
        pass


class Liveliness:
    callbacks: list = []

    def declare_token(self, key: str) -> Token:
        return Token()

    def declare_subscriber(self, key: str, callback, **kw) -> Token:
        Liveliness.callbacks.append((key, callback))
        return Token()


class Session:
    def __init__(self) -> None:
        self.inbox = Inbox()
        self.pubs: dict[str, Pub] = {}
        self.puts: list[tuple[str, bytes]] = []
        self.closed = False

    def declare_subscriber(self, key, handler=None):
        return self.inbox

    def declare_publisher(self, key, **kw) -> Pub:
        return self.pubs.setdefault(key, Pub(key))

    def liveliness(self) -> Liveliness:
        return Liveliness()

    def zid(self) -> str:
        return "a9e1"

    def put(self, key, payload, **kw) -> None:
        self.puts.append((key, bytes(payload)))

    def declare_queryable(self, key, handler):
        return Token()

    def get(self, key, **kw):
        if str(key).endswith("/ping"):  # every listener answers a link check
            return [Reply()]
        return []  # nobody knows where the vehicle was

    def close(self) -> None:
        self.closed = True


@pytest.fixture
def fake(monkeypatch):
    sessions: list[Session] = []
    agents: list[Agent] = []

    def open_session(transport):
        s = Session()
        sessions.append(s)
        return s

    monkeypatch.setattr(agent_module, "open_session", open_session)

    def make(clock: str = "lockstep", duration: float = 0.1, **over) -> tuple[Agent, Session, list[str]]:
        sc = load_scenario("configs/lake_circle.toml", over)
        lines: list[str] = []
        a = Agent(sc, ME, FLEET, Transport(), clock=clock, duration=duration, log=lines.append)
        a.open()
        agents.append(a)
        return a, sessions[-1], lines

    yield make
    for a in agents:
        a.close()


def ctl(session: Session, op: str, **fields) -> None:
    session.inbox.q.append(Sample(keys.ctl(FLEET, [ME]), Payload(encode_control(op, **fields))))


def stop_when_idle(session: Session) -> None:
    session.inbox.then.append(Sample(keys.ctl(FLEET, [ME]), Payload(encode_control("stop"))))


def omega_from(session: Session, a: Agent, vid: str, seq: int, payload: bytes | None = None) -> None:
    j = a.ids.index(vid)
    msg = OmegaMsg(j, seq, seq * a.period, 1.0 - seq * a.period, -1.0)
    key = keys.omega(FLEET, vid, listeners_of(a.scenario, vid))
    session.inbox.q.append(Sample(key, Payload(encode_omega(msg) if payload is None else payload)))


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
    ctl(s, "join", tick=0)
    ctl(s, "grant", until=2)
    for seq in range(5):
        omega_from(s, a, "usv2", seq)
        omega_from(s, a, "uav3", seq)
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


def test_malformed_omega_is_counted_and_logged_once_per_sender_and_reason(fake):
    a, s, lines = fake()
    for _ in range(3):
        omega_from(s, a, "usv2", 0, payload=b"\xc1garbage")
    omega_from(s, a, "uav3", 0, payload=msgpack.packb([1, 1, 0, 0.0, 1.0, -1.0]))  # usv2's index on uav3's key
    a.drain()
    assert sum(a.rejected.values()) == 4
    assert len([ln for ln in lines if "rejected a message from 'usv2'" in ln]) == 1
    assert len([ln for ln in lines if "rejected a message from 'uav3'" in ln]) == 1
    assert a.node.counters.delivered == 0 and a.node.counters.sent == 0


def test_unexpected_keys_and_bad_commands_are_rejected_not_raised(fake):
    a, s, lines = fake()
    s.inbox.q.append(Sample(f"cdus/{FLEET}/to/+{ME}+/state/usv2", Payload(b"x")))
    ctl(s, "roster", vehicle="nobody", tick=3, state="gone", fresh=False)
    ctl(s, "roster", vehicle="usv2", tick=3, state="asleep", fresh=False)
    ctl(s, "gains", gains={"k": "big"}, tick=3)
    ctl(s, "link", link={"loss": 2.0}, at=1.0)
    s.inbox.q.append(Sample(keys.ctl(FLEET, [ME]), Payload(b"\x93\x01")))  # not a control map
    a.drain()
    assert a.rejected["unexpected_state"] == 1
    assert a.rejected["bad_roster"] == 2
    assert a.rejected["bad_gains_command"] == 1
    assert a.rejected["bad_link_command"] == 1
    assert sum(a.rejected.values()) == 6
    assert any("link command rejected" in ln and "loss" in ln for ln in lines)


def test_a_relayed_link_delay_past_its_bound_is_counted_and_dropped(fake):
    """Issue 27: a link change of delay.base = 1e308 reached every agent and each died in
    cdus.core.schedule.needed_seq (OverflowError). The agent checks what the world relays with the
    same bounds (cdus.wire.bounds): counted by reason, dropped, the link as it was."""
    a, s, lines = fake()
    table = dict(a.control.link_table)
    for bad in ({"delay": {"base": 1e308}}, {"delay": {"jitter": 1e308}}, {"timeout": 1e308}):
        ctl(s, "link", link=bad, at=1.0)
    a.drain()
    assert a.rejected["bad_link_command"] == 3 and a.control.link_table == table
    assert any("link command rejected" in ln and "link.delay.base" in ln for ln in lines)


def test_gains_and_link_commands_apply(fake):
    a, s, lines = fake()
    ctl(s, "gains", gains={"k": 2.0, "c": 3.0}, tick=4)
    ctl(s, "link", link={"loss": 0.5}, at=1.0)
    a.drain()
    assert not a.rejected
    assert a.control.link_table["loss"] == 0.5
    assert any("gains k = (2.0, 2.0), c = 3.0 from tick 4" in ln for ln in lines)


def test_a_link_command_merges_sub_tables_and_switches_the_stale_policy_at_its_tick(fake):
    a, s, lines = fake()
    ctl(s, "link", link={"delay": {"base": 0.2}}, at=1.0)
    ctl(s, "link", link={"delay": {"jitter": 0.001}}, at=1.0)  # delay.base stays
    ctl(s, "link", link={"policy": "extrapolate"}, at=1.0)
    a.drain()
    assert not a.rejected
    assert a.control.link_table["delay"] == {"base": 0.2, "jitter": 0.001}
    assert a.node.link.epochs[-1][1].delay.base == 0.2
    table = a.node.table
    assert table.policy == "hold"  # from tick 50 (t = 1.0 s at 50 Hz) on
    for n in range(51):
        a.node.step(n)
    assert table.policy == "extrapolate"


def test_a_numbered_command_heard_again_is_applied_once(fake):
    """The world replays its run-time commands to a resumed or restarted process, and says the
    catch-up again while the process stays silent: a process that had them heard an older link
    table merged again over a newer one (until the newer one came again), and an older radio
    change refused as out of time order. Numbered (seq), each applies once."""
    a, s, lines = fake()
    ctl(s, "link", link={"loss": 0.1, "delay": {"base": 0.2}}, at=1.0, seq=0)
    ctl(s, "link", link={"loss": 0.3}, at=2.0, seq=1)
    a.drain()
    epochs = list(a.node.link.epochs)
    ctl(s, "link", link={"loss": 0.1, "delay": {"base": 0.2}}, at=1.0, seq=0)  # the replay, in order
    ctl(s, "gains", gains={"c": 3.0}, tick=4, seq=2)
    a.drain()
    assert a.control.link_table["loss"] == 0.3 and list(a.node.link.epochs) == epochs and not a.rejected
    assert a.control.heard_again == 1 and sum("gains" in ln for ln in lines) == 1
    ctl(s, "link", link={"loss": 0.1}, at=1.0, seq=1)  # heard again, whatever it says: once
    ctl(s, "gains", gains={"c": 3.0}, tick=4, seq=2)
    a.drain()
    assert a.control.link_table["loss"] == 0.3 and a.control.heard_again == 3
    ctl(s, "link", link={"loss": 0.2}, at=3.0)  # without a number (an older world): applied as ever
    ctl(s, "link", link={"loss": 0.25}, at=3.0, seq=True)  # not a number: refused, counted
    a.drain()
    assert a.control.link_table["loss"] == 0.2 and a.rejected["seq"] == 1


def test_a_link_command_without_a_policy_keeps_the_one_the_agent_runs(fake):
    a, s, lines = fake()
    a.node.table.policy = "timeout"  # as `--policy timeout` sets it
    ctl(s, "link", link={"loss": 0.1}, at=0.0)
    a.drain()
    a.node.step(0)
    assert a.node.table.policy == "timeout"


def test_clock_messages_set_the_agents_clock(fake):
    a, s, lines = fake(clock="realtime")
    t0 = time.time()
    ctl(s, "start", t0=t0)
    ctl(s, "pause")
    a.drain()
    assert a.clock.t0 == t0 and a.clock.paused
    ctl(s, "resume", t0=t0 + 5.0)
    ctl(s, "stop")
    a.drain()
    assert a.clock.t0 == t0 + 5.0 and not a.clock.paused and a.clock.stop


def test_stats_round_trip_and_send_only_new_latency_samples(fake):
    a, s, lines = fake(duration=0.1)
    ctl(s, "join", tick=0)
    ctl(s, "grant", until=5)
    for seq in range(5):
        omega_from(s, a, "usv2", seq)
        omega_from(s, a, "uav3", seq)
    stop_when_idle(s)
    a.run()
    first = a.stats()
    assert decode_stats(encode_stats(first)) == first
    assert a.stats().latencies_ms == ()  # already reported


def test_the_waker_deadline_is_the_next_tick_or_the_alarm():
    w = Waker(lambda: None, 0.02)
    assert w._deadline(5.0) is None
    w.t0 = 1.0
    assert w._deadline(1.03) == pytest.approx(1.04)
    w.alarm = 1.035
    assert w._deadline(1.03) == 1.035


# ------------------------------------------------------------------ hostile ω and control (issue 15)

def forged(session: Session, a: Agent, vid: str, seq: int, t: float, omega: float, rate: float = -1.0) -> None:
    j = a.ids.index(vid)
    key = keys.omega(FLEET, vid, listeners_of(a.scenario, vid))
    session.inbox.q.append(Sample(key, Payload(encode_omega(OmegaMsg(j, seq, t, omega, rate)))))


def test_hostile_omega_neither_crashes_nor_locks_out_nor_offsets_a_lockstep_run(fake):
    """The attacks of issue 15 between genuine messages: the run steps every tick with the
    genuine values, and each attack is counted under its reason."""
    a, s, lines = fake(duration=0.1)
    ctl(s, "join", tick=0)
    ctl(s, "grant", until=5)
    forged(s, a, "usv2", 0, 1e308, 1.0)  # crashed send_tick before
    forged(s, a, "usv2", 2**32 - 1, (2**32 - 1) * a.period, 1.0)  # locked the sender out before
    for seq in range(5):
        omega_from(s, a, "usv2", seq)
        omega_from(s, a, "uav3", seq)
        if seq < 4:  # the next one, offset by 1 rad: sent before the genuine one
            forged(s, a, "uav3", seq + 1, (seq + 1) * a.period, 2.0 - (seq + 1) * a.period)
        omega_from(s, a, "usv2", seq)  # a replay
    stop_when_idle(s)
    assert a.run() == 6
    assert a.rejected["inconsistent"] == 1 and a.rejected["future"] == 1
    assert a.rejected["implausible"] == 4 and a.rejected["stale"] == 5
    assert a.rejected["conflict"] == 0
    latest = a.node.table.latest
    assert latest[a.ids.index("uav3")].omega == 1.0 - 4 * a.period  # the genuine value is used
    stats = a.stats()
    assert stats.rejected == 11 and stats.rejected_by_reason["implausible"] == 4
    assert len([ln for ln in lines if "implausible" in ln]) == 1  # logged once


def test_a_conflicting_replay_is_counted(fake):
    a, s, lines = fake(duration=0.1)
    ctl(s, "join", tick=0)
    ctl(s, "grant", until=5)
    omega_from(s, a, "usv2", 0)
    forged(s, a, "usv2", 0, 0.0, 1.5)
    a.drain()
    assert a.rejected["conflict"] == 1 and a.stats().rejected == 1


@pytest.mark.parametrize("op, fields, reason", [
    ("grant", {"until": 6}, "grant_range"),  # past the run's last tick (5)
    ("grant", {"until": -3}, "grant_range"),
    ("join", {"tick": 99}, "join_range"),
    ("start", {"t0": 1e12}, "t0_range"),
    ("resume", {"t0": 0.0}, "t0_range"),
    ("roster", {"vehicle": "usv2", "tick": 10**9, "state": "gone", "fresh": False}, "bad_roster"),
    ("gains", {"gains": {"k": 2.0}, "tick": -1}, "gains_range"),
    ("link", {"link": {"loss": 0.1}, "at": -1.0}, "link_range"),
    ("link", {"link": {"delay": {"base": {"x": {"y": 1}}}}, "at": 0.0}, "link_range"),
])
def test_control_fields_out_of_range_are_counted_and_dropped(fake, op, fields, reason):
    a, s, lines = fake(duration=0.1)
    before = (a.clock.granted, a.clock.join, a.clock.t0, dict(a.control.link_table))
    ctl(s, op, **fields)
    a.drain()
    assert a.rejected == {reason: 1}
    assert (a.clock.granted, a.clock.join, a.clock.t0, dict(a.control.link_table)) == before
    assert not a.node._gains


def test_a_realtime_flood_on_one_key_is_cut_at_the_senders_rate_before_decoding(fake, monkeypatch):
    a, s, lines = fake(clock="realtime", duration=0.1)
    decoded = []
    real = intake_module.decode_omega
    monkeypatch.setattr(intake_module, "decode_omega", lambda *x, **kw: decoded.append(1) or real(*x, **kw))
    for _ in range(10 * realtime.RATE_BURST):
        omega_from(s, a, "usv2", 0)
    a.drain(lambda: 0.0)
    assert len(decoded) <= realtime.RATE_BURST + 5  # a few tokens refill while it drains
    assert a.rejected["rate"] >= 9 * realtime.RATE_BURST - 5
    assert sum(a.rejected.values()) == 10 * realtime.RATE_BURST - 1  # all but the first


# ------------------------------------------------------------------ properties (issue 15)

from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402

_FIXTURE = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
_CTL = [encode_control("grant", until=3), encode_control("join", tick=0), encode_control("start", t0=time.time()),
        encode_control("roster", vehicle="usv2", tick=3, state="gone", fresh=False),
        encode_control("link", link={"loss": 0.1}, at=0.0), encode_control("gains", gains={"c": 2.0}, tick=2)]


def _payload(data, valid: list[bytes]) -> bytes:
    p = bytearray(data.draw(st.sampled_from(valid)))
    if data.draw(st.booleans()):
        return data.draw(st.binary(max_size=64))
    for _ in range(data.draw(st.integers(0, 3))):
        if p:
            p[data.draw(st.integers(0, len(p) - 1))] = data.draw(st.integers(0, 255))
    return bytes(p)


@_FIXTURE
@given(data=st.data(), clock=st.sampled_from(["lockstep", "realtime"]))
def test_the_agents_handler_never_raises_and_counts_every_omega_it_does_not_take(fake, data, clock):
    a, s, lines = fake(clock=clock, duration=0.1)
    keyset = {vid: keys.omega(FLEET, vid, listeners_of(a.scenario, vid)) for vid in ("usv2", "uav3")}
    omegas = [encode_omega(OmegaMsg(j, q, q * a.period, 1.0 - q * a.period, -1.0)) for j in (1, 2) for q in range(4)]
    taken = rejected = 0
    for _ in range(data.draw(st.integers(1, 30))):
        kind = data.draw(st.sampled_from(["omega", "ctl", "contacts", "other"]))
        if kind == "omega":
            vid = data.draw(st.sampled_from(sorted(keyset)))
            before_seq, before_rej = dict(a.node.seen_seq), sum(a.rejected.values())
            before_in = len(a.node._inbox) + a.node._order  # a gap filled is taken without a newer seq
            a.feed(keyset[vid], _payload(data, omegas), 0.0 if clock == "realtime" else None)
            if a.node.seen_seq != before_seq or len(a.node._inbox) + a.node._order != before_in:
                taken += 1
            else:
                assert sum(a.rejected.values()) == before_rej + 1
                rejected += 1
        elif kind == "ctl":
            a.feed(keys.ctl(FLEET, [ME]), _payload(data, _CTL), None)
        elif kind == "contacts":
            a.feed(f"cdus/{FLEET}/to/+{ME}+/contacts", data.draw(st.binary(max_size=64)), None)
        else:
            key = data.draw(st.sampled_from([f"cdus/{FLEET}/to/+{ME}+/", f"cdus/{FLEET}/x", "a/b/to/c/\x1b[31m/z"]))
            a.feed(key + data.draw(st.text(max_size=10)), b"", None)
    stats = a.stats()
    assert decode_stats(encode_stats(stats)) == stats
    assert all("\x1b" not in ln for ln in lines)


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


def test_a_restarted_agent_takes_omega_from_a_run_under_way_before_it_knows_where_the_run_is(fake):
    a, s, lines = fake(duration=10.0)
    a.rejoin = True
    omega_from(s, a, "usv2", 300)  # far past any window of a process that has not joined yet
    a.drain()
    assert not a.rejected and a.node.seen_seq[a.ids.index("usv2")] == 300
    b, s, lines = fake(duration=100.0)  # a first start: a tick beyond what anyone can have been granted
    omega_from(s, b, "usv2", lockstep.LOCKSTEP_SEQ_MARGIN + 1)
    b.drain(lambda: None)
    assert b.rejected == {"future": 1}


def test_genuine_omega_does_not_spend_its_senders_rate_budget(fake):
    a, s, lines = fake(clock="realtime", duration=10.0)
    a.clock.t0 = time.time() - 5.0  # the run is at tick ~250
    for seq in range(3 * realtime.RATE_BURST):  # more genuine messages than the bucket holds
        omega_from(s, a, "usv2", seq)
    a.drain(lambda: 5.0)
    assert not a.rejected


def test_gains_past_the_bound_for_the_rate_are_refused_by_the_agent_too(fake):
    a, s, lines = fake()
    ctl(s, "gains", gains={"k": 1e300}, tick=3)
    a.drain()
    assert a.rejected["bad_gains_command"] == 1 and not a.node._gains
    assert any("too large" in ln for ln in lines)


def test_after_an_outage_an_agent_says_again_every_omega_its_lookahead_can_have_run_ahead(fake):
    """With a least link delay of 0.5 s (25 ticks) a sender steps 25 ticks past its neighbours'
    newest ω, so more than 16 of its messages can be lost in flight when the router goes: it
    says again (far) more than that."""
    a, s, lines = fake(duration=2.0, **{"link.delay.base": 0.5})
    a.clock.begun, a.clock.granted = True, a.last_tick
    for n in range(40):
        a.step(n)
    sent = list(a.report.pub_omega.puts)
    a.report.pub_omega.puts.clear()
    a.report.resend()
    assert a.report.pub_omega.puts == sent  # all 40, in order


def test_after_an_outage_an_agent_says_again_the_telemetry_a_grant_window_can_hold(fake):
    """A vehicle runs up to a grant window (hundreds of ticks) past the world's newest row of the
    slowest vehicle: rows lost in flight then are said again, in messages the world takes."""
    a, s, lines = fake(duration=10.0)
    a.clock.begun, a.clock.granted = True, a.last_tick
    for n in range(300):
        a.step(n)
    a.report.flush()
    a.report.pub_state.puts.clear()
    a.report.resend()
    rows = [r for p in a.report.pub_state.puts for r in decode_states(p, len(a.ids))]
    assert [r.tick for r in rows] == list(range(300))


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
