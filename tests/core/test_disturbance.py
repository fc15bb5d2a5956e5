"""The seeded, bounded velocity disturbance."""

import math
import statistics

import pytest

from cdus.core.disturbance import Disturbance, DisturbanceSpec


def _run(dist, n, h=0.1):
    return [dist.step(h) for _ in range(n)]


def test_no_spec_is_zero_and_inactive():
    d = Disturbance(None, 3, seed=1, vehicle_id="uav0")
    assert not d.active
    assert d.value == (0.0, 0.0, 0.0)
    assert all(v == (0.0, 0.0, 0.0) for v in _run(d, 50))


def test_zero_spec_is_zero():
    d = Disturbance(DisturbanceSpec((0.0, 0.0)), 2, seed=1, vehicle_id="usv0")
    assert d.active
    assert all(v == (0.0, 0.0) for v in _run(d, 50))


def test_constant_without_gust():
    d = Disturbance(DisturbanceSpec((0.3, -0.1)), 2, seed=1, vehicle_id="usv0")
    assert d.value == (0.3, -0.1)
    assert all(v == (0.3, -0.1) for v in _run(d, 50))


def test_gust_is_bounded_by_three_std_around_the_constant():
    spec = DisturbanceSpec((1.0, -2.0, 0.0), gust=0.5, gust_tau=0.2)
    d = Disturbance(spec, 3, seed=11, vehicle_id="uav1")
    values = _run(d, 20000, h=0.5)  # h >> τ: nearly white, so the tails are sampled
    for v in values:
        for x, c in zip(v, spec.constant):
            assert abs(x - c) <= 3 * 0.5 + 1e-12
    # the clip is reached (so the bound is the clip, not luck)
    assert max(abs(v[0] - 1.0) for v in values) == pytest.approx(1.5)


def test_seeded_reproducibility():
    spec = DisturbanceSpec((0.0, 0.0), gust=0.4, gust_tau=2.0)
    a = _run(Disturbance(spec, 2, seed=42, vehicle_id="usv0"), 300)
    b = _run(Disturbance(spec, 2, seed=42, vehicle_id="usv0"), 300)
    other_id = _run(Disturbance(spec, 2, seed=42, vehicle_id="usv1"), 300)
    other_seed = _run(Disturbance(spec, 2, seed=43, vehicle_id="usv0"), 300)
    assert a == b
    assert a != other_id
    assert a != other_seed
    assert any(v != (0.0, 0.0) for v in a)


def test_axes_are_independent():
    spec = DisturbanceSpec((0.0, 0.0), gust=1.0, gust_tau=1.0)
    values = _run(Disturbance(spec, 2, seed=5, vehicle_id="usv0"), 20000, h=0.5)
    x = [v[0] for v in values]
    y = [v[1] for v in values]
    assert abs(statistics.correlation(x, y)) < 0.05


@pytest.mark.parametrize("gust, tau", [(0.3, 2.0), (1.0, 0.5)])
def test_long_run_std_matches_gust(gust, tau):
    """Ornstein-Uhlenbeck with stationary std ``gust``: over 1000 correlation times the
    empirical std is within 20% (the ±3σ clip takes off about 1%)."""
    spec = DisturbanceSpec((0.2, 0.0), gust=gust, gust_tau=tau)
    h = 0.1
    n = int(round(1000 * tau / h))
    values = _run(Disturbance(spec, 2, seed=2024, vehicle_id="usv3"), n, h=h)
    for axis, c in ((0, 0.2), (1, 0.0)):
        xs = [v[axis] for v in values]
        assert statistics.pstdev(xs) == pytest.approx(gust, rel=0.20)
        assert statistics.fmean(xs) == pytest.approx(c, abs=0.2 * gust)


def test_gust_is_correlated_over_its_time_constant():
    """Lag-one autocorrelation of an OU sampled at h is exp(-h/τ)."""
    spec = DisturbanceSpec((0.0,), gust=1.0, gust_tau=2.0)
    h = 0.1
    xs = [v[0] for v in _run(Disturbance(spec, 1, seed=9, vehicle_id="x"), 40000, h=h)]
    rho = statistics.correlation(xs[:-1], xs[1:])
    assert rho == pytest.approx(math.exp(-h / 2.0), abs=0.01)
