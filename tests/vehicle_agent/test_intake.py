"""vehicle_agent.intake: what arrives is taken or counted by reason (logged once per sender and
reason), never raised."""

from __future__ import annotations

import time

import msgpack
from hypothesis import HealthCheck, given, settings, strategies as st

from cdus.sim.build import listeners_of
from cdus.wire import keys
from cdus.wire.messages import OmegaMsg, encode_control, encode_omega
from cdus.wire.schemas import decode_stats, encode_stats
from tests.fakes import Payload, Sample
from tests.vehicle_agent.fake_session import FLEET, ME, ctl, forged, omega_from, stop_when_idle
from vehicle_agent import lockstep, realtime


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
