"""world_sim.asking: how the world is asked (its last-telemetry queries, command queries) and how
it answers. No network: the world's public door World.ask records the replies."""

from __future__ import annotations

import zenoh
from hypothesis import given, settings, strategies as hs

from cdus.wire import keys
from cdus.wire.messages import decode_states, encode_control
from world_sim.limits import MAX_QUEUED_QUERIES

from world_sim.asking import Asked

from .test_commands import ask
from .test_world import FLEET, row, send_rows, started, world


def test_a_restarted_agent_asking_where_it_was_hears_its_newest_row_on_its_own_key():
    w = started(world())
    send_rows(w, "usv2", [row(1, 0), row(1, 1)])
    q = w.ask(keys.world_last(FLEET, "usv2"))
    assert [k for k, _ in q.replies] == [keys.world_last(FLEET, "usv2")]
    assert decode_states(q.replies[0][1], len(w.ids)) == [row(1, 1)]


def test_a_wildcard_last_query_answers_one_row_per_vehicle_heard_from_and_an_unknown_one_nothing():
    w = started(world())
    send_rows(w, "usv1", [row(0, 0)])
    send_rows(w, "uav1", [row(3, 0)])
    q = w.ask(keys.world_last(FLEET, "*"))
    assert sorted(k for k, _ in q.replies) == sorted(keys.world_last(FLEET, v) for v in ("usv1", "uav1"))
    q = w.ask(keys.world_last(FLEET, "nobody"))
    assert q.replies == [] and q.errors == [] and q.done


def test_a_command_query_is_answered_once_on_its_key_and_finalized():
    w = started(world())
    q = ask(w, "pause", name="op")
    r = q.answer  # checks: one reply, on the query's key, and the query dropped after it
    assert (r.status, r.op, r.by) == ("applied", "pause", "gs:op")


def test_a_command_query_past_what_may_wait_is_answered_busy_at_once_and_counted():
    w = started(world())
    # asked on a vehicle's key: past no rate (the ground credentials' only), refused by the main thread
    held = [w.ask(keys.world_command(FLEET, "usv1"), encode_control("resume"), answer=False)
            for _ in range(MAX_QUEUED_QUERIES)]
    late = w.ask(keys.world_command(FLEET, keys.GROUND), encode_control("resume"), answer=False)
    assert late.answer.status == "rejected" and late.answer.reason.startswith("busy")
    assert all(q.replies == [] for q in held)  # waiting for the main thread
    w.feed(keys.wake(FLEET, keys.WORLD))
    assert w.st.rejects["busy"] == 1 and held[0].answer.status == "rejected"


def test_an_asker_gone_before_its_answer_is_logged_not_raised():
    w = started(world())
    lines: list[str] = []
    w.log = lines.append

    class Gone(Asked):
        def reply(self, key, payload) -> None:
            raise zenoh.ZError("the querier left")

    key = keys.world_command(FLEET, keys.GROUND)
    q = w.ask(key, asked=Gone(key, encode_control("pause")))
    assert q.done and any("could not answer gs's pause" in ln for ln in lines), lines


def test_ask_reaches_every_queryable_whose_key_expression_intersects_as_zenoh_routes_a_query():
    """World.ask is the door the tests and the bench ask by: the world's queryables are one table
    (World.queryables, what World.open declares), and a key reaches each that Zenoh would."""
    w = started(world())
    w._publish_status()
    send_rows(w, "usv1", [row(0, 0)])
    assert [on for on, _ in w.queryables()] == [keys.world_last(FLEET, "*"), keys.world_settings(FLEET),
                                                keys.world_status(FLEET), keys.world_command(FLEET, "*")]
    q = w.ask(f"cdus/{FLEET}/world/**", encode_control("pause"))
    assert sorted(k for k, _ in q.replies) == sorted([keys.world_last(FLEET, "usv1"), keys.world_settings(FLEET),
                                                      keys.world_status(FLEET), f"cdus/{FLEET}/world/**"])
    assert q.done and not w.lockstep.paused  # the command's answer: not asked as 'gs', refused
    for key in ("cdus/other/world/status", f"cdus/{FLEET}/world/cmd", "cdus//x", ""):
        q = w.ask(key, encode_control("pause"))
        assert (q.replies, q.errors, q.done) == ([], [], True), key


@settings(max_examples=200, deadline=None)
@given(chunks=hs.lists(hs.sampled_from(["cdus", FLEET, "world", "cmd", "gs", "last", "status", "settings", "usv1",
                                        "*", "**", "", "x"]), max_size=6),
       payload=hs.binary(max_size=24) | hs.none(), answer=hs.booleans())
def test_any_key_asked_is_answered_at_most_once_per_queryable_and_never_raises(chunks, payload, answer):
    w = started(world())
    w._publish_status()
    q = w.ask("/".join(chunks), payload, answer=answer)
    w.feed(keys.wake(FLEET, keys.WORLD))  # the next pass of the main thread
    assert q.done and w.st.rejects["internal"] == 0
    assert len(q.replies) + len(q.errors) <= len(w.ids) + 3
    assert not w._queries
