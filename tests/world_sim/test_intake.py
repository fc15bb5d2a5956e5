"""world_sim.intake: what comes in to the world through its door (World.feed), taken or counted by
reason and dropped, never raised. No network (tests/world_sim/test_world.py's fakes)."""

from __future__ import annotations

from cdus.wire import keys
from cdus.wire.messages import encode_states
from tests.fakes import Payload

from .test_world import FLEET, row, send_rows, started, world


def test_a_row_from_a_sender_not_in_the_fleet_or_on_another_fleets_key_is_dropped_by_reason():
    w = started(world())
    w.feed(keys.state(FLEET, "stranger"), encode_states([row(0, 0)]))
    w.feed(keys.stats(FLEET, "stranger"), b"")
    w.feed(keys.state("otherfleet", "usv1"), encode_states([row(0, 0)]))
    assert dict(w.st.rejects) == {"unknown_sender": 2, "key": 1}
    assert w.st.latest == {} and w.lockstep.acked == {}


def test_a_batch_takes_its_newest_row_as_the_latest_and_acks_it_whatever_its_order():
    w = started(world())
    w.feed(keys.state(FLEET, "usv2"), Payload(encode_states([row(1, 1), row(1, 0)])))  # as Zenoh hands it
    assert w.st.latest[1] == row(1, 1) and w.st.acked[1] == 1 and w.lockstep.acked == {1: 1}
    assert set(w.st.rows) == {0, 1}
    send_rows(w, "usv2", [row(1, 0)])  # an older batch after: the latest stays the newest
    assert w.st.latest[1] == row(1, 1) and w.st.acked[1] == 1


def test_a_bug_of_ours_while_handling_is_counted_as_internal_and_logged_once_not_raised():
    w = started(world())
    lines: list[str] = []
    w.log = lines.append

    def broken(vid, payload):
        raise KeyError("oops")

    w._on_state = broken
    for _ in range(3):
        send_rows(w, "usv1", [row(0, 0)])
    assert w.st.rejects["internal"] == 3
    assert len([ln for ln in lines if "internal" in ln and "KeyError" in ln]) == 1, lines


def test_a_wake_carries_nothing_and_changes_nothing():
    w = started(world())
    before = (dict(w.st.rejects), dict(w.st.latest), sorted(w.st.alive))
    w.feed(keys.wake(FLEET, keys.WORLD), b"\xc1 anything")
    assert (dict(w.st.rejects), dict(w.st.latest), sorted(w.st.alive)) == before


def test_alive_is_the_door_of_liveliness_news():
    w = world()
    w.alive("usv1", True)
    assert "usv1" in w.st.alive
    w.alive("usv1", False)
    assert "usv1" not in w.st.alive
