"""The agent's receive path for the world's radio geometry and radio commands, without a
Zenoh session: every hostile sample is counted by reason and dropped, never crashes the
agent, never changes what it decides (Hypothesis)."""

import math

import msgpack
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cdus.scenario.config import load_scenario
from cdus.wire.messages import GeometryMsg, decode_geometry, encode_control, encode_geometry
from cdus.wire.transport import Transport
from cdus.wire.rejected import Rejected
from vehicle_agent.agent import Agent

SC = load_scenario("configs/range_out.toml")
N = len(SC.ids)
GOOD = GeometryMsg(0, ((50.0, 0.0, 30.0), (52.0, 0.0, 30.0), (57.0, 0.0, 30.0), None))
KEY = "cdus/tunit/to/+uav1+uav2+uav3+uav4+/radio"
CTL = "cdus/tunit/to/+uav1+uav2+uav3+uav4+/ctl"


def make_agent(sc=SC, vid="uav1"):
    return Agent(sc, vid, "tunit", Transport(), clock="lockstep", log=lambda s: None)


@pytest.fixture
def agent():
    return make_agent()


def test_a_geometry_sample_round_trips_and_is_what_tick_1_waits_for(agent):
    assert decode_geometry(encode_geometry(GOOD), N) == GOOD
    node = agent.node
    assert not node.geometry_missing(0)  # tick 0 decides nothing
    assert node.geometry_missing(1)  # tick 1 decides what tick 0 sent: sample 0 is in force then
    agent.feed(KEY, encode_geometry(GOOD), None)
    assert not node.geometry_missing(1)
    every, lag = node.radio.every, node.radio.lag
    assert not node.geometry_missing(every + lag)  # sent at every + lag - 1: still sample 0
    assert node.geometry_missing(every + lag + 1)  # sent at every + lag: sample `every` is in force
    assert agent.loop.samples_missing(agent, every + lag + 1)
    assert agent.rejected == {}


@pytest.mark.parametrize("payload, reason", [
    (b"\xc1", "radio_malformed"),
    (msgpack.packb([2, 0, [None] * N]), "radio_version"),
    (msgpack.packb([1, -1, [None] * N]), "radio_type"),
    (msgpack.packb([1, 0, [[1.0, 2]] + [None] * (N - 1)]), "radio_type"),
    (msgpack.packb([1, 0, [[1.0, float("nan"), 3.0]] + [None] * (N - 1)]), "radio_non_finite"),
    (msgpack.packb([1, 0, [[1.0, 1e300, 3.0]] + [None] * (N - 1)]), "radio_range"),
    (msgpack.packb([1, 0, [None] * (N + 1)]), "radio_count"),
    (msgpack.packb([1, 0, [[1.0, 2.0]] + [None] * (N - 1)]), "radio_dimension"),  # a drone sent as a boat
    (msgpack.packb([1, 0, [[1.0, 2.0, 3.0]] * 5000]), "radio_oversized"),
    (msgpack.packb([1, 0, [None] * 5000]), "radio_malformed"),  # more entries than a fleet can have
    (encode_geometry(GeometryMsg(2**40, (None,) * N)), "radio_range"),  # past the run: kept, never freed
    (encode_geometry(GeometryMsg(1, (None,) * N)), "radio_tick"),  # not a sample tick
], ids=lambda x: x if isinstance(x, str) else None)
def test_a_malformed_geometry_sample_is_counted_and_dropped(agent, payload, reason):
    agent.feed(KEY, payload)
    assert agent.rejected == {reason: 1}
    assert agent.stats().rejected == 1
    assert agent.node.geometry_missing(1)  # nothing was taken
    agent.feed(KEY, encode_geometry(GOOD))
    assert not agent.node.geometry_missing(1)
    agent.feed(KEY, encode_geometry(GOOD))  # said again (the world, to a joining process): the first stands
    agent.feed(KEY, encode_geometry(GeometryMsg(0, ((0.0, 0.0, 1.0),) * N)))  # a different one: someone else's
    assert agent.rejected == {reason: 1, "radio_stale": 1, "radio_conflict": 1}
    assert agent.node.radio.geometry_at(0).positions[0] == (50.0, 0.0, 30.0)


def test_a_geometry_sample_without_radio_is_counted_and_dropped():
    a = make_agent(load_scenario("configs/crossing.toml"), "usv_a1")
    a.feed(KEY, encode_geometry(GeometryMsg(0, (None,) * 4)))
    assert a.rejected == {"radio_unexpected": 1}
    assert a.node.radio is None and not a.node.geometry_missing(5)


floats = st.floats(allow_nan=True, allow_infinity=True) | st.integers(-2**63, 2**64 - 1)
rows = st.none() | st.lists(floats, max_size=4) | st.text(max_size=3) | floats
junk = st.recursive(st.none() | st.booleans() | floats | st.text(max_size=4) | st.binary(max_size=4),
                    lambda c: st.lists(c, max_size=6) | st.dictionaries(st.text(max_size=3), c, max_size=3),
                    max_leaves=30)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(payload=st.one_of(
    st.binary(max_size=200),
    st.builds(lambda v, t, r: msgpack.packb([v, t, r]), st.integers(0, 3), st.integers(-5, 2**64 - 1) | floats,
              st.lists(rows, max_size=6)),
    st.builds(lambda j: msgpack.packb(j), junk)))
def test_hostile_geometry_never_raises_and_every_reject_is_counted(payload):
    a = make_agent()
    before = a.node.radio.newest
    a.feed(KEY, payload)
    msg = decode_geometry(payload, N, [v.dim for v in SC.vehicles])
    taken = a.node.radio.newest != before
    if isinstance(msg, Rejected):
        assert not taken and sum(a.rejected.values()) == 1 and list(a.rejected)[0].startswith("radio_")
    else:
        assert taken == (msg.tick % a.node.radio.every == 0 and msg.tick <= a.last_tick)
        assert sum(a.rejected.values()) == (0 if taken else 1)
        for q in msg.positions:
            assert q is None or all(math.isfinite(x) for x in q)


@pytest.mark.parametrize("change, taken", [
    ({"tx_power": 5.0}, True), ({"station": [10.0, 20.0, 0.0]}, True), ({"tx_power": 1e9}, False),
    ({"station": "x"}, False), ({"power": 3}, False), ({}, False),
])
def test_a_radio_command_applies_from_its_time_or_is_counted(agent, change, taken):
    agent.feed(CTL, encode_control("radio", radio=change, at=2.0))
    epochs = agent.node.radio.channel.epochs
    if taken:
        assert len(epochs) == 2 and epochs[1][0] == 2.0 and agent.rejected == {}
    else:
        assert len(epochs) == 1 and agent.rejected == {"bad_radio_command": 1}


def test_a_radio_command_out_of_range_is_rejected_before_it_applies(agent):
    agent.feed(CTL, encode_control("radio", radio={"tx_power": 5.0}, at=-1.0))
    agent.feed(CTL, encode_control("radio", radio={"a": {"b": {"c": {}}}}, at=1.0))
    assert agent.rejected == {"radio_command_range": 2}  # not the geometry's radio_range: told apart
    assert len(agent.node.radio.channel.epochs) == 1


@settings(max_examples=100, deadline=None)
@given(first=st.lists(st.none() | st.tuples(*[st.floats(-1e6, 1e6)] * 3), min_size=N, max_size=N),
       second=st.lists(st.none() | st.tuples(*[st.floats(-1e6, 1e6)] * 3), min_size=N, max_size=N),
       tick=st.integers(0, 50))
def test_a_second_sample_for_a_tick_never_replaces_the_first_and_is_a_conflict_unless_the_same(first, second, tick):
    """On an open fleet anyone may publish on the radio key (a secured fleet: the world only,
    cdus.wire.access): the first sample of a tick stands, the world's resend of it is
    ``radio_stale``, anything else for that tick ``radio_conflict`` (the world makes it a
    ``suspect`` event)."""
    a = make_agent()
    tick -= tick % a.node.radio.every
    a.feed(KEY, encode_geometry(GeometryMsg(tick, tuple(first))))
    held = a.node.radio.held(tick)
    a.feed(KEY, encode_geometry(GeometryMsg(tick, tuple(second))))
    assert a.node.radio.held(tick) is held
    same = [None if q is None else tuple(q) for q in first] == [None if q is None else tuple(q) for q in second]
    assert a.rejected == {"radio_stale" if same else "radio_conflict": 1}


def test_a_refused_numbered_radio_command_does_not_use_up_its_number(agent):
    """The world numbers its run-time commands (seq) and a process applies each number once. A
    radio command the process refuses (counted bad_radio_command: a value out of range, a change
    before one in force) had its number taken all the same, so the world's own command with that
    number (on an open fleet anyone may publish on ctl first) was then dropped as heard again:
    one refused message locked the world's change out. Only a command applied uses its number."""
    agent.feed(CTL, encode_control("radio", radio={"tx_power": 1e9}, at=2.0, seq=0))  # refused: out of range
    agent.feed(CTL, encode_control("radio", radio={"tx_power": 5.0}, at=3.0, seq=1))
    agent.feed(CTL, encode_control("radio", radio={"tx_power": 6.0}, at=1.0, seq=2))  # refused: before t = 3
    assert agent.rejected == {"bad_radio_command": 2}
    agent.feed(CTL, encode_control("radio", radio={"tx_power": 7.0}, at=4.0, seq=0))  # the world's
    agent.feed(CTL, encode_control("radio", radio={"tx_power": 8.0}, at=5.0, seq=2))
    agent.feed(CTL, encode_control("radio", radio={"tx_power": 9.0}, at=6.0, seq=1))  # heard again: once
    assert [e[:2] for e in agent.node.radio.channel.epochs] == [(-math.inf, 24.0), (3.0, 5.0), (4.0, 7.0),
                                                                (5.0, 8.0)]
    assert agent.control.heard_again == 1 and agent.rejected == {"bad_radio_command": 2}


anything = st.recursive(st.none() | st.booleans() | floats | st.text(max_size=4),
                        lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=8), c, max_size=3),
                        max_leaves=12)
changes = st.dictionaries(st.sampled_from(["tx_power", "station", "power"]),
                          floats | st.lists(floats, max_size=4) | anything, max_size=3) | anything


@settings(max_examples=300, deadline=None)
@given(change=changes, at=floats | anything, seq=st.integers(-2, 2**53) | anything, extra=st.booleans())
def test_a_hostile_radio_command_is_applied_or_counted_and_never_keeps_the_worlds_out(change, at, seq, extra):
    """Any ctl radio message (an open fleet: anyone may publish on ctl): never raises; applied
    (a new epoch) or counted once; and the world's command with the same number that follows is
    applied unless the first one was (then it is the same number heard again)."""
    a = make_agent()
    fields = {"radio": change, "at": at, "seq": seq}
    if extra:
        fields["junk"] = 1
    a.feed(CTL, msgpack.packb({"v": 1, "op": "radio", **fields}))
    applied = len(a.node.radio.channel.epochs) == 2
    assert applied != (sum(a.rejected.values()) == 1), (a.rejected, a.node.radio.channel.epochs)
    if type(seq) is int and 0 <= seq < 2**53:
        a.feed(CTL, encode_control("radio", radio={"tx_power": 3.0}, at=1.0e6, seq=seq))
        assert (a.node.radio.channel.epochs[-1][:2] == (1.0e6, 3.0)) != applied
