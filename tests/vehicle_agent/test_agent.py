"""vehicle_agent.agent: the public door (Agent.feed takes a message as the inbox delivers it), and
the clock picked once where the agent is built."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from cdus.scenario.config import load_scenario
from cdus.sim.build import listeners_of
from cdus.wire import keys
from cdus.wire.messages import ContactsMsg, OmegaMsg, encode_contacts, encode_control, encode_omega
from cdus.wire.transport import Transport
from tests.fakes import Payload, Sample
from tests.vehicle_agent.fake_session import FLEET, ME
from vehicle_agent.agent import Agent

ROOT = Path(__file__).resolve().parents[2]


def test_feed_takes_each_message_as_the_inbox_delivers_it(fake):
    a, s, _ = fake()
    b, _, _ = fake()
    j = a.ids.index("usv2")
    omega_key = keys.omega(FLEET, "usv2", listeners_of(a.scenario, "usv2"))
    messages = [
        (keys.ctl(FLEET, [ME]), encode_control("join", tick=0)),
        (keys.ctl(FLEET, [ME]), encode_control("grant", until=4)),
        (keys.ctl(FLEET, [ME]), encode_control("grant", until=99)),  # past the run: grant_range
        (omega_key, encode_omega(OmegaMsg(j, 0, 0.0, 1.0, -1.0))),
        (omega_key, b"\xc1"),  # malformed
        (keys.contacts(FLEET, ME), encode_contacts(ContactsMsg(0, ()))),
        (keys.wake(FLEET, ME), b""),
        (keys.state(FLEET, "usv2"), b"x"),  # unexpected_state
    ]
    for key, payload in messages:
        s.inbox.q.append(Sample(key, Payload(payload)))
        b.feed(key, payload)
    a.drain()
    assert a.rejected == b.rejected == {"grant_range": 1, "malformed": 1, "unexpected_state": 1}
    assert a.clock == b.clock and a.clock.granted == 4
    assert a.node.seen_seq == b.node.seen_seq and a.node.seen_seq[j] == 0
    assert not a.node.contacts_missing(1) and not b.node.contacts_missing(1)


def test_a_key_that_only_ends_like_a_control_key_is_not_taken_for_one(fake):
    """The agent told its keys apart with endswith("/ctl"): ``.../to/+me+/x/ctl`` (anyone's, on an
    open fleet) stopped the run. Now cdus.wire.keys.leaf_kind reads the key's shape."""
    a, _, _ = fake()
    for key in (f"cdus/{FLEET}/to/+{ME}+/x/ctl", f"cdus/{FLEET}/to/+{ME}+/ctl/x"):
        a.feed(key, encode_control("stop"))
    assert not a.clock.stop
    assert a.rejected == {"unexpected_key": 1, "unexpected_ctl": 1}
    a.feed(keys.ctl(FLEET, [ME]), encode_control("stop"))
    assert a.clock.stop


def test_an_unknown_clock_is_refused_where_the_agent_is_built():
    sc = load_scenario(ROOT / "configs/lake_circle.toml")
    with pytest.raises(ValueError, match="clock must be one of"):
        Agent(sc, ME, FLEET, Transport(), clock="wall", log=lambda s: None)


def test_no_room_of_the_agent_compares_the_clocks_name():
    """The clock is a strategy picked once (vehicle_agent.clocks.pick), never a name compared."""
    found = [f"{p.name}:{n}" for p in (ROOT / "vehicle_agent").glob("*.py")
             for n, line in enumerate(p.read_text().splitlines(), 1) if re.search(r"clock\w* (==|!=)", line)]
    assert found == []
