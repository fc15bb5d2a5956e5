"""The link fault emulator: statistics, exact windows, determinism (its [link] schema is
tested in tests/scenario/test_link.py).

Statistical bounds are 5 σ (or a DKW band at confidence 1 - 1e-6), over 10^5 seeded
messages, so a correct emulator fails them with probability < 1e-6 per check, and since
everything is seeded the outcome is fixed anyway.
"""

import math
import random
from statistics import NormalDist

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from cdus.core.linkspec import Burst, Delay, LinkSpec
from cdus.scenario.link import validate_link
from cdus.core.link import (
    DropBursts, LinkEmulator, LinkFaultCounters, burst_bad, burst_events, draw_delay, merge_link_summaries, stream_key, uniform,
)

IDS = ("usv1", "usv2", "usv3", "uav1", "uav2", "uav3")
USV1, USV2, USV3, UAV1, UAV2, UAV3 = range(6)
N = 100_000
DT = 0.02  # s between broadcasts


def spec(table):
    return validate_link(table, IDS, "test.toml")


def emulator(table, seed=7):
    return LinkEmulator(spec(table), IDS, seed)


def run(e, src=USV1, dst=USV2, n=N, dt=DT):
    return [e.decide(src, dst, s, s * dt) for s in range(n)]


def binomial_ok(count, n, p, sigmas=5.0, inflation=1.0):
    """|count - n p| within ``sigmas`` standard deviations (variance times ``inflation``)."""
    return abs(count - n * p) <= sigmas * math.sqrt(n * p * (1 - p) * inflation)


# --------------------------------------------------------------------------- random streams


def test_uniforms_are_in_range_and_depend_on_every_key_part():
    key = stream_key(7, "usv1", "usv2", "loss")
    us = [uniform(key, s) for s in range(10_000)]
    assert all(0.0 <= u < 1.0 for u in us)
    assert abs(sum(us) / len(us) - 0.5) < 5 * math.sqrt(1 / 12 / len(us))
    keys = {stream_key(7, "usv1", "usv2", "loss"), stream_key(8, "usv1", "usv2", "loss"),
            stream_key(7, "usv2", "usv1", "loss"), stream_key(7, "usv1", "usv2", "duplicate")}
    assert len(keys) == 4
    assert uniform(key, 3) == uniform(key, 3) != uniform(key, 4)


# --------------------------------------------------------------------------- Bernoulli loss


@pytest.mark.parametrize("p", [0.05, 0.3])
def test_bernoulli_loss_rate_is_binomial(p):
    e = emulator({"loss": p})
    drops = sum(1 for d in run(e) if not d)
    assert binomial_ok(drops, N, p), (drops, N * p)
    c = e.counters()[(USV1, USV2)]
    assert (c.sent, c.dropped, c.loss, c.burst) == (N, drops, drops, 0)


def test_loss_zero_and_one_are_exact():
    assert all(d == (0.0,) for d in run(emulator({"loss": 0.0, "duplicate": 0.0}), n=1000))
    assert all(d == () for d in run(emulator({"loss": 1.0}), n=1000))


# --------------------------------------------------------------------------- Gilbert-Elliott


def _runs(dropped):
    lengths, current = [], 0
    for x in dropped:
        if x:
            current += 1
        elif current:
            lengths.append(current)
            current = 0
    return lengths


def test_gilbert_elliott_stationary_loss_and_mean_burst_length():
    p, r = 0.05, 0.5
    dropped = [not d for d in run(emulator({"burst": {"p": p, "r": r}}))]
    pi_bad = p / (p + r)
    lam = 1 - p - r  # the chain's second eigenvalue: Var(mean) grows by (1 + λ) / (1 - λ)
    assert binomial_ok(sum(dropped), N, pi_bad, inflation=(1 + lam) / (1 - lam)), (sum(dropped) / N, pi_bad)
    bursts = _runs(dropped)  # with bad_loss = 1, good_loss = 0 a burst is a stay in the bad state: Geometric(r)
    mean = sum(bursts) / len(bursts)
    se = math.sqrt(1 - r) / r / math.sqrt(len(bursts))
    assert abs(mean - 1 / r) <= 5 * se, (mean, 1 / r, se)
    assert abs(mean - 1 / r) / (1 / r) < 0.05


def test_gilbert_elliott_with_partial_losses():
    b = {"p": 0.1, "r": 0.3, "bad_loss": 0.8, "good_loss": 0.02}
    e = emulator({"burst": b})
    drops = sum(1 for d in run(e) if not d)
    expected = Burst(**b).stationary_loss  # π_bad 0.8 + π_good 0.02 = 0.215
    assert expected == pytest.approx(0.25 * 0.8 + 0.75 * 0.02)
    lam = 1 - b["p"] - b["r"]  # Var(X) (1 + λ) / (1 - λ) bounds the asymptotic variance of the mean
    assert binomial_ok(drops, N, expected, inflation=(1 + lam) / (1 - lam)), (drops / N, expected)
    assert e.counters()[(USV1, USV2)].burst == drops


@pytest.mark.parametrize("p, r", [(0.05, 0.5), (0.01, 0.1), (0.7, 0.6), (0.5, 0.5), (0.3, 0.7), (0.0, 0.0),
                                  (1.0, 1.0), (0.0, 1.0), (1.0, 0.0), (0.9, 0.95)])
def test_burst_state_by_look_back_equals_stepping_forward(p, r):
    key = stream_key(3, "usv1", "uav2", "burst-step")
    bad = False
    for seq in range(3000):
        bad = uniform(key, seq) < (1 - r if bad else p)
        assert burst_bad(p, r, key, seq) == bad, seq


def test_burst_state_is_the_same_in_any_call_order():
    table = {"burst": {"p": 0.02, "r": 0.2, "bad_loss": 0.9, "good_loss": 0.01}}
    in_order = run(emulator(table), n=2000)
    e = emulator(table)
    seqs = list(range(2000))
    random.Random(1).shuffle(seqs)
    shuffled = {s: e.decide(USV1, USV2, s, s * DT) for s in seqs}
    assert [shuffled[s] for s in range(2000)] == in_order
    gappy = emulator(table)  # in seq order with gaps (messages that never arrived)
    kept = [s for s in range(2000) if random.Random(s).random() < 0.3]
    assert [gappy.decide(USV1, USV2, s, s * DT) for s in kept] == [in_order[s] for s in kept]


# --------------------------------------------------------------------------- delays


def _ks(samples, cdf):
    x = np.sort(np.asarray(samples))
    f = cdf(x)
    n = len(x)
    return max(np.max(np.arange(1, n + 1) / n - f), np.max(f - np.arange(0, n) / n))


DKW = math.sqrt(math.log(2 / 1e-6) / (2 * N))  # sup |F_n - F| <= DKW with probability 1 - 1e-6

_PHI = np.vectorize(NormalDist().cdf)
DELAYS = {
    # distribution: (base, jitter, cdf(x), quantile(q))
    "uniform": (0.1, 0.02, lambda x: np.clip((x - 0.08) / 0.04, 0, 1), lambda q: 0.08 + 0.04 * q),
    "normal": (0.5, 0.05, lambda x: _PHI((x - 0.5) / 0.05), lambda q: 0.5 + 0.05 * NormalDist().inv_cdf(q)),
    "pareto": (0.05, 0.02, lambda x: np.where(x < 0.05, 0.0, 1 - (1 + np.maximum(x - 0.05, 0) / 0.04) ** -3),
               lambda q: 0.05 + 0.04 * ((1 - q) ** (-1 / 3) - 1)),
}


@pytest.mark.parametrize("distribution", sorted(DELAYS))
def test_delay_distribution_matches_its_law(distribution):
    base, jitter, cdf, quantile = DELAYS[distribution]
    e = emulator({"delay": {"base": base, "jitter": jitter, "distribution": distribution}})
    delays = np.array([d[0] for d in run(e)])
    assert _ks(delays, cdf) <= DKW
    for q in (0.1, 0.5, 0.9):
        empirical = float(np.quantile(delays, q))
        assert abs(float(cdf(np.array([empirical]))[0]) - q) <= DKW, (q, empirical, quantile(q))
    if distribution == "pareto":
        assert delays.min() >= base and abs(delays.mean() - (base + jitter)) < 0.01 * base
    else:
        assert abs(delays.mean() - base) < 5 * delays.std() / math.sqrt(N)


def test_negative_delays_are_clipped_to_zero():
    delays = [d[0] for d in run(emulator({"delay": {"base": 0.0, "jitter": 0.1, "distribution": "normal"}}),
                                n=10_000)]
    assert min(delays) == 0.0
    zero = sum(1 for d in delays if d == 0.0)
    assert binomial_ok(zero, 10_000, 0.5)


def test_draw_delay_formulas():
    assert draw_delay("uniform", 1.0, 0.5, 0.0, 0.0) == 0.5
    assert draw_delay("uniform", 1.0, 0.5, 0.75, 0.0) == 1.25
    assert draw_delay("normal", 1.0, 0.5, 1 - math.exp(-0.5), 0.0) == pytest.approx(1.5)  # z = 1
    assert draw_delay("pareto", 1.0, 0.5, 0.0, 0.0) == 1.0
    assert draw_delay("pareto", 1.0, 0.5, 1 - 1 / 8, 0.0) == pytest.approx(2.0)  # 2 jitter (8^(1/3) - 1)
    assert draw_delay("uniform", 0.0, 0.5, 0.0, 0.0) == 0.0  # clipped


# --------------------------------------------------------------------------- reproducibility

GOLDEN_TABLE = {
    "delay": {"base": 0.1, "jitter": 0.05, "distribution": "normal"},
    "loss": 0.1, "burst": {"p": 0.1, "r": 0.4}, "duplicate": 0.1,
}
GOLDEN = [  # written once from the implementation, then frozen: a change here changes every run
    (0.026171831468,), (0.081258071472,), (0.110991507674,), (0.062316300311, 0.096248054823),
    (0.118601606151,), (0.046375927968,), (0.216711675425,), (0.087184553017,), (0.097597995889,),
    (), (), (), (), (), (), (),
    (0.100431102403, 0.038783465402), (0.107069974006,), (0.108824266029,), (0.137567801247,),
]


def test_golden_sequence_is_frozen():
    """The first 20 decisions of usv1 -> uav2 for seed 42: pins the random streams across versions."""
    e = emulator(GOLDEN_TABLE, seed=42)
    got = [e.decide(USV1, UAV2, s, s * 0.1) for s in range(20)]
    assert [tuple(round(d, 12) for d in x) for x in got] == GOLDEN


ALL_TABLE = {
    "delay": {"base": 0.05, "jitter": 0.04, "distribution": "pareto"},
    "loss": 0.05, "burst": {"p": 0.05, "r": 0.3, "good_loss": 0.01}, "duplicate": 0.05,
    "override": [{"src": "uav1", "delay": {"reorder": False, "distribution": "uniform"}},
                 {"dst": "usv3", "loss": 0.5}],
    "down": [{"src": "usv2", "from": 1.0, "to": 2.0}],
    "partition": [{"from": 3.0, "to": 4.0, "groups": [["usv1", "usv2"]]}],
}


def test_decisions_do_not_depend_on_the_call_order_across_links():
    links = [(s, d) for s in range(6) for d in range(6) if s != d]
    calls = [(s, d, q) for s, d in links for q in range(250)]
    expected = {}
    ref = emulator(ALL_TABLE)
    for s, d, q in sorted(calls, key=lambda c: (c[2], c[0], c[1])):  # send order, as the in-process fleet
        expected[(s, d, q)] = ref.decide(s, d, q, q * DT)
    # arrival order at each receiver: links interleaved at random, each link still in seq order
    rng = random.Random(5)
    queues = {ln: list(range(250)) for ln in links}
    shuffled = emulator(ALL_TABLE)
    got = {}
    while queues:
        ln = rng.choice(sorted(queues))
        q = queues[ln].pop(0)
        got[(*ln, q)] = shuffled.decide(ln[0], ln[1], q, q * DT)
        if not queues[ln]:
            del queues[ln]
    assert got == expected
    # one emulator per receiver (the multi-process agents) decides the same
    for dst in range(6):
        agent = emulator(ALL_TABLE)
        for q in range(250):
            for src in range(6):
                if src != dst:
                    assert agent.decide(src, dst, q, q * DT) == expected[(src, dst, q)]
    assert sum(1 for x in expected.values() if not x) > 0
    assert sum(1 for x in expected.values() if len(x) == 2) > 0


def test_seeds_give_independent_streams():
    a = run(emulator({"loss": 0.5}, seed=1), n=200)
    assert run(emulator({"loss": 0.5}, seed=1), n=200) == a
    assert run(emulator({"loss": 0.5}, seed=2), n=200) != a
    assert run(emulator({"loss": 0.5}, seed=1), src=USV2, dst=USV1, n=200) != a


# --------------------------------------------------------------------------- windows, overrides, duplicates, FIFO


def _times():
    return sorted([k * 0.25 for k in range(400)] + [29.999999, 39.999999])


def test_link_down_drops_exactly_within_its_window():
    e = emulator({"down": [{"src": "usv1", "dst": "usv2", "from": 30.0, "to": 40.0}]})
    for seq, t in enumerate(_times()):
        assert (e.decide(USV1, USV2, seq, t) == ()) == (30.0 <= t < 40.0), t
        assert e.decide(USV2, USV1, seq, t) == (0.0,)
        assert e.decide(USV1, USV3, seq, t) == (0.0,)
    c = e.counters()[(USV1, USV2)]
    assert c.down == c.dropped == sum(1 for t in _times() if 30.0 <= t < 40.0)
    assert [(t, s, d, st) for t, s, d, st in e.state_changes] == [(30.0, 0, 1, "down"), (40.0, 0, 1, "up")]


def test_link_down_with_wildcards_and_open_end():
    e = emulator({"down": [{"src": "uav1", "from": 5.0}]})  # every link from uav1, from t = 5 on
    for dst in (USV1, USV2, UAV3):
        assert e.decide(UAV1, dst, 0, 4.99) == (0.0,)
        assert e.decide(UAV1, dst, 1, 5.0) == ()
        assert e.decide(UAV1, dst, 2, 1e6) == ()
    assert e.decide(USV1, UAV1, 0, 10.0) == (0.0,)


def test_partition_groups_drop_between_groups_only_within_the_window():
    e = emulator({"partition": [{"from": 60.0, "to": 90.0, "groups": [["usv1", "usv2"], ["uav1"]]}]})
    group = {"usv1": 0, "usv2": 0, "uav1": 1, "usv3": 2, "uav2": 2, "uav3": 2}  # the unlisted stay together
    for seq, t in enumerate([59.99, 60.0, 75.0, 89.999, 90.0, 120.0]):
        for s in range(6):
            for d in range(6):
                if s == d:
                    continue
                split = group[IDS[s]] != group[IDS[d]] and 60.0 <= t < 90.0
                assert (e.decide(s, d, seq, t) == ()) == split, (IDS[s], IDS[d], t)
    assert e.counters()[(USV1, UAV1)].partition == 3
    assert e.counters()[(USV3, UAV2)].partition == 0


def test_partition_drops_are_asymmetric():
    e = emulator({"partition": [{"from": 0.0, "to": 10.0, "drops": {"usv2": ["usv1"], "uav1": ["usv3", "uav3"]}}]})
    assert e.decide(USV1, USV2, 0, 5.0) == ()  # usv2 drops usv1
    assert e.decide(USV2, USV1, 0, 5.0) == (0.0,)  # but usv1 still hears usv2
    assert e.decide(USV3, UAV1, 0, 5.0) == () and e.decide(UAV3, UAV1, 0, 5.0) == ()
    assert e.decide(USV2, UAV1, 0, 5.0) == (0.0,)
    assert e.decide(USV1, USV2, 1, 10.0) == (0.0,)


def test_down_is_the_cause_when_down_and_partition_overlap():
    e = emulator({"down": [{"from": 0.0, "to": 5.0}],
                  "partition": [{"from": 0.0, "to": 10.0, "drops": {"usv2": ["usv1"]}}]})
    assert e.decide(USV1, USV2, 0, 1.0) == () and e.decide(USV1, USV2, 1, 6.0) == ()
    c = e.counters()[(USV1, USV2)]
    assert (c.down, c.partition) == (1, 1)


def test_overrides_match_wildcards_and_later_ones_win():
    s = spec({"loss": 0.1, "delay": {"base": 0.2, "jitter": 0.01},
              "override": [{"src": "usv1", "loss": 0.5},
                           {"src": "usv1", "dst": "uav1", "loss": 0.9},
                           {"dst": "uav1", "delay": {"jitter": 0.05}},
                           {"src": "usv1", "dst": "*", "duplicate": 0.3}]})
    assert s.for_link("usv2", "usv3").loss == 0.1
    assert s.for_link("usv1", "usv3").loss == 0.5
    assert s.for_link("usv1", "uav1").loss == 0.9
    assert s.for_link("usv1", "uav1").delay == Delay(base=0.2, jitter=0.05)  # only jitter replaced
    assert s.for_link("usv2", "uav1").delay == Delay(base=0.2, jitter=0.05)
    assert s.for_link("usv1", "usv3").delay == Delay(base=0.2, jitter=0.01)
    assert s.for_link("usv1", "usv2").duplicate == 0.3 and s.for_link("usv2", "usv1").duplicate == 0.0
    e = LinkEmulator(s, IDS, 3)
    drops = sum(1 for d in run(e, USV1, UAV1, n=20_000) if not d)
    assert binomial_ok(drops, 20_000, 0.9)


def test_an_override_can_make_one_link_ideal():
    e = emulator({"loss": 0.5, "override": [{"src": "uav1", "dst": "uav2", "loss": 0.0}]})
    assert all(d == (0.0,) for d in run(e, UAV1, UAV2, n=1000))
    assert e.state_changes == []  # uav1 -> uav2 stays up
    assert sum(1 for d in run(e, UAV2, UAV1, n=1000) if not d) > 0
    assert e.state_changes == [(0.0, UAV2, UAV1, "lossy")]


def test_duplicate_probability_and_independent_copies():
    e = emulator({"duplicate": 0.2, "delay": {"base": 0.1, "jitter": 0.05}})
    decisions = run(e)
    twice = [d for d in decisions if len(d) == 2]
    assert all(len(d) in (1, 2) for d in decisions)
    assert binomial_ok(len(twice), N, 0.2)
    assert sum(1 for a, b in twice if a != b) == len(twice)  # each copy its own delay draw
    c = e.counters()[(USV1, USV2)]
    assert c.duplicated == len(twice) and c.delayed == N + len(twice)


def _usable(decisions, dt=DT):
    return [s * dt + x for s, d in enumerate(decisions) for x in d]


def test_fifo_keeps_the_order_and_reorder_does_not():
    table = {"delay": {"base": 0.1, "jitter": 0.09}, "duplicate": 0.1, "loss": 0.1}
    free = _usable(run(emulator(table), n=5000))
    assert sum(1 for a, b in zip(free, free[1:]) if b < a) > 100  # messages overtake one another
    e = emulator({**table, "delay": {**table["delay"], "reorder": False}})
    fifo_decisions = run(e, n=5000)
    fifo = _usable(fifo_decisions)
    assert all(b >= a - 1e-12 for a, b in zip(fifo, fifo[1:]))
    plain = run(emulator(table), n=5000)  # FIFO only holds messages back, never drops or speeds them up
    assert [len(d) for d in fifo_decisions] == [len(d) for d in plain]
    assert all(f >= p for fd, pd in zip(fifo_decisions, plain) for f, p in zip(fd, pd))
    assert e.decide(USV1, USV2, 4999, 4999 * DT) == fifo_decisions[4999]  # a repeated call answers the same


def test_fifo_without_delay_is_ideal_in_effect():
    e = emulator({"delay": {"reorder": False}})
    assert run(e, n=100) == [(0.0,)] * 100
    assert spec({"delay": {"reorder": False}}).is_ideal  # so the fleet takes IdealLink for it


# --------------------------------------------------------------------------- runtime changes


def test_update_applies_from_its_time_on_and_leaves_earlier_decisions():
    old = {"loss": 0.2, "burst": {"p": 0.1, "r": 0.5}, "delay": {"base": 0.05, "jitter": 0.01}}
    new = {"loss": 0.05, "burst": {"p": 0.02, "r": 0.3}, "delay": {"base": 0.3, "jitter": 0.1,
                                                                    "distribution": "normal"}}
    e = emulator(old)
    e.update(spec(new), at=50.0)
    got = run(e, n=5000)
    before, after = run(emulator(old), n=5000), run(emulator(new), n=5000)
    cut = int(round(50.0 / DT))
    assert got[:cut] == before[:cut]
    assert got[cut:] == after[cut:]
    assert got != before and got != after
    with pytest.raises(ValueError, match="before the previous one"):
        e.update(spec(old), at=10.0)


def test_update_to_ideal_takes_the_fast_path_and_records_the_state():
    e = emulator({"loss": 0.3})
    e.update(LinkSpec(), at=1.0)
    e.update(spec({"down": [{"from": 2.0, "to": 3.0}]}), at=1.5)
    for seq in range(200):
        e.decide(USV1, USV2, seq, seq * DT)
    assert [(t, st) for t, _, _, st in e.state_changes] == [(0.0, "lossy"), (1.0, "up"), (2.0, "down"),
                                                            (3.0, "up")]
    assert all(e.decide(USV1, USV2, seq, seq * DT) == (0.0,) for seq in range(50, 75))
    assert [d for _, d in e.epochs] == [spec({"loss": 0.3}), LinkSpec(),
                                        spec({"down": [{"from": 2.0, "to": 3.0}]})]


# --------------------------------------------------------------------------- records


def test_counters_summary_and_merge():
    table = {"loss": 0.2, "duplicate": 0.1, "delay": {"base": 0.01},
             "down": [{"src": "usv2", "dst": "usv1", "from": 0.0, "to": 1.0}]}
    agents = [emulator(table) for _ in range(2)]
    for seq in range(100):
        agents[0].decide(USV2, USV1, seq, seq * DT)  # usv1's agent
        agents[1].decide(USV1, USV2, seq, seq * DT)  # usv2's agent
    a = agents[0].counters_summary()
    assert set(a) == {"total", "links", "state_changes"}
    link = a["links"]["usv2->usv1"]
    assert link["sent"] == 100 and link["dropped_by"]["down"] == 50
    assert link["dropped"] == sum(link["dropped_by"].values())
    assert a["state_changes"] == [{"t": 0.0, "link": "usv2->usv1", "state": "down"},
                                  {"t": 1.0, "link": "usv2->usv1", "state": "lossy"}]
    both = merge_link_summaries([a, agents[1].counters_summary()])
    assert list(both["links"]) == ["usv1->usv2", "usv2->usv1"]
    assert both["total"]["sent"] == 200
    assert both["total"]["dropped"] == link["dropped"] + both["links"]["usv1->usv2"]["dropped"]
    c = LinkFaultCounters()
    for x in agents[0].counters().values():
        c.add(x)
    assert c.as_dict() == a["total"]


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(1, 60), min_size=1, max_size=4), st.integers(0, 2**32 - 1))
def test_a_restarted_receivers_processes_merge_into_the_counters_of_one(lengths, seed):
    """A restarted vehicle's processes each decide part of its incoming links (the new one counts
    from zero): merged, every link counts what one process deciding it all counts. The merge used
    to keep the newest process's counters of a link only (per-link sums 65,000 against a total of
    70,898 after a lockstep restart, issue 27), while the totals added up."""
    table = {"loss": 0.3, "duplicate": 0.1, "burst": {"p": 0.05, "r": 0.3}}
    whole = emulator(table, seed)
    parts, seq = [], 0
    for n in lengths:  # one process per stretch of seqs, as a kill and a restart cut them
        part = emulator(table, seed)
        for s in range(seq, seq + n):
            for src, dst in ((USV1, USV2), (USV3, USV2)):
                assert part.decide(src, dst, s, s * DT) == whole.decide(src, dst, s, s * DT)
        parts.append(part.counters_summary())
        seq += n
    merged, one = merge_link_summaries(parts), whole.counters_summary()
    assert merged["links"] == one["links"] and merged["total"] == one["total"]
    assert sum(c["sent"] for c in merged["links"].values()) == merged["total"]["sent"] == 2 * seq


# --------------------------------------------------------------------------- which model


def test_drop_bursts_are_reported_when_a_run_of_drops_ends():
    b = DropBursts(min_len=3)
    pattern = [False, True, True, False, True, True, True, True, False, True]
    for j, dropped in enumerate(pattern):
        b.feed(0, 1, dropped, j * 0.1)
        b.feed(1, 0, False, j * 0.1)  # another link, never dropping
    assert b.done == [(0.4, 0.8, 0, 1, 4)]  # the run of 2 is too short; the last run is still open
    events = burst_events(b, ["a", "b"])
    assert [(e.t, e.kind, e.severity, e.link) for e in events] == [(0.8, "link_burst", "warn", "a->b")]
    assert events[0].text == "link a->b: 4 messages dropped in a row (0.40-0.80 s)"
    assert burst_events(b, ["a", "b"]) == []  # each burst is news once
