"""The agent's receive path for the proximity sensor, without a Zenoh session."""

import msgpack
import pytest

from cdus.scenario.config import load_scenario
from cdus.wire.messages import ContactsMsg, encode_contacts
from cdus.wire.transport import Transport
from vehicle_agent.agent import Agent

CONTACTS = "cdus/tunit/to/+usv_a1+/contacts"  # cdus.wire.keys.contacts


@pytest.fixture
def agent():
    sc = load_scenario("configs/crossing.toml")
    return Agent(sc, "usv_a1", "tunit", Transport(), clock="lockstep", log=lambda s: None)


@pytest.mark.parametrize("payload, reason", [
    (b"\xc1", "contacts_malformed"),
    (msgpack.packb([2, 0, []]), "contacts_version"),
    (msgpack.packb([1, 0, [[1, 0.5, [1.0, 2]]]]), "contacts_type"),
    (msgpack.packb([1, 0, [[1, 0.5, [1.0, "x"]]]]), "contacts_malformed"),  # no strings at all
    (msgpack.packb([1, 0, [[1, 0.5, [1.0, float("nan")]]]]), "contacts_non_finite"),
    (msgpack.packb([1, 0, [[9, 0.5, [1.0, 2.0]]]]), "contacts_unknown_sender"),
    (msgpack.packb([1, 0, [[1, 0.0, [1.0, 2.0]]]]), "contacts_share"),
    # a boat's filter takes 2 coordinates: a 3-D contact raised in guard() and killed the agent
    # as "diverged" (review of issue 16)
    (msgpack.packb([1, 0, [[1, 0.5, [1.0, 2.0, 3.0]]]]), "contacts_dimension"),
    (msgpack.packb([1, 0, [[0, 0.5, [1.0, 2.0]]]]), "contacts_self"),  # usv_a1 is vehicle 0
    (msgpack.packb([1, 0, [[1, 0.5, [1.0, 2.0]], [1, 0.5, [9.0, 2.0]]]]), "contacts_duplicate"),
    (msgpack.packb([1, 2**62, [[1, 0.5, [1.0, 2.0]]]]), "contacts_range"),  # past the run: never freed
])
def test_a_malformed_contacts_message_is_counted_and_dropped(agent, payload, reason):
    agent.feed(CONTACTS, payload)
    assert agent.rejected == {reason: 1}
    assert agent.stats().rejected == 1
    assert agent.node.contacts_missing(1)  # nothing was taken: tick 1 still waits for tick 0's sample
    agent.feed(CONTACTS, encode_contacts(ContactsMsg(0, ((1, 0.5, (1.0, 2.0)),))))
    assert not agent.node.contacts_missing(1)
    (c,) = agent.node.contacts_at(1)
    assert (c.id, c.share, c.q) == ("usv_b1", 0.5, (1.0, 2.0))
    assert agent.rejected == {reason: 1}


def test_a_contact_of_the_wrong_dimension_does_not_stop_the_vehicle():
    """A forged (or buggy) 3-D contact for a boat is dropped; the boat steps on."""
    sc = load_scenario("configs/crossing_dynamic.toml")
    a = Agent(sc, "usv_a1", "tunit", Transport(), clock="lockstep", log=lambda s: None)
    a.feed(CONTACTS, msgpack.packb([1, 0, [[1, 0.5, [1.0, 2.0, 3.0]]]]))
    assert a.rejected == {"contacts_dimension": 1}
    a.feed(CONTACTS, encode_contacts(ContactsMsg(0, ((1, 0.5, (1.0, 2.0)),))))
    for n in range(3):
        a.node.step(n)
    assert a.node.tick == 3
