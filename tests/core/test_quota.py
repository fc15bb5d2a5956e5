"""The token bucket the world bounds floods with (cdus.core.quota)."""

from __future__ import annotations

import pytest
from hypothesis import given, strategies as st

from cdus.core.quota import Quota


def test_a_burst_then_the_rate_and_what_was_held_is_told_once():
    q = Quota(2.0, 3, now=0.0)
    assert [q.take(0.0) for _ in range(5)] == [True, True, True, False, False]
    assert q.held == 2
    assert q.take(0.5) and q.passed() == 2 and q.passed() == 0  # 0.5 s at 2 a second: one more
    assert not q.take(0.5)
    assert [q.take(100.0) for _ in range(4)] == [True, True, True, False]  # never more than the burst


def test_a_clock_that_goes_back_gives_nothing():
    q = Quota(1.0, 1, now=10.0)
    assert q.take(10.0) and not q.take(5.0) and not q.take(10.5) and q.take(11.0)


@pytest.mark.parametrize("rate, burst", [(0.0, 1), (-1.0, 1), (float("nan"), 1), (1.0, 0)])
def test_a_quota_that_lets_nothing_through_is_refused(rate, burst):
    with pytest.raises(ValueError):
        Quota(rate, burst)


@given(st.floats(0.1, 100.0), st.integers(1, 50), st.lists(st.floats(0.0, 5.0), max_size=300))
def test_never_more_than_the_burst_plus_the_rate_over_the_time_elapsed(rate, burst, gaps):
    q, now, passed = Quota(rate, burst, now=0.0), 0.0, 0
    for gap in gaps:
        now += gap
        passed += q.take(now)
    assert passed <= burst + rate * now + 1e-9
    assert passed <= len(gaps)


def test_a_new_quota_starts_at_time_zero_and_a_bad_one_says_why():
    """mutmut on quota.py: the default start time and the refusal's words were untested."""
    q = Quota(rate=1.0, burst=1)
    assert q.take(0.0) and not q.take(0.5) and q.take(1.0)  # refilled one second after t = 0
    with pytest.raises(ValueError, match=r"a quota needs rate > 0 and burst >= 1, got rate = 0, burst = 1"):
        Quota(rate=0, burst=1)
