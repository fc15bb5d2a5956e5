"""world_sim.asking: how the world is asked (its last-telemetry queries, command queries) and how
it answers. No network: fake queries record the replies (tests/world_sim/test_commands.py)."""

from __future__ import annotations

import zenoh

from cdus.wire import keys
from cdus.wire.messages import decode_states, encode_control
from world_sim.limits import MAX_QUEUED_QUERIES

from .test_commands import Query, ask
from .test_world import FLEET, row, send_rows, started, world


def test_a_restarted_agent_asking_where_it_was_hears_its_newest_row_on_its_own_key():
    w = started(world())
    send_rows(w, "usv2", [row(1, 0), row(1, 1)])
    q = Query(keys.world_last(FLEET, "usv2"), None)
    w._on_last_query(q)
    assert [k for k, _ in q.replies] == [keys.world_last(FLEET, "usv2")]
    assert decode_states(q.replies[0][1], len(w.ids)) == [row(1, 1)]


def test_a_wildcard_last_query_answers_one_row_per_vehicle_heard_from_and_an_unknown_one_nothing():
    w = started(world())
    send_rows(w, "usv1", [row(0, 0)])
    send_rows(w, "uav1", [row(3, 0)])
    q = Query(keys.world_last(FLEET, "*"), None)
    w._on_last_query(q)
    assert sorted(k for k, _ in q.replies) == sorted(keys.world_last(FLEET, v) for v in ("usv1", "uav1"))
    q = Query(keys.world_last(FLEET, "nobody"), None)
    w._on_last_query(q)
    assert q.replies == [] and q.errors == []


def test_a_command_query_is_answered_once_on_its_key_and_finalized():
    w = started(world())
    q = ask(w, "pause", name="op")
    r = q.answer  # checks: one reply, on the query's key, and the query dropped after it
    assert (r.status, r.op, r.by) == ("applied", "pause", "gs:op")


def test_a_command_query_past_what_may_wait_is_answered_busy_at_once_and_counted():
    w = started(world())
    # asked on a vehicle's key: past no rate (the ground credentials' only), refused by the main thread
    held = [Query(keys.world_command(FLEET, "usv1"), encode_control("resume")) for _ in range(MAX_QUEUED_QUERIES)]
    for q in held:
        w._on_command_query(q)
    late = Query(keys.world_command(FLEET, keys.GROUND), encode_control("resume"))
    w._on_command_query(late)
    assert late.answer.status == "rejected" and late.answer.reason.startswith("busy")
    assert all(q.replies == [] for q in held)  # waiting for the main thread
    w.feed(keys.wake(FLEET, keys.WORLD))
    assert w.st.rejects["busy"] == 1 and held[0].answer.status == "rejected"


def test_an_asker_gone_before_its_answer_is_logged_not_raised():
    w = started(world())
    lines: list[str] = []
    w.log = lines.append

    class Gone(Query):
        def reply(self, key, payload) -> None:
            raise zenoh.ZError("the querier left")

    q = Gone(keys.world_command(FLEET, keys.GROUND), encode_control("pause"))
    w._on_command_query(q)
    w.feed(keys.wake(FLEET, keys.WORLD))
    assert q.dropped and any("could not answer gs's pause" in ln for ln in lines), lines
