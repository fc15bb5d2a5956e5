"""The radio channel (cdus/core/radio.py, docs/radio.md); its parts' math has tests of its own
(test_propagation.py, test_reception.py, test_fading.py).

Statistical checks bound the deviation by the sample size: a normal (CLT) bound at a
Bonferroni-corrected alpha (ALPHA over the checks of one test), or an exact Poisson-binomial
tail for the delivery counts. Every draw is seeded, so a test gives the same answer each run;
the bounds say the answer is what the model predicts, not a tolerance picked to pass.
"""

from __future__ import annotations

import math
import random
from dataclasses import replace
from statistics import NormalDist

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from cdus.core.radio import C_LIGHT, Geometry, RadioChannel, RadioSpec, airtime, omega_size, path_loss_db
from cdus.wire.messages import OmegaMsg, encode_omega

ALPHA = 1e-3  # family-wise false-alarm rate of each statistical test


def z_bound(checks: int) -> float:
    """The two-sided normal quantile at the Bonferroni-corrected level ALPHA / checks."""
    return NormalDist().inv_cdf(1.0 - ALPHA / (2.0 * checks))


def chan(ids=("a", "b"), kinds=("usv", "usv"), seed=1, **kw) -> RadioChannel:
    rate = kw.pop("rate", 10.0)
    tick_period = kw.pop("tick_period", None)
    return RadioChannel(RadioSpec(**kw), ids, kinds, seed, rate=rate, tick_period=tick_period)


# --------------------------------------------------------------------------- propagation


@pytest.mark.parametrize("d,n,d0,pl0", [(1.0, 2.0, 1.0, 40.0), (10.0, 2.0, 1.0, 40.0), (250.0, 3.0, 1.0, 47.0),
                                        (1000.0, 2.7, 10.0, 60.0), (0.5, 3.0, 1.0, 40.0)])
def test_log_distance_at_known_distances(d, n, d0, pl0):
    expected = pl0 + 10 * n * math.log10(max(d, d0) / d0)
    assert path_loss_db(d, n, d0, pl0) == pytest.approx(expected, abs=1e-9)
    ch = chan(propagation="log_distance", exponent=n, d0=d0, pl0=pl0, antenna=(2.0, 0.1, 10.0),
              shadowing_sigma=0.0)
    geo = Geometry.of(0, [(0.0, 0.0), (d, 0.0)])
    assert ch.path_loss(ch.antenna(0, geo, 0), ch.antenna(1, geo, 0)) == pytest.approx(expected, abs=1e-9)


def test_log_distance_default_pl0_is_free_space_at_d0():
    spec = RadioSpec(propagation="log_distance", d0=1.0, frequency=5.18e9)
    assert spec.loss_d0 == pytest.approx(20 * math.log10(4 * math.pi * 5.18e9 / C_LIGHT), abs=1e-9)
    assert spec.loss_d0 == pytest.approx(46.73, abs=0.01)  # the textbook 5.18 GHz figure at 1 m


# --------------------------------------------------------------------------- reception


def test_delivery_falls_off_smoothly_with_range():
    ch = chan(shadowing_sigma=0.0, propagation="log_distance", exponent=3.0)
    ps = [ch.delivery_probability(0, 1, Geometry.of(0, [(0.0, 0.0), (d, 0.0)])) for d in range(50, 600, 5)]
    assert all(b <= a + 1e-12 for a, b in zip(ps, ps[1:]))
    assert ps[0] > 0.99 and ps[-1] < 0.01
    assert sum(1 for p in ps if 0.05 < p < 0.95) >= 3  # a transition band, not a cliff at one distance


def test_message_size_is_the_omega_wire_size_plus_header():
    assert omega_size(6) == len(encode_omega(OmegaMsg(5, 7, 1.0, 2.0, -1.0))) == 32
    assert omega_size(300) == 33
    ch = chan(header=40)
    assert ch.bytes == 72
    assert ch.air == pytest.approx(5e-5 + 8 * 72 / 6e6)


# --------------------------------------------------------------------------- shadowing and fading


def test_channel_shadowing_is_reciprocal_and_follows_positions():
    ch = chan(shadowing_sigma=5.0, shadowing_distance=20.0)
    g1 = Geometry.of(0, [(0.0, 0.0), (100.0, 0.0)])
    g2 = Geometry.of(5, [(0.0, 0.0), (100.0, 0.0)])  # the same positions later: the same (time not used)
    g3 = Geometry.of(5, [(0.0, 0.0), (160.0, 0.0)])
    s = [ch.shadowing(0, 1, ch.antenna(0, g, 0), ch.antenna(1, g, 0), g) for g in (g1, g2, g3)]
    back = ch.shadowing(1, 0, ch.antenna(1, g1, 0), ch.antenna(0, g1, 0), g1)
    assert s[0] == s[1] == back
    assert s[2] != s[0]
    timed = chan(shadowing_sigma=5.0, shadowing_time=2.0)
    with pytest.raises(ValueError, match="tick_period"):
        timed.delivery_probability(0, 1, g1)
    timed = chan(shadowing_sigma=5.0, shadowing_time=2.0, tick_period=0.02)
    assert timed.shadowing(0, 1, (0, 0, 1), (100, 0, 1), g1) != timed.shadowing(0, 1, (0, 0, 1), (100, 0, 1), g2)


# --------------------------------------------------------------------------- determinism


def geo_line(tick, dists, z=None):
    return Geometry.of(tick, [(d, 0.0, 0.0 if z is None else z[j]) for j, d in enumerate(dists)])


def test_decisions_do_not_depend_on_call_order():
    kw = dict(fading="nakagami", nakagami_m=1.0, shadowing_sigma=6.0, tx_power=0.0)
    ids, kinds = ("u1", "u2", "u3", "d1"), ("usv", "usv", "usv", "uav")
    geos = [geo_line(t, [0.0, 150.0 + t, 300.0, 50.0 * t], [0, 0, 0, 20.0]) for t in range(4)]
    calls = [(s, d, q, g) for s in range(4) for d in range(4) if s != d for q in range(30) for g in range(4)]
    for topology in ("adhoc", "station"):
        extra = {"topology": topology, "station": (0.0, -100.0, 0.0)}
        a = chan(ids, kinds, seed=9, **kw, **extra)
        first = {c: a.decide(c[0], c[1], c[2], 0.1 * c[2], geos[c[3]]) for c in calls}
        shuffled = list(calls)
        random.Random(4).shuffle(shuffled)
        b = chan(ids, kinds, seed=9, **kw, **extra)
        for c in shuffled:
            assert b.decide(c[0], c[1], c[2], 0.1 * c[2], geos[c[3]]) == first[c]
        c0 = calls[77]
        fresh = chan(ids, kinds, seed=9, **kw, **extra)
        assert fresh.decide(c0[0], c0[1], c0[2], 0.1 * c0[2], geos[c0[3]]) == first[c0]
        assert len({d.delivered for d in first.values()}) == 2  # the setting does decide something
        other = chan(ids, kinds, seed=10, **kw, **extra)
        assert any(other.decide(c[0], c[1], c[2], 0.1 * c[2], geos[c[3]]) != first[c] for c in calls)


# --------------------------------------------------------------------------- the delivery ratio, measured


def poisson_binomial(ps: np.ndarray) -> np.ndarray:
    """P(X = k), k = 0..n, X the number of successes of independent Bernoulli(p_i) (exact DP)."""
    dist = np.zeros(len(ps) + 1)
    dist[0] = 1.0
    for i, p in enumerate(ps):
        dist[1:i + 2] = dist[1:i + 2] * (1 - p) + dist[0:i + 1] * p
        dist[0] *= 1 - p
    return dist


def binomial_check(delivered: np.ndarray, ps: np.ndarray, bands: np.ndarray, n_bands: int) -> list:
    """Per band: the exact two-sided Poisson-binomial tail of the delivered count, Bonferroni
    over the bands; returns the failing bands."""
    bad = []
    for b in range(n_bands):
        sel = bands == b
        if not sel.any():
            continue
        dist = poisson_binomial(ps[sel])
        x = int(delivered[sel].sum())
        lower, upper = dist[:x + 1].sum(), dist[x:].sum()
        if min(lower, upper) < ALPHA / (2 * n_bands):
            bad.append((b, x, float(ps[sel].sum()), int(sel.sum()), lower, upper))
    return bad


@pytest.mark.parametrize("setting", [
    dict(propagation="two_ray", shadowing_sigma=4.0),
    dict(propagation="log_distance", exponent=2.8, shadowing_sigma=6.0, fading="nakagami", nakagami_m=1.5),
    dict(propagation="two_ray", shadowing_sigma=3.0, fading="rician", rician_k=4.0, capacity=4.0e5),
    # ^ a saturated medium (ρ = 1.08): queue drops and collisions too
    dict(propagation="two_ray", shadowing_sigma=4.0, access="aloha"),
    # ^ unslotted ALOHA: about 16 % collisions (CSMA's 9 µs window makes them 0.4 % above: a
    #   collision draw 3 times too likely passed every test)
])
def test_measured_delivery_per_distance_band_matches_the_prediction(setting):
    """At least 10,000 messages over distance bands: the delivered count per band is the exact
    Poisson-binomial of the model's per-message probabilities (given each geometry)."""
    n_rx, n_geo, per_geo = 10, 100, 11  # 10 receivers x 100 geometries x 11 messages = 11,000
    ids = ("tx",) + tuple(f"rx{j}" for j in range(n_rx))
    ch = RadioChannel(RadioSpec(**setting), ids, ("usv",) * len(ids), 5, rate=50.0)
    # the same model 1 dB stronger: the test must tell it apart
    stronger = RadioChannel(RadioSpec(**setting, tx_power=21.0), ids, ("usv",) * len(ids), 5, rate=50.0)
    rng = random.Random(2)
    dist, delivered, ps, ps1 = [], [], [], []
    seq = 0
    for t in range(n_geo):
        pos = [(0.0, 0.0)] + [(rng.uniform(20.0, 900.0), rng.uniform(-200.0, 200.0)) for _ in range(n_rx)]
        geo = Geometry.of(t, pos)
        for _ in range(per_geo):
            for r in range(1, n_rx + 1):
                d = ch.decide(0, r, seq, 0.02 * seq, geo)
                assert d.p == ch.delivery_probability(0, r, geo)
                dist.append(math.hypot(*pos[r]))
                delivered.append(d.delivered)
                ps.append(d.p)
                ps1.append(stronger.delivery_probability(0, r, geo))
            seq += 1
    assert len(ps) >= 10_000
    dist_a, ps_a, del_a = np.array(dist), np.array(ps), np.array(delivered)
    bands = np.minimum((dist_a // 100).astype(int), 9)
    assert binomial_check(del_a, ps_a, bands, 10) == []
    assert 0.05 < del_a.mean() < 0.95  # the bands span the transition
    # the check has power: the predictions of a model 1 dB off fail it
    assert binomial_check(del_a, np.array(ps1), bands, 10) != []


# --------------------------------------------------------------------------- station mode


def test_station_mode_both_legs_can_lose_it():
    ids, kinds = ("a", "b", "c"), ("usv", "usv", "usv")
    spec = dict(topology="station", station=(0.0, 0.0, 0.0), shadowing_sigma=0.0, tx_power=0.0, relay_delay=0.004)
    ch = chan(ids, kinds, **spec)
    near, mid, far = 30.0, 120.0, 2000.0

    def leg(d):  # one hop from a boat to a 10 m mast at distance d: the adhoc model with that height
        a = RadioChannel(RadioSpec(shadowing_sigma=0.0, tx_power=0.0, antenna_override=(("s", 10.0),)),
                         ("x", "s"), ("usv", "usv"), 1, rate=10.0)
        return a._leg(0, 1, Geometry.of(0, [(0.0, 0.0), (d, 0.0)]), 0).success
    # uplink far: lost whatever the downlink; downlink far: lost whatever the uplink
    g_up = Geometry.of(0, [(far, 0.0), (near, 0.0), (0.0, near)])
    g_down = Geometry.of(0, [(near, 0.0), (far, 0.0), (0.0, near)])
    assert ch.delivery_probability(0, 1, g_up) < 1e-6 and ch.delivery_probability(0, 1, g_down) < 1e-6
    assert ch.delivery_probability(0, 2, g_up) < 1e-6  # the uplink fails for every receiver
    assert ch.delivery_probability(1, 2, g_up) > 0.95  # two near boats talk through the station
    # both legs in the transition: delivery is the product of the legs (given the medium)
    g = Geometry.of(0, [(mid, 0.0), (0.0, mid), (0.0, near)])
    m = ch.medium(g)
    keep = 1 - m.queue_drop
    up, down = ch._leg(0, 3, g, 0), ch._leg(3, 1, g, 0)
    assert up.success == pytest.approx(leg(mid), abs=1e-12) and down.success == pytest.approx(leg(mid), abs=1e-12)
    p = ch.delivery_probability(0, 1, g)
    assert p == pytest.approx(keep * (1 - up.collision) * up.success * keep * (1 - down.collision) * down.success)
    assert 0.05 < p < 0.9
    n = 12000
    got = sum(ch.decide(0, 1, s, 0.0, g).delivered for s in range(n))
    assert abs(got - n * p) <= z_bound(1) * math.sqrt(n * p * (1 - p))
    # the uplink's outcome is shared: a message lost on the uplink is lost for b and c alike
    ups = [ch.decide(0, 1, s, 0.0, g) for s in range(2000)]
    ups2 = [ch.decide(0, 2, s, 0.0, g) for s in range(2000)]
    up_lost = [i for i in range(2000) if ch._through(up, 0, 3, i, "") is not None]
    assert up_lost and all(not ups[i].delivered and not ups2[i].delivered for i in up_lost)
    ok = next(d for d in ups if d.delivered)
    assert ok.delay == pytest.approx(2 * (m.wait + m.airtime) + 0.004)


# --------------------------------------------------------------------------- the shared medium


def test_medium_load_queueing_and_collisions():
    n, rate = 10, 50.0
    ids = tuple(f"v{j}" for j in range(n))
    geo = Geometry.of(0, [(float(j), 0.0) for j in range(n)])
    ch = RadioChannel(RadioSpec(shadowing_sigma=0.0), ids, ("usv",) * n, 1, rate=rate)
    a = airtime(96, 6e6, 5e-5)
    m = ch.medium(geo)
    rho = n * rate * a
    assert m.airtime == pytest.approx(a) and m.utilisation == pytest.approx(rho) == ch.utilisation(geo)
    assert m.wait == pytest.approx(rho * a / (2 * (1 - rho)))  # M/D/1 mean wait
    assert m.queue_drop == 0.0
    leg = ch._leg(0, 1, geo, 0)
    assert leg.collision == pytest.approx(1 - math.exp(-(n - 1) * rate * 9e-6))
    # not live: no load, no link
    half = Geometry.of(1, [(float(j), 0.0) if j < 5 else None for j in range(n)])
    assert ch.utilisation(half) == pytest.approx(5 * rate * a)
    assert ch.delivery_probability(0, 7, half) == 0.0 and ch.decide(0, 7, 0, 0.0, half).cause == "range"
    # station mode: every message goes on the air twice
    st = RadioChannel(RadioSpec(shadowing_sigma=0.0, topology="station", station=(0.0, 5.0, 0.0)), ids,
                      ("usv",) * n, 1, rate=rate)
    assert st.utilisation(geo) == pytest.approx(2 * rho)
    # beyond saturation: the carried load is the capacity, the rest is dropped at the queues
    sat = RadioChannel(RadioSpec(shadowing_sigma=0.0, capacity=2e4, queue=4, access="aloha"), ids, ("usv",) * n, 1,
                       rate=rate)
    ms = sat.medium(geo)
    assert ms.utilisation > 1
    assert ms.queue_drop == pytest.approx(1 - 1 / ms.utilisation)
    assert ms.wait == pytest.approx(4 * n * ms.airtime)
    aloha = RadioChannel(RadioSpec(shadowing_sigma=0.0, access="aloha"), ids, ("usv",) * n, 1, rate=rate)
    assert aloha._leg(0, 1, geo, 0).collision == pytest.approx(1 - math.exp(-(n - 1) * rate * 2 * a))
    causes = {sat.decide(0, 1, s, 0.0, geo).cause for s in range(3000)}
    assert {"queue", "collision"} <= causes


def test_counters_by_cause_and_update_epochs():
    ch = chan(shadowing_sigma=0.0, tx_power=20.0, fading="rician", rician_k=2.0)
    geo = Geometry.of(0, [(0.0, 0.0), (520.0, 0.0)])
    before = [ch.decide(0, 1, s, 1.0, geo) for s in range(500)]
    ch.update(2.0, tx_power_dbm=-10.0)
    after = [ch.decide(0, 1, s, 2.0, geo) for s in range(500, 1000)]
    again = [ch.decide(0, 1, s, 1.0, geo) for s in range(500)]
    assert again == before  # an earlier t_send keeps its epoch
    assert sum(d.delivered for d in after) < sum(d.delivered for d in before)
    assert ch.delivery_probability(0, 1, geo) < ch.delivery_probability(0, 1, geo, t=1.0)
    c = ch.counters
    assert c.sent == 1500 and c.delivered + c.range + c.fading + c.collision + c.queue == 1500
    assert c.range > 0 and c.fading > 0
    assert ch.counters_summary()["links"]["a->b"]["sent"] == 1500
    with pytest.raises(ValueError, match="time order"):
        ch.update(1.0, tx_power_dbm=0.0)
    ch.update(3.0, station=(1.0, 2.0))
    assert ch.epochs[-1] == (3.0, -10.0, (1.0, 2.0, 0.0))
    assert replace(RadioSpec(), tx_power=1.0).tx_power == 1.0


def test_channel_shadowing_follows_the_configured_distance_and_time():
    """Through the channel: one boat moving shadowing_distance decorrelates the link to
    exp(-1); shadowing_time later, to exp(-1) too; the variance is shadowing_sigma²."""
    n, sigma, dist, tau = 1500, 5.0, 40.0, 3.0
    g0 = Geometry.of(0, [(0.0, 0.0), (200.0, 0.0)])
    g_moved = Geometry.of(0, [(0.0, 0.0), (200.0, dist)])
    g_later = Geometry.of(150, [(0.0, 0.0), (200.0, 0.0)])  # 150 ticks x 0.02 s = 3 s
    v = np.empty((n, 3))
    for i in range(n):
        ch = chan(seed=i, shadowing_sigma=sigma, shadowing_distance=dist, shadowing_time=tau, tick_period=0.02)
        for j, g in enumerate((g0, g_moved, g_later)):
            v[i, j] = ch.shadowing(0, 1, ch.antenna(0, g, 0), ch.antenna(1, g, 0), g)
    z = z_bound(3)
    m4 = np.mean((v[:, 0] - v[:, 0].mean()) ** 4)
    assert abs(v[:, 0].var() - sigma ** 2) <= z * math.sqrt((m4 - v[:, 0].var() ** 2) / n)
    for j in (1, 2):
        r = np.corrcoef(v[:, 0], v[:, j])[0, 1]
        assert abs(math.atanh(r) - math.atanh(math.exp(-1.0))) <= z / math.sqrt(n - 3), (j, r)


def test_without_fading_a_reception_loss_is_always_range():
    ch = chan(shadowing_sigma=0.0)
    geo = Geometry.of(0, [(0.0, 0.0), (530.0, 0.0)])
    causes = [ch.decide(0, 1, s, 0.0, geo).cause for s in range(3000)]
    assert "range" in causes and None in causes and "fading" not in causes


@pytest.mark.parametrize("fading, k, m", [("nakagami", 10.0, 0.5), ("nakagami", 10.0, 1.0), ("rician", 0.0, 1.0),
                                          ("rician", 100.0, 1.0), ("nakagami", 10.0, 100.0)])
def test_a_faded_delivery_probability_never_exceeds_one(fading, k, m):
    """With fading the probability is a quadrature over the gains, whose weights sum to 1 within
    rounding: with Nakagami m = 0.5, a link far above the noise (noise_floor -250 dBm) and no
    collisions to speak of (slot 1e-300 s) it was 1.0000000000000002 (the [radio] Hypothesis
    test's 0 <= p <= 1 could fail on it)."""
    ch = chan(fading=fading, rician_k=k, nakagami_m=m, noise_floor=-250.0, shadowing_sigma=0.0, slot=1e-300)
    geo = Geometry.of(0, [(0.0, 0.0), (10.0, 0.0)])
    p = ch.delivery_probability(0, 1, geo)
    assert 0.0 <= p <= 1.0 and ch.decide(0, 1, 0, 0.0, geo).p == p


@pytest.mark.parametrize("at", [math.nan, math.inf, -math.inf])
def test_an_update_at_a_time_that_is_not_finite_is_refused_and_changes_nothing(at):
    """A NaN ``at`` was kept as an epoch start (bisect over a list holding NaN, and every later
    update taken after it whatever its time); +inf refused every later update (InProcessFleet.
    set_radio took both: the world and the agents refuse them before, as non_finite)."""
    ch = chan()
    with pytest.raises(ValueError, match="finite"):
        ch.update(at, tx_power_dbm=5.0)
    assert ch.epochs == ((-math.inf, 20.0, (0.0, 0.0, 0.0)),)
    ch.update(1.0, tx_power_dbm=6.0)
    assert ch.epochs[-1] == (1.0, 6.0, (0.0, 0.0, 0.0))
