"""The one finite-number predicate and the table of bounds (cdus/wire/bounds.py)."""

from __future__ import annotations

import math
import re
import sys
from pathlib import Path

import pytest
from hypothesis import given, strategies as st

from cdus.wire.bounds import BOUNDS, MAX_FLOAT, Bound, finite, is_number, nonnegative, positive, within

ROOT = Path(__file__).resolve().parents[2]
ANY = st.one_of(st.none(), st.booleans(), st.integers(), st.integers(-10**400, 10**400), st.floats(allow_nan=True, allow_infinity=True),
                st.text(max_size=3), st.lists(st.integers(), max_size=2))


@given(ANY)
def test_finite_is_a_real_number_that_is_not_a_bool_nan_or_inf(x):
    expected = (type(x) in (int, float) and x == x and x not in (math.inf, -math.inf)
                and (type(x) is float or abs(x) <= sys.float_info.max))
    assert finite(x) is expected
    assert is_number(x) is (expected or type(x) is float)


def test_is_number_says_a_number_finite_or_not_and_an_int_too_large_for_a_float_is_neither():
    """finite(10**400) raised OverflowError (math.isfinite converts it): a JSON scenario's huge
    int crashed a check instead of being refused."""
    assert is_number(math.nan) and is_number(-math.inf) and is_number(3) and not is_number(True)
    assert not finite(10**400) and not is_number(-10**400) and finite(10**308)
    assert not BOUNDS["gains.k"].holds(10**400)


@pytest.mark.parametrize("x, ok", [(0, True), (-0.0, True), (1e308, True), (5e-324, True), (2**80, True), (10**400, False), (-10**400, False), (int(MAX_FLOAT), True),
                                   (True, False), (False, False), (math.nan, False), (math.inf, False),
                                   (-math.inf, False), ("1", False), (None, False), ([1.0], False)])
def test_finite_cases(x, ok):
    assert finite(x) is ok


@given(st.floats(-10, 10), st.floats(-10, 10), st.booleans(), st.booleans(), ANY)
def test_a_bound_holds_exactly_the_finite_numbers_between_its_ends(lo, hi, lo_open, hi_open, x):
    b = Bound(lo, hi, lo_open=lo_open, hi_open=hi_open)
    inside = finite(x) and (x > lo if lo_open else x >= lo) and (x < hi if hi_open else x <= hi)
    assert b.holds(x) is inside
    assert (b.problem(x) is None) is inside


def test_the_ends_are_in_or_out_as_written():
    assert Bound(0, 1).holds(0) and Bound(0, 1).holds(1) and Bound(0, 1).holds(0.5)
    assert not Bound(0, 1, lo_open=True).holds(0) and Bound(0, 1, lo_open=True).holds(1e-300)
    assert not Bound(0, 1, hi_open=True).holds(1) and Bound(0, 1, hi_open=True).holds(0.9999999999999999)
    assert not Bound(0, 1).holds(-1e-300) and not Bound(0, 1).holds(1.0000000000000002)


def test_inf_is_a_value_only_where_the_bound_says_and_only_plus_inf():
    until_the_end = Bound(0.0, 1e9, lo_open=True, inf_ok=True)
    assert until_the_end.holds(math.inf) and until_the_end.holds(1e9) and not until_the_end.holds(2e9)
    assert not until_the_end.holds(-math.inf) and not until_the_end.holds(math.nan)
    assert not until_the_end.holds(True) and not until_the_end.holds(0)
    assert not Bound(0.0, 1e9).holds(math.inf)


def test_the_range_and_the_refusal_in_words():
    assert Bound(0.0, 3600.0).text() == ">= 0 and <= 3600"
    assert Bound(0.0, 1e6, lo_open=True, hi_open=True).text() == "> 0 and < 1e+06"
    assert Bound(-math.inf, 1e9).text() == "<= 1e+09" and Bound(0.0, math.inf, lo_open=True).text() == "> 0"
    assert Bound().text() == ""
    assert BOUNDS["link.delay.base"].problem(1e308, " s") == \
        "must be a finite number >= 0 and <= 3600 s, got 1e+308"
    assert BOUNDS["link.window.to"].problem(-1.0) == "must be a number > 0 and <= 1e+09, got -1"
    assert BOUNDS["path.radius"].problem(True) == "must be a finite number > 0 and <= 1e+06, got True"
    assert BOUNDS["path.radius"].problem("x") == "must be a finite number > 0 and <= 1e+06, got 'x'"
    assert BOUNDS["event.at"].problem(7) is None
    assert BOUNDS["event.at"].problem(10**20) == "must be a finite number >= 0 and <= 1e+09, got 100000000000000000000"
    assert BOUNDS["event.at"].problem(None) == "must be a finite number >= 0 and <= 1e+09, got None"


def test_the_shorthands():
    assert within(5.0) == Bound(-5.0, 5.0) and nonnegative(2.0) == Bound(0.0, 2.0)
    assert positive(3.0) == Bound(0.0, 3.0, lo_open=True) and positive(3.0, hi_open=True).hi_open


@pytest.mark.parametrize("field", sorted(BOUNDS))
def test_every_bound_is_an_interval_with_finite_numbers_in_it(field):
    b = BOUNDS[field]
    assert b.lo < b.hi and not math.isnan(b.lo) and not math.isnan(b.hi)
    middle = (b.lo + b.hi) / 2 if math.isfinite(b.lo + b.hi) else b.lo + 1 if math.isfinite(b.lo) else b.hi - 1
    inside = [x for x in (b.lo, b.hi, middle) if b.holds(x)]
    assert inside, field
    for x in (math.nan, -math.inf, True):
        assert not b.holds(x), (field, x)
    assert not b.holds(1e308) or b.hi == math.inf, field  # huge is out wherever there is a top


def test_the_documented_table_is_the_table():
    """docs/config.md, "Bounds of the numbers", lists every field of BOUNDS with its range."""
    text = (ROOT / "docs" / "config.md").read_text()
    section = text.split("### Bounds of the numbers", 1)[1].split("\n### ", 1)[0]
    rows = dict(re.findall(r"^\| `([a-z_.0-9]+)` \| ([^|]+) \|", section, re.M))
    assert set(rows) == set(BOUNDS), set(rows) ^ set(BOUNDS)
    for field, b in BOUNDS.items():
        text = b.text() or "any"
        assert rows[field].strip().startswith(text), (field, rows[field], text)


def test_an_integer_beyond_a_float_is_refused_in_words_not_by_overflow():
    # math.isfinite(10**400) raises OverflowError: `cdus sim --set gains.k=1000...0` and `cdus gs
    # gains k=1000...0` were tracebacks
    assert BOUNDS["gains.k"].problem(10**400) == "must be a finite number > 0, got an integer beyond a float's range"
    assert positive(1.0).problem("x" * 100).endswith("...")
