"""The per-vehicle tick protocol: deliveries, the roster, readiness, run-time changes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from cdus.core.events import RosterChange
from cdus.core.link import IdealLink, LinkEmulator
from cdus.core.linkspec import Delay, LinkSpec
from cdus.core.node import Refused, VehicleNode
from cdus.scenario.config import parse_scenario
from cdus.sim.build import build_node
from cdus.wire.messages import OmegaMsg

T = 0.02
RING = {
    "scenario": {"name": "ring3", "duration": 10.0},
    "vehicle": [
        {"id": f"v{j}", "kind": "usv", "phase": 2.0 * j, "path": {"family": "circle", "center": [0, 0], "radius": 10}}
        for j in range(3)
    ],
}


def node(j: int = 0, link=None, **kw) -> VehicleNode:
    sc = parse_scenario(RING)
    return build_node(sc, f"v{j}", link or IdealLink(), **kw)


def msg(sender: int, tick: int, omega: float | None = None) -> OmegaMsg:
    """What a genuine sender sends at ``tick``: ω falls at the rate it carries, -1 rad/s."""
    return OmegaMsg(sender, tick, tick * T, 1.0 - tick * T if omega is None else omega, -1.0)


def held(n: VehicleNode) -> dict[int, int]:
    """sender -> seq of the value the consensus uses."""
    return {k: m.seq for k, m in n.table.latest.items()}


def test_a_message_is_used_from_the_tick_after_it_was_sent():
    a = node(0)
    a.step(0)
    a.on_message(msg(1, 0))
    a.on_message(msg(2, 0))
    assert held(a) == {}
    a.step(1)
    assert held(a) == {1: 0, 2: 0}
    assert a.counters.sent == 2 and a.counters.delivered == 2


def test_a_message_from_a_neighbour_already_ahead_waits_for_its_turn():
    a = node(0)
    a.step(0)
    a.on_message(msg(1, 0))
    a.on_message(msg(1, 1))  # sent at tick 1: not usable at tick 1
    a.step(1)
    assert held(a) == {1: 0}
    a.step(2)
    assert held(a) == {1: 1}


def test_the_link_delays_in_simulated_time():
    spec = LinkSpec(delay=Delay(base=0.1))
    a = node(0, LinkEmulator(spec, ["v0", "v1", "v2"], seed=1))
    a.step(0)
    a.on_message(msg(1, 0))
    for n in range(1, 5):
        a.step(n)
        assert held(a) == {}
    a.step(5)  # sent at t = 0, delay 0.1 s = 5 ticks
    assert held(a) == {1: 0}
    assert a.counters.latencies == [pytest.approx(0.1)]


def test_a_gone_sender_is_never_readmitted_by_a_late_message():
    """The kill race: the last ω of a killed vehicle arrives after its neighbours were told
    it is gone. It is not used, and nobody waits for that vehicle again."""
    a = node(0)
    for n in range(5):
        a.step(n)
        a.on_message(msg(1, n))
        a.on_message(msg(2, n))
    a.on_roster(RosterChange(5, 1, "gone"))  # v1 killed at tick 5 ...
    a.on_message(msg(1, 4))  # (a duplicate of what arrived: stale)
    a.step(5)
    assert 1 not in held(a)
    a.on_message(msg(2, 5))
    late = OmegaMsg(1, 5, 5 * T, 42.0, -1.0)  # ... its last broadcast, in flight when it died
    assert a.on_message(late) is None  # received, decided ...
    a.step(6)
    assert 1 not in held(a)  # ... and refused: v1 is not back
    assert a.rejected["gone"] >= 1
    assert a.waiting_for(7) == [2]  # waits for v2's tick-6 broadcast, never for v1's
    a.on_message(msg(2, 6))
    assert a.waiting_for(7) == []


def test_in_flight_messages_of_a_gone_sender_are_dropped_at_delivery():
    spec = LinkSpec(delay=Delay(base=0.1))
    a = node(0, LinkEmulator(spec, ["v0", "v1", "v2"], seed=1))
    a.step(0)
    a.on_message(msg(1, 0))  # usable at tick 5
    a.on_roster(RosterChange(3, 1, "gone"))
    for n in range(1, 7):
        a.step(n)
    assert 1 not in held(a)
    assert a.counters.sent == 1 and a.counters.delivered == 0 and a.rejected["gone"] == 1


def test_only_liveliness_back_readmits_and_only_what_was_sent_since():
    a = node(0)
    a.step(0)
    a.on_message(msg(1, 0))
    a.step(1)
    a.on_roster(RosterChange(2, 1, "gone"))
    a.on_roster(RosterChange(4, 1, "live", fresh=True))  # restarted at tick 4
    a.on_message(msg(1, 1))  # the old process's, still in flight
    a.step(2)
    a.step(3)
    assert 1 not in held(a)
    a.on_message(msg(1, 4, omega=7.0))  # the new process's first broadcast
    a.step(4)
    assert 1 not in held(a)  # sent at tick 4: usable at 5
    a.step(5)
    assert held(a) == {1: 4} and a.table.latest[1].omega == 7.0


def test_a_paused_neighbour_is_held_not_awaited_and_dropped_after_the_lease():
    a = node(0)
    a.on_roster(RosterChange(3, 1, "paused"))
    a.on_roster(RosterChange(53, 1, "gone"))
    for n in range(3):
        a.step(n)
        a.on_message(msg(1, n))
        a.on_message(msg(2, n))
    assert a.waiting_for(3) == []  # v1 sent its tick-2 broadcast: arrived
    for n in range(3, 53):
        assert a.waiting_for(n + 1) == [2]  # v1 paused from tick 3: not awaited
        a.step(n)
        a.on_message(msg(2, n))
        assert held(a)[1] == 2  # its last value is held
    a.step(53)
    assert 1 not in held(a)


def test_readiness_waits_only_for_broadcasts_that_exist():
    a = node(0)
    assert a.waiting_for(0) == []  # nothing was sent before tick 0
    assert a.waiting_for(1) == [1, 2]
    a.on_message(msg(2, 0))
    assert a.waiting_for(1) == [1]
    late = node(0, joined_at=100)  # a restarted process hears nothing from before it joined
    assert late.waiting_for(100) == []
    assert late.waiting_for(101) == [1, 2]


def test_own_pause_and_resume_from_the_roster():
    a = node(0)
    a.on_roster(RosterChange(10, 0, "paused"))
    a.on_roster(RosterChange(30, 0, "live"))
    assert a.own_state_at(9) == ("live", False)
    assert a.own_state_at(10) == ("paused", False)
    assert a.resume_tick(10) == 30
    b = node(1)
    b.on_roster(RosterChange(10, 1, "gone"))
    b.on_roster(RosterChange(10, 1, "live", fresh=True))
    assert b.own_state_at(10) == ("live", True)


def test_a_roster_change_told_again_after_its_tick_changes_nothing():
    """The world says a caught-up process's roster again (world_sim CATCHUP_RESEND) while it has
    reported no tick, which it may have stepped past (its rows go in batches): a neighbour's
    restart heard again was applied again, its ω forgotten, and the run left `cdus sim`'s."""
    changes = [RosterChange(2, 1, "gone"), RosterChange(2, 1, "live", fresh=True),
               RosterChange(3, 0, "paused"), RosterChange(4, 0, "live")]

    def run(again: bool) -> list:
        a = node(0)
        for ch in changes:
            a.on_roster(ch)
        out = []
        for n in range(12):
            if again and n in (8, 9):
                for ch in changes:
                    a.on_roster(ch)
            if n % 3 == 0:
                a.on_message(msg(1, n))
                a.on_message(msg(2, n))
            if a.own_state_at(n)[0] == "live":
                out.append((n, a.step(n).telemetry.omega, held(a)))
        return out

    assert run(True) == run(False)
    a = node(0)
    assert [a.on_roster(ch) for ch in changes] == [True] * 4  # news, then not (the agent logs news only)
    assert [a.on_roster(ch) for ch in changes] == [False] * 4


def test_gains_change_on_their_tick():
    a = node(0)
    a.set_gains((3.0, 3.0), 4.0, tick=2)
    a.step(0)
    a.step(1)
    assert a.vehicle.c == 2.0
    a.step(2)
    assert a.vehicle.k == (3.0, 3.0) and a.vehicle.c == 4.0
    assert a.set_gains((1.0,), 1.0, tick=3) == Refused("gains need k > 0 (2 values) and c > 0, got k = (1.0,), c = 1.0")
    assert a.vehicle.k == (3.0, 3.0) and not a._gains  # refused: nothing scheduled


def test_a_flood_of_gains_changes_keeps_one_per_tick_and_applies_the_last_due():
    """A gains change was appended and the whole list sorted, then taken off its front one at a
    time: 18,000 from a flood cost a restarted vehicle 10 s of CPU before its first step. Now a
    change at the latest tick is appended, one at a tick already scheduled replaces it (a step
    applied both, the later last), and a step takes every change due at once."""
    a = node(0)
    for i in range(1000):  # a flood: every change on the tick nobody has been granted yet
        a.set_gains((1.0 + i, 1.0 + i), 2.0, tick=5)
    assert len(a._gains) == 1
    for n in range(1000, 3000):  # a restarted vehicle's replay: every change of the history
        a.set_gains((float(n), float(n)), 3.0, tick=n)
    a.step(0)
    assert a.vehicle.c == 2.0 and len(a._gains) == 2001  # none due yet (the first is at 5)
    a.step(2500)  # a vehicle's first step after a restart: the last change due is the one in force
    assert a.vehicle.k == (2500.0, 2500.0) and a.vehicle.c == 3.0 and len(a._gains) == 499


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 12), st.floats(0.5, 5.0)), max_size=30), st.integers(0, 14))
def test_gains_in_force_are_those_of_applying_every_change_in_arrival_order(changes, steps):
    """Whatever order the ticks come in: at each step, the gains are those of the last change (in
    the order they were given) of the latest tick due, as applying them all in order gave."""
    a = node(0)
    for tick, c in changes:
        a.set_gains((c, c), c, tick=tick)
    for n in range(steps):
        a.step(n)
        due = [c for tick, c in changes if tick <= n]
        if due:
            latest = max(tick for tick, _ in changes if tick <= n)
            want = [c for tick, c in changes if tick == latest][-1]
            assert a.vehicle.c == want and a.vehicle.k == (want, want)
        else:
            assert a.vehicle.c == 2.0


def test_realtime_messages_are_usable_at_arrival_plus_delay():
    spec = LinkSpec(delay=Delay(base=0.05))
    a = node(0, LinkEmulator(spec, ["v0", "v1", "v2"], seed=1))
    a.step(0)
    a.on_message(msg(1, 0), arrival=0.013)
    a.step(3)
    assert held(a) == {}  # usable at 0.063 s
    a.step(4)
    assert held(a) == {1: 0}


def test_not_a_neighbour_and_stale_are_counted():
    sc = parse_scenario({**RING, "graph": {"topology": "chain", "directed": True}})
    a = build_node(sc, "v1", IdealLink())
    assert a.on_message(msg(2, 0)) == "not_a_neighbour"
    assert a.on_message(msg(0, 3)) is None
    assert a.on_message(msg(0, 3)) == "stale"
    assert {r: x for r, x in a.rejected.items() if x} == {"not_a_neighbour": 1, "stale": 1}


# --------------------------------------------------------------------------- proximity contacts


def test_contacts_are_used_from_the_sample_tick_plus_latency_and_awaited_until_then():
    from cdus.core.safety import Contact
    from cdus.scenario.config import load_scenario
    sc = load_scenario("configs/crossing.toml", {"safety.latency": 0.06})  # 3 ticks at 50 Hz, sample every 5
    nd = build_node(sc, "usv_a1", IdealLink())
    assert (nd.sense_every, nd.sense_latency) == (5, 3)
    assert not nd.contacts_missing(2) and nd.contacts_at(2) == ()  # nothing sampled before tick 0 + 3
    assert nd.contacts_missing(3)
    c0, c5 = (Contact((1.0, 8.0), "usv_b1"),), (Contact((1.5, 8.0), "usv_b1"),)
    nd.on_contacts(5, c5)  # a newer sample early: not usable before tick 8, and tick 3 still needs tick 0's
    assert nd.contacts_missing(3) and nd.contacts_at(7) == ()
    nd.on_contacts(0, c0)
    assert not nd.contacts_missing(3) and nd.contacts_at(3) == c0 and nd.contacts_at(7) == c0
    assert nd.contacts_at(8) == c5 and not nd.contacts_missing(12)
    assert nd.contacts_missing(13)  # tick 10's sample
    nd.rejoin(20, None, None, None)  # a resumed vehicle: samples before it rejoined are not used
    assert nd.contacts_at(23) == () and not nd.contacts_missing(22) and nd.contacts_missing(23)


def test_the_filter_runs_in_the_step_and_counts_interventions():
    from cdus.core.safety import Contact
    from cdus.scenario.config import load_scenario
    sc = load_scenario("configs/crossing.toml")
    nd = build_node(sc, "usv_a1", IdealLink())
    q = nd.vehicle.q
    nd.on_contacts(0, (Contact((q[0] + 2.1, q[1] - 0.5), "usv_b1"),))  # just outside R, in its way
    nd.step(0)
    assert nd.vehicle.interventions == 0  # tick 0 has no contacts yet (latency 1)
    nd.step(1)
    assert nd.vehicle.interventions == 1 and nd.vehicle.last_filter.intervened


def test_back_from_a_pause_that_lapsed_it_hears_nothing_sent_while_it_was_gone():
    """Its session was closed: in a fleet of processes what was sent meanwhile is lost or not
    depending on wall time, so every runner drops all of it (lockstep == in-process)."""
    a = node(0)
    for ch in (RosterChange(2, 0, "paused"), RosterChange(5, 0, "gone"), RosterChange(8, 0, "live")):
        a.on_roster(ch)
    a.step(0)
    a.step(1)
    for t in (1, 3, 6):  # before the pause (not decided yet), paused, gone
        a.on_message(msg(1, t))
    a.rejoin(8, None, None, None)
    assert a.on_message(msg(2, 7)) is None  # late, from the gone interval: not heard, not counted
    a.on_message(msg(1, 8))
    a.step(8)
    a.step(9)
    assert held(a) == {1: 8} and a.counters.sent == 1


# ------------------------------------------------------------------ entry validation (issue 15)

def _ticked(a: VehicleNode, n: int) -> None:
    a.horizon = n
    a.step(n)


def test_a_send_time_that_its_seq_does_not_imply_is_inconsistent_and_crashes_nothing():
    a = node(0)
    a.step(0)
    for t in (1e308, -1e308, 5 * T + 1e-6, -T):
        assert a.on_message(OmegaMsg(1, 5, t, 1.0, -1.0)) == "inconsistent"
    assert a.rejected["inconsistent"] == 4 and a.seen_seq == {}
    a.step(1)  # nothing to send_tick's overflow


def test_a_seq_past_the_horizon_is_future_and_does_not_lock_the_sender_out():
    a = node(0)
    _ticked(a, 0)
    assert a.on_message(msg(1, 0)) is None
    assert a.on_message(msg(1, 2**32 - 1)) == "future"  # past the run's last tick
    assert a.on_message(msg(1, 1)) == "future"  # tick 1 is not stepped yet by anyone
    _ticked(a, 1)
    assert a.on_message(msg(1, 1)) is None
    assert a.on_message(msg(1, 5)) == "future"  # beyond what the sender can have reached
    _ticked(a, 2)
    assert a.on_message(msg(1, 2)) is None  # the genuine one is still taken
    assert a.rejected["future"] == 3 and a.seen_seq[1] == 2


def test_a_seq_seen_with_other_content_is_a_conflict_and_a_duplicate_is_stale():
    a = node(0)
    _ticked(a, 0)
    a.on_message(msg(1, 0))
    assert a.on_message(msg(1, 0)) == "stale"
    assert a.on_message(msg(1, 0, omega=2.0)) == "conflict"
    assert a.rejected["stale"] == 1 and a.rejected["conflict"] == 1


def test_an_offset_omega_is_implausible_and_does_not_advance_the_seq():
    a = node(0)
    _ticked(a, 0)
    a.on_message(msg(1, 0))
    _ticked(a, 1)
    forged = msg(1, 1)
    assert a.on_message(OmegaMsg(1, 1, forged.t_send, forged.omega + 1.0, forged.omega_rate)) == "implausible"
    assert a.seen_seq[1] == 0
    assert a.on_message(msg(1, 1)) is None  # the genuine one still gets through
    _ticked(a, 2)
    assert held(a) == {1: 1} and a.table.latest[1].omega == msg(1, 1).omega


def test_a_float32_rate_and_a_gap_of_lost_messages_pass_the_plausibility_check():
    import struct
    from cdus.core.node import omega_plausible
    w0, wd = 1234.5678901234, -0.987654321987
    w1 = w0 + T * wd
    rate32 = struct.unpack(">f", struct.pack(">f", (w1 - w0) / T))[0]
    assert omega_plausible(OmegaMsg(1, 7, 7 * T, w0, -0.9), OmegaMsg(1, 8, 8 * T, w1, rate32), T)
    assert not omega_plausible(OmegaMsg(1, 7, 7 * T, w0, -0.9), OmegaMsg(1, 8, 8 * T, w1 + 1e-6, rate32), T)
    # 3 ticks lost, the rate drifting from -1 to -0.8: within the end rates' spread
    assert omega_plausible(OmegaMsg(1, 0, 0.0, 0.0, -1.0), OmegaMsg(1, 4, 4 * T, -0.09 * 4 * T / 0.09 * 0.9, -0.8), T)
    assert not omega_plausible(OmegaMsg(1, 0, 0.0, 0.0, -1.0), OmegaMsg(1, 4, 4 * T, 1.0, -0.8), T)


def test_a_restart_in_the_roster_lets_omega_jump_and_a_consistent_new_past_heals():
    a = node(0)
    _ticked(a, 0)
    a.on_message(msg(1, 0))
    a.on_roster(RosterChange(1, 1, "gone"))
    a.on_roster(RosterChange(1, 1, "live", fresh=True))
    _ticked(a, 1)
    assert a.on_message(msg(1, 1, omega=7.0)) is None  # explained by the restart
    b = node(0)  # no roster news (a realtime stall): three consistent messages make a new past
    _ticked(b, 0)
    b.on_message(msg(1, 0))
    for n in (1, 2, 3):
        _ticked(b, n)
        reason = b.on_message(msg(1, n, omega=5.0 - n * T))
        assert reason == ("implausible" if n < 3 else None)
    assert b.rejected["implausible"] == 2 and b.seen_seq[1] == 3


def test_a_slower_broadcast_rejects_nothing_and_a_frozen_senders_omega_passes():
    from cdus.core.node import omega_plausible
    from cdus.scenario.config import load_scenario
    from cdus.sim.fleet import InProcessFleet
    sc = load_scenario("configs/lake_circle.toml", {"scenario.duration": 30.0, "rates.broadcast": 10.0})
    fleet = InProcessFleet(sc)
    fleet.run()
    assert fleet.nodes[0].every == 5
    assert not any(nd.rejected[r] for nd in fleet.nodes for r in ("implausible", "future", "conflict"))
    # a sender frozen for 12 ticks: ω where it was, rate the law's
    assert omega_plausible(OmegaMsg(1, 0, 0.0, 3.0, -1.0), OmegaMsg(1, 12, 12 * T, 3.0 + 0.01, -1.02), T)


@pytest.mark.parametrize("name", ["concentric_circles", "crossing", "lake_circle", "lake_circle_dynamic",
                                  "lake_windy", "lissajous_5x5", "offset_circles"])
def test_clean_runs_of_the_shipped_configs_reject_nothing_hostile_and_are_unchanged(name, monkeypatch):
    """The entry checks on a clean run: nothing is future, conflict or implausible, and the
    trajectory is bit for bit the one without the checks."""
    from cdus.core import node as node_mod
    from cdus.scenario.config import load_scenario
    from cdus.sim.fleet import InProcessFleet

    def run():
        sc = load_scenario(f"configs/{name}.toml", {"scenario.duration": 30.0})
        fleet = InProcessFleet(sc)
        res = fleet.run()
        return res.recorder, [*fleet._retired, *fleet.nodes]

    rec, nodes = run()
    for nd in nodes:
        assert not any(nd.rejected[r] for r in node_mod.HOSTILE_REASONS + ("inconsistent", "stale")), nd.rejected
    monkeypatch.setattr(node_mod.VehicleNode, "on_message", _on_message_before_issue_15)
    rec2, _ = run()
    for attr in ("t", "q", "heading", "omega", "omega_rate"):
        assert np.array_equal(getattr(rec, attr), getattr(rec2, attr)), attr


def _on_message_before_issue_15(self, msg, arrival=None):
    """The entry of ω before the checks, for the comparison above."""
    import heapq
    k = msg.sender
    if k not in self._peers:
        return self._reject("not_a_neighbour")
    if round(msg.t_send / self.period) < self._deaf_before:
        return None
    if msg.seq <= self.seen_seq.get(k, -1):
        return self._reject("stale")
    self.seen_seq[k] = msg.seq
    if arrival is None:
        self._inbox.append(msg)
    else:
        for d in self._decide(msg):
            self._order += 1
            heapq.heappush(self._pending, (arrival + d, self._order, msg, d))
    return None


# ------------------------------------------------------------------ properties (issue 15)


_floats = st.floats(allow_nan=False, allow_infinity=False) | st.sampled_from([0.0, 1e308, -1e308, T, 1e-300])
_any_omega = st.builds(OmegaMsg, st.integers(-2, 5), st.integers(-2, 2**33), _floats, _floats, _floats)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 12), _any_omega, st.booleans()), max_size=40))
def test_on_message_never_raises_and_counts_every_reject(script):
    """Arbitrary decoded messages between steps: no exception, and every message is either
    taken (its seq becomes the sender's newest) or rejected and counted."""
    a = node(0)
    n = 0
    for at, m, realtime in sorted(script, key=lambda s: s[0]):
        while n < at:
            _ticked(a, n)
            n += 1
        before = sum(a.rejected.values())
        reason = a.on_message(m, arrival=n * T if realtime else None)
        if reason is None:
            assert a.seen_seq.get(m.sender) == m.seq or m.seq * a.every < a._deaf_before
        else:
            assert reason in a.rejected and sum(a.rejected.values()) == before + 1
    for k in range(n, n + 3):
        _ticked(a, k)


def _hostile(data: st.DataObject, src: int, n: int, last: int) -> OmegaMsg | bytes:
    """A message on ``src``'s key that is out of window or malformed at fleet tick ``n``."""
    how = data.draw(st.sampled_from(["future", "inconsistent", "stale", "other", "bytes", "huge"]))
    w = data.draw(_floats)
    wd = data.draw(_floats)
    if how == "future":
        s = data.draw(st.integers(n + 1, 2**32 - 1))
        return OmegaMsg(src, s, s * T, w, wd)
    if how == "inconsistent":
        s = data.draw(st.integers(0, n))
        t = data.draw(_floats.filter(lambda t: t != s * T))
        return OmegaMsg(src, s, t, w, wd)
    if how == "stale" and n > 0:  # a seq already sent: a replay with any content
        s = data.draw(st.integers(0, n - 1))
        return OmegaMsg(src, s, s * T, w, wd)
    if how == "other":  # another vehicle's index on this key
        return OmegaMsg((src + 1) % 3, n, n * T, w, wd)
    if how in ("huge", "stale"):
        return OmegaMsg(src, 2**32 - 1, 1e308, w, wd)
    return data.draw(st.binary(max_size=40))


@settings(max_examples=25, deadline=None)
@given(st.data())
def test_hostile_traffic_out_of_window_never_changes_a_genuine_run(data):
    """The ring run in process, with hostile messages injected on the genuine senders' keys
    before and after each genuine one: the trajectory is the clean run's, bit for bit, and
    every hostile message is counted."""
    from cdus.sim.fleet import InProcessFleet
    from cdus.scenario.config import parse_scenario
    from cdus.wire.messages import decode_omega, encode_omega
    from cdus.wire.rejected import Rejected

    sc = parse_scenario({**RING, "scenario": {"name": "ring3", "duration": 1.0}})
    clean = InProcessFleet(sc)
    clean.run()
    fleet = InProcessFleet(sc)
    sent = {"hostile": 0}
    real_send = fleet._send

    def send(src, msg, n):
        for _ in range(data.draw(st.integers(0, 2))):
            h = _hostile(data, src, n, fleet.end_tick)
            wire = decode_omega(h if isinstance(h, bytes) else encode_omega(h), expected_sender=src, n_vehicles=3)
            for dst in fleet.listeners[src]:
                if isinstance(wire, Rejected):
                    sent["hostile"] += 1
                    fleet.nodes[dst].rejected.setdefault(wire, 0)
                    fleet.nodes[dst].rejected[wire] += 1
                else:
                    sent["hostile"] += 1
                    assert fleet.nodes[dst].on_message(wire) is not None
        real_send(src, msg, n)
    fleet._send = send
    fleet.run()
    for attr in ("t", "q", "heading", "omega", "omega_rate"):
        assert np.array_equal(getattr(clean.recorder, attr), getattr(fleet.recorder, attr)), attr
    counted = sum(sum(x for r, x in nd.rejected.items() if r != "gone") for nd in fleet.nodes)
    assert counted == sent["hostile"]


def test_a_message_lost_in_flight_and_said_again_fills_its_gap_in_send_order():
    """An outage loses seq 2 in flight while 3 gets through; the sender's resend of 2 is taken
    (not 'stale'), the node waits for it before stepping past it, and both are decided in send
    order, so the run is the one in which nothing was lost."""
    ref, a = node(0), node(0)
    for n in range(6):
        for k in (1, 2):
            ref.on_message(msg(k, n))
        ref.step(n)
    for n in range(2):
        for k in (1, 2):
            a.on_message(msg(k, n))
        a.step(n)
    a.on_message(msg(1, 3))  # 2 lost, 3 arrived
    a.on_message(msg(2, 2))
    a.on_message(msg(2, 3))
    assert a.waiting_for(3) == [1]  # seq 2 of vehicle 1 is missing
    assert a.on_message(msg(1, 2)) is None  # the resend fills the gap
    assert a.rejected["stale"] == 0 and a.waiting_for(3) == []
    assert a.on_message(msg(1, 2)) == "stale"  # a second copy is a duplicate
    for n in range(2, 6):
        if n >= 4:
            for k in (1, 2):
                a.on_message(msg(k, n))
        a.step(n)
    assert a.vehicle.omega == ref.vehicle.omega and list(a.vehicle.q) == list(ref.vehicle.q)
    assert a.counters.sent == ref.counters.sent and a.counters.delivered == ref.counters.delivered


def test_a_forged_fill_of_a_gap_is_implausible():
    a = node(0)
    a.on_message(msg(1, 0))
    a.on_message(msg(1, 2))
    assert a.on_message(msg(1, 1, omega=1.0 - T + 1.0)) == "implausible"
    assert a.on_message(msg(1, 1)) is None


def test_a_forgery_taken_first_does_not_lock_the_genuine_sender_out():
    """A forged ω that arrives before the genuine one of its seq, when there is no past to judge
    it by, is taken; the genuine one is a conflict but kept as a candidate, so the genuine
    sender's next messages agree with the past and are taken: the sender is never locked out."""
    a = node(0)
    assert a.on_message(msg(1, 0, omega=99.0)) is None  # forged, first heard: nothing to judge it by
    assert a.on_message(msg(1, 0)) == "conflict"  # the genuine one
    for t in range(1, 6):
        assert a.on_message(msg(1, t)) is None, t  # genuine, agrees with the genuine candidate
        assert a.on_message(msg(1, t + 1, omega=1.0 - t * T + 1.0)) == "implausible"
    assert a.seen_seq[1] >= 5 and a.rejected["implausible"] >= 4


def test_forgeries_that_disagree_with_the_past_are_never_candidates():
    a = node(0)
    a.on_message(msg(1, 0))
    a.on_message(msg(1, 1))
    assert a.on_message(msg(1, 1, omega=5.0)) == "conflict"
    assert all(m.omega != 5.0 for m in a._peers[1].recent[1])



def _spoof(m: OmegaMsg) -> OmegaMsg:
    """The Spoofer of tests/e2e/test_hostile.py: the genuine ω + 1 rad at the next seq."""
    return OmegaMsg(m.sender, m.seq + 1, (m.seq + 1) * T, m.omega + 1.0, 12345.0)


def _as_an_agent(a: VehicleNode, arrivals: list[OmegaMsg], last: int) -> list[str | None]:
    """Feed ``arrivals`` in this order, stepping as far as the lookahead allows after each, as a
    lockstep agent granted up to ``last`` does; returns each message's answer."""
    answers = []
    for m in arrivals:
        answers.append(a.on_message(m))
        while a.tick <= last and not a.waiting_for(a.tick):
            a.step(a.tick)
    return answers


def _clean(last: int) -> VehicleNode:
    ref = node(0)
    for n in range(last + 1):
        for k in (1, 2):
            ref.on_message(msg(k, n))
        ref.step(n)
    return ref


def test_a_forgery_that_overtakes_its_genuine_predecessor_is_withdrawn_not_decided():
    """Lockstep under load: the Spoofer's seq 8, made from the genuine seq 7, reaches a receiver
    before the genuine 7. Judged against seq 6 over a 2-tick gap, with its absurd rate, it passed
    and was taken; the genuine 7 filled the gap, and then tick 9 (which needs seq 8) did not wait
    for the genuine 8 and decided the forgery in its place (the hostile e2e test's trace then
    differed from cdus sim by ~1e-4 rad after 60 s). Once 7 is in, 8 is re-judged, withdrawn,
    and the node waits for the genuine 8: the run is the clean one, the forgery counted."""
    ref, a = _clean(12), node(0)
    arrivals = [msg(k, n) for n in range(7) for k in (1, 2)]
    arrivals += [msg(2, 7), _spoof(msg(1, 7)), msg(1, 7), msg(2, 8)]  # the forgery overtakes the genuine 7
    arrivals += [msg(1, 8)] + [msg(k, n) for n in range(9, 12) for k in (1, 2)]
    answers = _as_an_agent(a, arrivals, 12)
    assert a.tick == 13
    assert a.vehicle.omega == ref.vehicle.omega and list(a.vehicle.q) == list(ref.vehicle.q)
    assert a.table.latest[1] == ref.table.latest[1]
    assert a.counters.sent == ref.counters.sent and a.counters.delivered == ref.counters.delivered
    # the forgery was taken at first, then withdrawn and counted when the genuine 7 came
    assert answers[14:17] == [None, None, "implausible"] and answers.count(None) == len(answers) - 1


def test_a_forgery_withdrawn_after_its_genuine_came_as_a_conflict_gives_the_genuine_its_place():
    """The same overtaking forgery, but the genuine 8 also arrives before the genuine 7 (a
    conflict then, kept as a candidate): the fill of 7 puts the genuine 8 in the forgery's place."""
    ref, a = _clean(12), node(0)
    arrivals = [msg(k, n) for n in range(7) for k in (1, 2)]
    arrivals += [msg(2, 7), msg(2, 8), _spoof(msg(1, 7)), msg(1, 8), msg(1, 7)]
    arrivals += [msg(k, n) for n in range(9, 12) for k in (1, 2)]
    answers = _as_an_agent(a, arrivals, 12)
    assert a.tick == 13
    assert a.vehicle.omega == ref.vehicle.omega and list(a.vehicle.q) == list(ref.vehicle.q)
    assert a.table.latest[1] == ref.table.latest[1]
    assert answers[16:19] == [None, "conflict", "implausible"]


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_spoofed_omega_in_any_arrival_order_lockstep_allows_never_changes_the_run(data):
    """The Spoofer's forgeries (seq s + 1 made from the genuine s, +1 rad) reach the receiver in
    any order a fleet of processes allows: the genuine messages of each sender in send order, a
    forgery at any moment after its sender's previous genuine message was sent (a sender runs
    at most a tick or two ahead of this receiver in the ring), once the sender's first message
    is in (before it, a forgery has no past to be judged by: docs/security.md). The receiver
    steps whenever the lookahead lets it; it ends where the clean run ends, bit for bit."""
    last = 12
    ref = _clean(last)
    arrivals: list[OmegaMsg] = []
    nxt = {1: 0, 2: 0}
    while min(nxt.values()) < last:  # the two senders' streams merged in any order, each in send order
        k = data.draw(st.sampled_from([j for j in (1, 2) if nxt[j] < last]))
        arrivals.append(msg(k, nxt[k]))
        nxt[k] += 1
    for s in data.draw(st.lists(st.integers(0, last - 2), unique=True, max_size=8)):
        g = msg(1, s)
        earliest = arrivals.index(msg(1, max(0, s - 2))) + 1
        at = data.draw(st.integers(earliest, len(arrivals)))
        arrivals.insert(at, _spoof(g))
    a = node(0)
    _as_an_agent(a, arrivals, last)
    assert a.tick == last + 1
    assert a.vehicle.omega == ref.vehicle.omega and list(a.vehicle.q) == list(ref.vehicle.q)
