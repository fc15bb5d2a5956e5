"""cdus.wire.stats: the optional fields a stats report gained with [[obstacle]], plant = "ros2"
and the world's end of run (``deflected``, ``odometry_gaps``, ``final``): an older report without them still decodes, and every
odometry_gaps field decodes exactly when an independent reading of its rules accepts it."""

from __future__ import annotations

import math

import msgpack
import pytest
from hypothesis import given, settings, strategies as st

from cdus.wire.schemas import (MAX_ODOMETRY_GAPS, MAX_TIME, SCHEMA_VERSION, AgentStats, OdometryGap, Rejected,
                               decode_stats, encode_stats)


def _report(**extra) -> bytes:
    return msgpack.packb({"v": SCHEMA_VERSION, "id": "usv1", "tick": 1, **extra})


def test_a_report_without_the_new_fields_decodes_with_none_of_them():
    s = decode_stats(_report())
    assert s == AgentStats(id="usv1", tick=1) and s.odometry_gaps == () and s.deflected == 0 and s.final is False


def test_final_round_trips_and_is_a_bool():
    assert decode_stats(encode_stats(AgentStats(id="usv1", tick=1, final=True))).final is True
    assert decode_stats(encode_stats(AgentStats(id="usv1", tick=1))).final is False
    for bad in (1, 0, "true", None, 1.0):
        assert decode_stats(_report(final=bad)) == Rejected("type"), bad


def test_deflected_round_trips_and_is_an_int_within_bounds():
    assert decode_stats(encode_stats(AgentStats(id="usv1", tick=1, interventions=9, deflected=7))).deflected == 7
    for bad in (-1, 1.5, True, "3"):
        assert decode_stats(_report(deflected=bad)) == Rejected("type")


def test_an_open_spell_is_packed_without_back():
    assert OdometryGap(1.5).as_dict() == {"t": 1.5}
    assert OdometryGap(1.5, 2.0).as_dict() == {"t": 1.5, "back": 2.0}
    assert msgpack.unpackb(encode_stats(AgentStats(id="usv1", tick=1, odometry_gaps=(OdometryGap(0.5),))))["odometry_gaps"] \
        == [{"t": 0.5}]


def _number(x) -> bool:
    return type(x) in (int, float) and math.isfinite(x)


def _reference(x):
    """The rules of docs (cdus.wire.stats._odometry_gaps) written again: a list of at most
    MAX_ODOMETRY_GAPS maps with "t" and maybe "back", 0 <= t <= back <= MAX_TIME, each spell
    beginning at or after the previous one came back (so only the newest may be open)."""
    if type(x) is not list or len(x) > MAX_ODOMETRY_GAPS:
        return None
    out = []
    for d in x:
        if type(d) is not dict or set(d) - {"t", "back"} or "t" not in d:
            return None
        t, back = d["t"], d.get("back")
        if not _number(t) or t < 0 or t > MAX_TIME:
            return None
        if back is not None and (not _number(back) or back < t or back > MAX_TIME):
            return None
        if out and (out[-1][1] is None or t < out[-1][1]):
            return None
        out.append((float(t), None if back is None else float(back)))
    return tuple(OdometryGap(t, b) for t, b in out)


# near the boundaries: small times so order, overlap and back < t all happen; a key too many or
# missing; the length limit's both sides
_time = st.integers(-1, 6) | st.sampled_from([0.5, MAX_TIME, MAX_TIME + 1, math.nan, math.inf, True, "1"])
_gap = st.fixed_dictionaries({}, optional={"t": _time, "back": _time | st.none(), "x": st.just(1)})


@settings(max_examples=400, deadline=None)
@given(gaps=st.lists(_gap, max_size=MAX_ODOMETRY_GAPS + 1) | st.sampled_from(["", {}, None, 3, "ab", {"t": 1}]))
def test_odometry_gaps_decode_exactly_when_the_reference_accepts_them(gaps):
    want = _reference(gaps)
    got = decode_stats(_report(odometry_gaps=gaps))
    if want is None:
        assert got == Rejected("odometry_gaps")
    else:
        assert got.odometry_gaps == want


@pytest.mark.parametrize("n", [MAX_ODOMETRY_GAPS, MAX_ODOMETRY_GAPS + 1])
def test_the_gap_count_limit(n):
    gaps = [{"t": float(i), "back": i + 0.5} for i in range(n)]
    got = decode_stats(_report(odometry_gaps=gaps))
    assert (got == Rejected("odometry_gaps")) == (n > MAX_ODOMETRY_GAPS)


@pytest.mark.parametrize("gaps, ok", [
    ([{"t": 1.0, "back": 2.0}, {"t": 2.0}], True),  # begins the tick the last one came back
    ([{"t": 1.0, "back": 2.0}, {"t": 1.5}], False),  # overlaps it
    ([{"t": 1.0}, {"t": 2.0}], False),  # only the newest may be open
    ([{"t": 0, "back": 0}], True),  # a spell at the very start, ended at once
    ([{"t": 2.0, "back": 1.0}], False),  # back before it began
])
def test_spells_in_order_without_overlap(gaps, ok):
    got = decode_stats(_report(odometry_gaps=gaps))
    assert (got != Rejected("odometry_gaps")) == ok
