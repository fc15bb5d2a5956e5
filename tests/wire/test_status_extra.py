"""The world status's optional console fields (cdus.wire.schemas.STATUS_EXTRA): they round-trip,
a status without them is still valid, and every malformed one is rejected as ``extra``."""

from __future__ import annotations

import math

import msgpack
import pytest
from hypothesis import given, settings, strategies as hs

from cdus.wire.schemas import STATUS_EXTRA, StatusExtra, decode_status, encode_status
from cdus.wire.rejected import Rejected
from cdus.wire.status import WorldStatus

IDS = ["usv1", "usv2", "uav1"]


def extra(**over) -> StatusExtra:
    d = dict(kinds=["usv", "usv", "uav"], states=["live", "gone", "paused"],
             edges=[("usv1", "usv2", None), ("usv1", "uav1", 0.25)],
             links=[("usv1", "usv2", 100, 7, "lossy"), ("usv2", "usv1", 90, 0, None)],
             rx=[(100, 7), None, (50, 0)], safety_radius=2.0, closest=("usv1", "usv2", 1.5),
             path_errors=[0.1, None, 0.3], directed=False, completion="completed")
    d.update(over)
    return StatusExtra(**d)


def present(st: WorldStatus) -> set[str]:
    """The optional fields a decoded status carries (the others are None)."""
    return {k for k in STATUS_EXTRA if getattr(st, k) is not None}


def status(ex: StatusExtra | None) -> bytes:
    return encode_status(3.0, 100.0, "lockstep", ["usv1", "uav1"], IDS, 0.3, 0.25, [], False, extra=ex)


def test_the_console_fields_round_trip():
    st = decode_status(status(extra()))
    assert present(st) == set(STATUS_EXTRA)
    assert st.kinds == ["usv", "usv", "uav"] and st.states == ["live", "gone", "paused"]
    assert st.edges == [("usv1", "usv2", None), ("usv1", "uav1", 0.25)]
    assert st.links == [("usv1", "usv2", 100, 7, "lossy"), ("usv2", "usv1", 90, 0, None)]
    assert st.rx == [(100, 7), None, (50, 0)]
    assert st.safety_radius == 2.0 and st.closest == ("usv1", "usv2", 1.5)
    assert st.path_errors == [0.1, None, 0.3] and st.directed is False
    assert st.completion == "completed"


def test_a_status_without_them_is_still_valid_and_non_finite_values_are_left_out():
    assert present(decode_status(status(None))) == set()
    st = decode_status(status(extra(safety_radius=math.nan, closest=("usv1", "usv2", math.inf),
                                    edges=[("usv1", "usv2", math.nan)], path_errors=[math.inf, 0.0, None])))
    assert st.safety_radius is None and st.closest is None
    assert st.edges == [("usv1", "usv2", None)] and st.path_errors == [None, 0.0, None]


@pytest.mark.parametrize("field, value", [
    ("kinds", ["usv", "usv"]),  # not one per id
    ("kinds", ["usv", "boat", "uav"]),
    ("states", ["live", "dead", "live"]),
    ("edges", [["usv1", "nobody", 0.1]]),
    ("edges", [["usv1", "usv1", 0.1]]),
    ("edges", [["usv1", "usv2", -1.0]]),
    ("edges", [["usv1", "usv2"]]),
    ("edges", "usv1-usv2"),
    ("links", [["usv1", "usv2", 5, 6, None]]),  # more dropped than sent
    ("links", [["usv1", "usv2", 5, 1, "flaky"]]),
    ("links", [["usv1", "usv2", -5, 0, None]]),
    ("links", [["usv1", "usv2", 5.0, 0, None]]),
    ("rx", [[1, 0], [1, 2], None]),
    ("rx", [[1, 0]]),
    ("safety_radius", 0.0),
    ("safety_radius", "2"),
    ("closest", ["usv1", "x", 1.0]),
    ("closest", ["usv1", "usv2", -1.0]),
    ("path_errors", [0.1, -0.1, None]),
    ("path_errors", [0.1]),
    ("directed", 1),
    ("completion", "done"),  # not one of COMPLETIONS
    ("completion", None),
    ("completion", ["completed"]),
])
def test_a_malformed_console_field_is_rejected(field, value):
    d = msgpack.unpackb(status(extra()), raw=False)
    d[field] = value
    assert decode_status(msgpack.packb(d)) == Rejected("extra")


def test_too_many_edges_or_links_are_rejected():
    d = msgpack.unpackb(status(extra()), raw=False)
    assert decode_status(msgpack.packb({**d, "edges": [["usv1", "usv2", 0.1]] * 513})) == Rejected("extra")
    assert decode_status(msgpack.packb({**d, "links": [["usv1", "usv2", 1, 0, None]] * 513})) == Rejected("extra")
    # the world sends at most as many as the decoder takes
    many = extra(edges=[("usv1", "usv2", 0.1)] * 600, links=[("usv1", "usv2", 1, 0, None)] * 600)
    st = decode_status(status(many))
    assert len(st.edges) == 512 and len(st.links) == 512


def test_a_status_too_big_for_the_console_fields_still_says_the_run_is_over():
    ids = [f"v{j}" for j in range(3000)]  # the summary alone fits, the console fields do not
    ex = StatusExtra(kinds=["usv"] * len(ids), path_errors=[0.1] * len(ids), completion="stopped")
    st = decode_status(encode_status(3.0, 100.0, "lockstep", ids, ids, 0.3, 0.25, [], False, extra=ex))
    assert isinstance(st, WorldStatus) and st.completion == "stopped" and st.kinds is None


_values = hs.recursive(hs.one_of(hs.none(), hs.booleans(), hs.integers(-2**63, 2**64 - 1), hs.floats(),
                                 hs.sampled_from(IDS + ["usv", "uav", "live", "gone", "lossy", "x"])),
                       lambda inner: hs.lists(inner, max_size=4), max_leaves=20)


@settings(max_examples=300, deadline=None)
@given(hs.dictionaries(hs.sampled_from(STATUS_EXTRA), _values, max_size=len(STATUS_EXTRA)))
def test_any_console_fields_decode_or_are_rejected_never_raise(fields):
    d = msgpack.unpackb(status(None), raw=False)
    out = decode_status(msgpack.packb({**d, **fields}))
    assert out == Rejected("extra") or isinstance(out, WorldStatus) and present(out) == set(fields)
    if isinstance(out, WorldStatus):  # what ground_station.alarms and tui take as it is, without a check
        n, ids = len(out.ids), set(out.ids)
        assert all(x is None or len(x) == n for x in (out.kinds, out.states, out.rx, out.path_errors))
        assert all(a in ids and b in ids and (e is None or math.isfinite(e) and e >= 0) for a, b, e in out.edges or [])
        assert out.closest is None or out.closest[0] in ids and out.closest[1] in ids and math.isfinite(out.closest[2])
        assert out.safety_radius is None or math.isfinite(out.safety_radius) and out.safety_radius > 0
        assert all(e is None or math.isfinite(e) for e in out.path_errors or [])


def test_a_fleet_of_thousands_still_gets_its_status_with_what_fits():
    def big(n: int) -> dict:
        ids = [f"vehicle{j:05d}" for j in range(n)]
        ex = StatusExtra(kinds=["usv"] * n, states=["live"] * n,
                         edges=[(ids[j], ids[j + 1], 0.123456789) for j in range(min(n - 1, 512))],
                         links=[(ids[j], ids[j + 1], 10**9, 10**6, "lossy") for j in range(min(n - 1, 512))],
                         rx=[(10**9, 10**6)] * n, safety_radius=2.0, closest=(ids[0], ids[1], 1.0),
                         path_errors=[0.123456789] * n, directed=False)
        payload = encode_status(3.0, 100.0, "lockstep", ids, ids, 0.3, 0.25, [], False, extra=ex)
        assert len(payload) <= 1 << 16
        st = decode_status(payload)
        assert isinstance(st, WorldStatus), st
        return st

    assert {"edges", "links", "kinds"} <= present(big(300))  # everything fits
    st = big(800)  # the edges and links do not: left out, the rest kept
    assert st.edges is None and st.links is None and len(st.states) == 800
    st = big(2000)  # only the summary fits (ids and alive take most of it)
    assert present(st) == set() and len(st.ids) == 2000


@pytest.mark.parametrize("field, value", [
    ("edges", [["nobody", "usv2", 0.1]]),  # the first end is checked as the second
    ("links", [["nobody", "usv2", 5, 1, None]]),
    ("links", [["usv1", "usv2", 5, 1, None], ["usv2", "usv2", 5, 1, None]]),
    ("rx", [[-1, 0], None, None]),
    ("rx", [[1.5, 0], None, None]),  # the first count is checked as the second
    ("closest", ["nobody", "usv2", 1.0]),
    ("closest", ["usv1", "usv1", 1.0]),
])
def test_each_end_of_an_edge_link_or_pair_is_checked(field, value):
    d = msgpack.unpackb(status(extra()), raw=False)
    d[field] = value
    assert decode_status(msgpack.packb(d)) == Rejected("extra")


def test_the_console_fields_at_their_bounds_are_kept():
    """The edges of what the decoder takes: an edge error and a distance of 0 (settled, touching),
    as many dropped as sent, a radius below 1 m, times at MAX_TIME."""
    from cdus.wire.schemas import MAX_TIME

    d = msgpack.unpackb(status(extra()), raw=False)
    d.update(edges=[["usv1", "usv2", 0.0]], links=[["usv1", "usv2", 5, 5, None]], rx=[[3, 3], None, None],
             safety_radius=0.5, closest=["usv1", "usv2", 0.0])
    st = decode_status(msgpack.packb(d))
    assert st.edges == [("usv1", "usv2", 0.0)] and st.links == [("usv1", "usv2", 5, 5, None)]
    assert st.rx[0] == (3, 3) and st.safety_radius == 0.5 and st.closest == ("usv1", "usv2", 0.0)
    d.update(safety_radius=MAX_TIME, closest=["usv1", "usv2", 0.5])
    st = decode_status(msgpack.packb(d))
    assert st.safety_radius == MAX_TIME and st.closest[2] == 0.5
    d.update(closest=["usv1", "usv2", MAX_TIME])
    assert decode_status(msgpack.packb(d)).closest[2] == MAX_TIME
