"""cdus.app.stats to the digit: the bootstrap interval against a reference computation, and
the formatting of the summary's numbers (cases mutation testing found unchecked)."""

import numpy as np
import pytest

from cdus.app.stats import LEVEL, RESAMPLES, SEED, Stat, bootstrap_ci, describe, fmt_duration, fmt_number, \
    fmt_seconds, fmt_stat


def reference_ci(x, level=LEVEL, seed=SEED):
    x = np.asarray(x, dtype=float)
    idx = np.random.default_rng(seed).integers(0, x.size, size=(RESAMPLES, x.size))
    means = x[idx].mean(axis=1)
    return tuple(float(v) for v in np.quantile(means, [(1 - level) / 2, (1 + level) / 2]))


@pytest.mark.parametrize("x", [[1.0, 2.0, 4.0, 8.0], [0.5, 0.7], [3.0, 3.0, 9.0, 1.0, 2.0, 40.0]])
def test_the_interval_is_the_percentile_bootstrap_of_the_mean(x):
    assert bootstrap_ci(x) == reference_ci(x)
    assert bootstrap_ci(x, level=0.5) == reference_ci(x, level=0.5)
    lo, hi = bootstrap_ci(x)
    assert lo < hi  # two or more distinct values: an interval, not a point


def test_the_level_is_strictly_between_0_and_1():
    for level in (0.0, 1.0, -0.1):
        with pytest.raises(ValueError, match=r"level must be in \(0, 1\)"):
            bootstrap_ci([1.0, 2.0], level=level)


def test_describe_uses_its_seed_and_the_sample_deviation():
    x = [1.0, 2.0, 4.0, 8.0, 3.5, 0.25, 11.0]  # enough values that two seeds give two intervals
    s = describe(x, seed=5)
    assert (s.lo, s.hi) == reference_ci(x, seed=5) != reference_ci(x)
    assert describe([1.0, 3.0]).std == pytest.approx(2 ** 0.5)
    assert describe([2.0]).std is None


def test_numbers_as_the_summary_prints_them():
    assert fmt_number(3.14159) == "3.1"
    assert fmt_number(0.095, 2) == "0.095" and fmt_number(0.1, 2) == "0.10"
    assert fmt_seconds(1.234, 2) == "1.23 s" and fmt_seconds(None) == "never"
    assert fmt_stat(Stat(1, 3.14159, None, 3.14159, 3.14159)) == "3.1"
    assert fmt_stat(Stat(3, 1.234, 0.5678, 1.0, 1.5), digits=2) == "1.23 ± 0.57 [1.00, 1.50]"
    assert fmt_stat(Stat(0, None, None, None, None), never=2) == "never"
    assert fmt_stat(Stat(2, 2.0, 1.0, 1.5, 2.5)) == "2.0 ± 1.0 [1.5, 2.5]"  # two values have an interval
    assert fmt_duration(0.5) == "0.5 s" and fmt_duration(-3) == "0.0 s"
    assert fmt_duration(60) == "1 min 0 s" and fmt_duration(125.9) == "2 min 5 s"
    assert fmt_duration(3600) == "1 h 00 min" and fmt_duration(7265) == "2 h 01 min"
    assert fmt_duration(7140) == "1 h 59 min"
