"""vehicle_agent.control: a control message's outcome is a value (applied, heard again, or refused
with its reason), and the count of refusals is made from that value."""

from __future__ import annotations

import msgpack
from hypothesis import given, settings, strategies as st

from cdus.scenario.config import load_scenario
from cdus.wire.messages import encode_control
from cdus.wire.transport import Transport
from vehicle_agent.agent import Agent
from vehicle_agent.control import APPLIED, HEARD_AGAIN, Outcome

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
