"""vehicle_agent.control: a control message's outcome is a value (applied, heard again, or refused
with its reason), and the count of refusals is made from that value."""

from __future__ import annotations

import time

import msgpack
import pytest
from hypothesis import given, settings, strategies as st

from cdus.scenario.config import load_scenario
from cdus.wire.messages import encode_control
from cdus.wire.transport import Transport
from vehicle_agent.agent import Agent
from vehicle_agent.control import APPLIED, HEARD_AGAIN, Outcome
from tests.vehicle_agent.fake_session import ctl

SC = load_scenario("configs/lake_circle.toml")


def make() -> Agent:
    return Agent(SC, "usv1", "tunit", Transport(), clock="lockstep", duration=0.1, log=lambda s: None)


def test_each_control_message_returns_its_outcome():
    a = make()
    take = a.control.take
    assert take(encode_control("grant", until=3)) == APPLIED and a.clock.granted == 3
    assert take(encode_control("grant", until=99)) == Outcome("grant_range")
    assert take(b"\xc1").reason == "malformed"
    out = take(encode_control("gains", gains={"k": -1.0}, tick=2))
    assert out.reason == "bad_gains_command" and out.detail.startswith("gains command rejected: ")
    assert not out.applied and not a.node._gains
    assert take(encode_control("gains", gains={"c": 2.0}, tick=2, seq=4)) == APPLIED
    assert take(encode_control("gains", gains={"c": 9.0}, tick=2, seq=4)) == HEARD_AGAIN
    assert a.control.heard_again == 1 and len(a.node._gains) == 1
    assert not HEARD_AGAIN.applied and HEARD_AGAIN.reason is None
    assert a.rejected == {}  # take() counts nothing: the intake counts from the value


def test_a_refused_numbered_command_keeps_its_number_free():
    a = make()
    assert a.control.take(encode_control("link", link={"loss": 2.0}, at=0.0, seq=7)).reason == "bad_link_command"
    assert a.control.take(encode_control("link", link={"loss": 0.5}, at=0.0, seq=7)) == APPLIED
    assert a.control.link_table["loss"] == 0.5


anything = st.recursive(st.none() | st.booleans() | st.floats() | st.integers(-2**63, 2**64 - 1) | st.text(max_size=4),
                        lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=6), c, max_size=3),
                        max_leaves=10)
OPS = ["grant", "join", "start", "pause", "resume", "stop", "roster", "link", "gains", "formation", "path", "radio", "x"]
FIELDS = ["until", "tick", "t0", "vehicle", "state", "fresh", "link", "at", "gains", "phases", "path", "radio", "seq"]


@settings(max_examples=200, deadline=None)
@given(op=st.sampled_from(OPS), fields=st.dictionaries(st.sampled_from(FIELDS), anything, max_size=5))
def test_a_hostile_control_message_is_applied_or_refused_and_counted_once_from_its_outcome(op, fields):
    try:
        payload = msgpack.packb({"v": 1, "op": op, **fields})
    except (OverflowError, TypeError, ValueError):
        return
    out = make().control.take(payload)
    assert out.applied == (out.reason is None and not out.again)
    b = make()
    b.feed("cdus/tunit/to/+usv1+/ctl", payload)  # as the agent takes it: counted from its outcome alone
    assert b.rejected == ({} if out.reason is None else {out.reason: 1})


# ------------------------------------------------------------------ through the agent's inbox

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


def test_gains_past_the_bound_for_the_rate_are_refused_by_the_agent_too(fake):
    a, s, lines = fake()
    ctl(s, "gains", gains={"k": 1e300}, tick=3)
    a.drain()
    assert a.rejected["bad_gains_command"] == 1 and not a.node._gains
    assert any("too large" in ln for ln in lines)
