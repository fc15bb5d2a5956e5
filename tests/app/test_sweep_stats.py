import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cdus.app.stats import bootstrap_ci, describe, fmt_duration, fmt_number, fmt_seconds, fmt_stat


@pytest.mark.parametrize("dist", ["normal", "exponential", "uniform"])
def test_the_interval_contains_the_sample_mean(dist):
    for seed in range(20):
        rng = np.random.default_rng(100 + seed)
        n = int(rng.integers(3, 60))
        x = getattr(rng, dist)(size=n)
        lo, hi = bootstrap_ci(x, seed=seed)
        assert lo < x.mean() < hi


def test_the_interval_shrinks_with_more_samples():
    rng = np.random.default_rng(7)
    x = rng.normal(10.0, 2.0, size=1000)
    widths = []
    for n in (10, 100, 1000):
        lo, hi = bootstrap_ci(x[:n])
        widths.append(hi - lo)
    assert widths[0] > widths[1] > widths[2] > 0
    # about 2 x 1.96 sigma / sqrt(n): 0.25 for n = 1000
    assert 0.18 < widths[2] < 0.32


def test_the_interval_is_deterministic_per_seed():
    x = np.random.default_rng(3).exponential(size=25)
    assert bootstrap_ci(x, seed=5) == bootstrap_ci(x, seed=5)
    assert bootstrap_ci(x, seed=5) != bootstrap_ci(x, seed=6)
    assert bootstrap_ci(list(x)) == bootstrap_ci(tuple(x))


def test_a_wider_level_gives_a_wider_interval():
    x = np.random.default_rng(4).normal(size=30)
    lo90, hi90 = bootstrap_ci(x, level=0.90)
    lo99, hi99 = bootstrap_ci(x, level=0.99)
    assert lo99 < lo90 and hi90 < hi99
    with pytest.raises(ValueError):
        bootstrap_ci(x, level=1.0)


def test_degenerate_samples():
    assert bootstrap_ci([]) is None
    assert bootstrap_ci([4.2]) == (4.2, 4.2)
    assert bootstrap_ci([3.0, 3.0, 3.0]) == (3.0, 3.0)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(min_value=-1e6, max_value=1e6), min_size=1, max_size=40))
def test_the_interval_lies_within_the_values(xs):
    lo, hi = bootstrap_ci(xs)
    tol = 1e-9 * max(1.0, max(abs(v) for v in xs))
    assert min(xs) - tol <= lo <= hi <= max(xs) + tol


def test_describe_skips_missing_and_non_finite_values():
    s = describe([1.0, None, 3.0, float("nan"), float("inf"), 2.0])
    assert (s.n, s.mean, s.std) == (3, 2.0, 1.0)
    assert s.lo <= 2.0 <= s.hi
    one = describe([5.0])
    assert (one.n, one.mean, one.std, one.lo, one.hi) == (1, 5.0, None, 5.0, 5.0)
    assert describe([None, float("nan")]).n == 0


def test_numbers_are_rounded_for_people():
    assert fmt_seconds(141.42000000000002) == "141.4 s"
    assert fmt_seconds(None) == "never"
    assert fmt_seconds(0.04) == "0.04 s"
    assert fmt_number(None) == "n/a" and fmt_number(float("nan")) == "n/a"
    assert fmt_number(0.02571, 4) == "0.0257"
    assert fmt_number(0.000236, 4) == "0.000236"
    assert fmt_number(0.0, 3) == "0.000"
    assert fmt_duration(45.34) == "45.3 s" and fmt_duration(75.3) == "1 min 15 s" and fmt_duration(725) == "12 min 5 s"
    assert fmt_duration(3 * 3600 + 125) == "3 h 02 min"


def test_a_stat_reads_mean_sd_and_interval():
    s = describe([10.0, 12.0, 11.0])
    text = fmt_stat(s, 1)
    assert text.startswith("11.0 ± 1.0 [") and text.endswith("]")
    lo, hi = (float(v) for v in text.split("[")[1].rstrip("]").split(", "))
    assert lo <= 11.0 <= hi
    assert fmt_stat(s, 1, never=2).endswith("(2 never)")
    assert fmt_stat(describe([]), 1, never=3) == "never"
    assert fmt_stat(describe([]), 1) == "-"
    assert fmt_stat(describe([7.25]), 1) == "7.2"
    assert not any(math.isnan(v) for v in (s.mean, s.std, s.lo, s.hi))
