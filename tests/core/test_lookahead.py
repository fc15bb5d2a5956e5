"""The lockstep lookahead: a tick waits only for the broadcasts it can use (cdus.core.schedule.
needed_seq, VehicleNode.waiting_for), and a fleet stepping in any order that rule allows
equals the in-process run to the bit."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cdus.core.link import LinkEmulator, draw_delay
from cdus.core.linkspec import Delay, LinkSpec, Override
from cdus.core.schedule import delay_floor, delivery_tick, first_seq_at, needed_seq
from cdus.scenario.config import load_scenario
from cdus.scenario.link import validate_link
from cdus.sim.build import build_node, link_emulator_for, listeners_of
from cdus.sim.fleet import InProcessFleet
from cdus.wire.messages import OmegaMsg, decode_omega, encode_omega

T = 0.02


# ------------------------------------------------------------------ the bound


@settings(max_examples=300, deadline=None)
@given(dist=st.sampled_from(["uniform", "normal", "pareto"]), base=st.floats(0, 2), jitter=st.floats(0, 2),
       u1=st.floats(0, 1, exclude_max=True), u2=st.floats(0, 1, exclude_max=True))
def test_no_draw_is_below_the_floor(dist, base, jitter, u1, u2):
    d = Delay(base=base, jitter=jitter, distribution=dist)
    assert draw_delay(dist, base, jitter, u1, u2) >= delay_floor(d)


def test_the_floor_of_each_distribution():
    assert delay_floor(Delay()) == 0.0
    assert delay_floor(Delay(base=0.1)) == 0.1
    assert delay_floor(Delay(base=0.1, jitter=0.04)) == pytest.approx(0.06)
    assert delay_floor(Delay(base=0.1, jitter=0.2)) == 0.0
    assert delay_floor(Delay(base=0.1, jitter=0.05, distribution="pareto")) == 0.1
    assert delay_floor(Delay(base=0.1, jitter=0.05, distribution="normal")) == 0.0
    assert delay_floor(Delay(base=0.1, distribution="normal")) == 0.1


def brute_needed(n: int, every: int, floors) -> int:
    """By definition: the newest seq sent before n whose earliest delivery is by n."""
    best = -1
    for s in range(0, n):
        m = s * every
        if m > n - 1:
            break
        floor = [f for first, f in floors if first <= s][-1]
        if delivery_tick(m, floor, T) <= n:
            best = s
    return best


@settings(max_examples=300, deadline=None)
@given(n=st.integers(0, 400), every=st.integers(1, 7),
       epochs=st.lists(st.tuples(st.integers(1, 80), st.sampled_from([0.0, 0.01, 0.02, 0.03, 0.1, 0.13, 0.5, 1.0])),
                       max_size=3),
       first=st.sampled_from([0.0, 0.02, 0.1, 0.3]))
def test_needed_seq_is_the_newest_usable_broadcast(n, every, epochs, first):
    floors, s = [(0, first)], 0
    for gap, f in epochs:  # run-time changes, raising or lowering the delay
        s += gap
        floors.append((s, f))
    assert needed_seq(n, every, T, floors) == brute_needed(n, every, floors)


def test_first_seq_at_follows_the_emulators_epochs():
    assert first_seq_at(-math.inf, 5, T) == 0
    for at in (0.0, 0.02, 0.1, 0.11, 0.3, 1.0, 7.77):
        for every in (1, 3, 5):
            s = first_seq_at(at, every, T)
            assert (s * every) * T >= at and (s == 0 or ((s - 1) * every) * T < at)


def test_a_least_delay_of_five_ticks_lets_a_tick_go_on_without_the_last_five_broadcasts():
    """Fails with the rule that waits for every broadcast sent before n."""
    sc = load_scenario("configs/lake_circle.toml", {"link.delay.base": 0.1})
    a = build_node(sc, "usv1", link_emulator_for(sc))
    assert a.waiting_for(5) == sorted(a.neighbours)  # needs seq 0: sent at 0, usable at 5
    for k in a.neighbours:
        a.on_message(OmegaMsg(k, 0, 0.0, 1.0, -1.0))
    assert a.waiting_for(5) == []  # seqs 1..4 cannot be usable before tick 6
    assert a.waiting_for(6) == sorted(a.neighbours)


def test_broadcasts_every_five_ticks_and_a_delay_wait_for_what_is_usable():
    sc = load_scenario("configs/lake_circle.toml", {"rates.broadcast": 10.0, "link.delay.base": 0.06})
    a = build_node(sc, "usv1", link_emulator_for(sc))  # every 5 ticks, least delay 3 ticks
    assert [a.needed_seq(a.neighbours[0], n) for n in (0, 2, 3, 7, 8, 12, 13)] == [-1, -1, 0, 0, 1, 1, 2]


def test_a_run_time_change_that_lowers_the_delay_is_waited_for_from_its_epoch():
    sc = load_scenario("configs/lake_circle.toml", {"link.delay.base": 0.2})
    a = build_node(sc, "usv1", link_emulator_for(sc))
    k = a.neighbours[0]
    assert a.needed_seq(k, 50) == 40
    a.set_link(validate_link({"delay": {"base": 0.0}}, list(sc.ids), "t"), 50 * T)
    assert [a.needed_seq(k, n) for n in (50, 51, 52, 60)] == [40, 50, 51, 59]


def test_the_bound_is_per_link():
    sc = load_scenario("configs/lake_circle.toml")
    spec = LinkSpec(delay=Delay(base=0.1), overrides=(Override(src="usv2", delay=(("base", 0.0),)),))
    a = build_node(sc, "usv1", LinkEmulator(spec, list(sc.ids), 1))
    usv2, uav3 = sc.ids.index("usv2"), sc.ids.index("uav3")
    assert a.needed_seq(usv2, 10) == 9 and a.needed_seq(uav3, 10) == 5


# ------------------------------------------------------------------ a fleet in any order


def lockstep_in_any_order(sc, rng: random.Random, change: tuple[int, dict] | None = None):
    """Step sc's vehicles as lockstep agents would, in a random order the protocol allows:
    each node its own emulator; messages in flight per link (FIFO), delivered at random
    moments; a node steps tick n once granted and ``waiting_for(n)`` is empty; the grant grows
    by random amounts, held below a run-time link change's tick until every node has it.
    Returns omega[tick, vehicle], q[tick, vehicle], the most ticks any node stepped ahead of
    a neighbour's newest send."""
    ids = list(sc.ids)
    period = 1.0 / sc.rates.control
    last = round(sc.duration / period)
    nodes = [build_node(sc, v, link_emulator_for(sc)) for v in ids]
    listeners = {j: [ids.index(x) for x in listeners_of(sc, v)] for j, v in enumerate(ids)}
    flight: dict[tuple[int, int], list[OmegaMsg]] = {(j, d): [] for j in range(len(ids)) for d in listeners[j]}
    omega = np.full((last + 1, len(ids)), np.nan)
    q = np.full((last + 1, len(ids), 3), np.nan)
    granted, lead, applied = -1, 0, change is None
    while min(node.tick for node in nodes) <= last:
        r = rng.random()
        if r < 0.1:
            cap = last if applied else change[0] - 1
            granted = min(cap, granted + rng.randint(1, 40))
            if not applied and granted == change[0] - 1 and rng.random() < 0.3:
                spec = validate_link(change[1], ids, "change")
                for node in nodes:
                    node.set_link(spec, change[0] * period)
                applied = True
        elif r < 0.55:
            busy = [key for key, msgs in flight.items() if msgs]
            if busy:
                src, dst = rng.choice(busy)
                nodes[dst].on_message(flight[(src, dst)].pop(0))
        else:
            j = rng.randrange(len(ids))
            node = nodes[j]
            n = node.tick
            if n > last or n > granted or node.waiting_for(n):
                continue
            sent = [nodes[k].tick - 1 for k in node.neighbours]
            lead = max(lead, n - 1 - min(sent))
            out = node.step(n)
            omega[n, j] = out.telemetry.omega
            q[n, j, :len(out.telemetry.q)] = out.telemetry.q
            if out.omega is not None:
                wire = decode_omega(encode_omega(out.omega))
                for dst in listeners[j]:
                    flight[(j, dst)].append(wire)
    counters = [(nd.counters.sent, nd.counters.delivered, nd.counters.dropped, nd.counters.duplicated)
                for nd in nodes]
    return omega, q, lead, counters


def in_process(sc, change: tuple[int, dict] | None = None):
    fleet = InProcessFleet(sc)
    if change is not None:
        while fleet.tick < change[0]:
            fleet.step()
        fleet.link.update(validate_link(change[1], list(sc.ids), "change"), change[0] * fleet.period)
    res = fleet.run()
    counters = [(nd.counters.sent, nd.counters.delivered, nd.counters.dropped, nd.counters.duplicated)
                for nd in fleet.nodes]
    ref_q = np.full(res.recorder.view("q").shape[:2] + (3,), np.nan)
    for j, v in enumerate(sc.vehicles):
        ref_q[:, j, :v.dim] = res.recorder.view("q")[:, j, :v.dim]
    return res.recorder.view("omega"), ref_q, counters


CASES = {
    "broadcast = control": ({}, None),
    "broadcast 10 Hz": ({"rates.broadcast": 10.0}, None),
    "delay 0.1 s": ({"link.delay.base": 0.1}, None),
    "delay 0.1 ± 0.04 s, loss": ({"link.delay.base": 0.1, "link.delay.jitter": 0.04, "link.loss": 0.2}, None),
    "pareto delay, fifo, 10 Hz": ({"link.delay.base": 0.08, "link.delay.jitter": 0.05,
                                   "link.delay.distribution": "pareto", "link.delay.reorder": False,
                                   "rates.broadcast": 10.0}, None),
    "the delay lowered at run time": ({"link.delay.base": 0.2}, (60, {"delay": {"base": 0.02}})),
    "the delay raised at run time": ({"link.delay.base": 0.04, "rates.broadcast": 25.0},
                                     (35, {"delay": {"base": 0.3, "jitter": 0.1}})),
}


@pytest.mark.parametrize("case", CASES)
def test_a_fleet_stepping_in_any_order_the_lookahead_allows_equals_the_in_process_run(case):
    settings_, change = CASES[case]
    sc = load_scenario("configs/lake_circle.toml", {"scenario.duration": 3.0, **settings_})
    ref_omega, ref_q, ref_counters = in_process(sc, change)
    for seed in range(3):
        omega, q, lead, counters = lockstep_in_any_order(sc, random.Random(seed), change)
        assert counters == ref_counters, (case, seed)  # every message decided, as in process
        assert np.array_equal(omega, ref_omega), (case, seed)
        assert np.array_equal(q, ref_q, equal_nan=True), (case, seed)
    if case != "broadcast = control":
        assert lead > 1, "the lookahead was never used"
