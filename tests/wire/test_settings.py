"""The world's settings in force (``world/settings``, cdus.wire.schemas.encode_settings /
decode_settings): they round-trip, every command in them is decoded as a vehicle decodes it,
and any payload decodes to plain JSON-able values or is refused with a reason, never raises."""

from __future__ import annotations

import json
import math

import msgpack
from hypothesis import given, settings, strategies as hs

from cdus.wire.messages import encode_control
from cdus.wire.schemas import MAX_SETTINGS_CHANGES, decode_settings, encode_settings
from cdus.wire.rejected import Rejected

IDS = ["usv1", "usv2", "uav1"]
PHASES = [("usv1", 0.0), ("usv2", 3.14), ("uav1", 1.0)]


def test_the_settings_round_trip_as_plain_values():
    changes = [("usv1", encode_control("gains", gains={"k": 2.0}, tick=131, seq=0)),
               (None, encode_control("link", link={"loss": 0.1}, at=4.1, seq=1)),
               (None, encode_control("formation", phases={"usv2": 3.14}, tick=256, seq=2))]
    got = decode_settings(encode_settings(changes, PHASES, {"loss": 0.1}), IDS)
    assert got["changes"] == [
        {"seq": 0, "op": "gains", "vehicle": "usv1", "fields": {"gains": {"k": 2.0}, "tick": 131}},
        {"seq": 1, "op": "link", "vehicle": None, "fields": {"link": {"loss": 0.1}, "at": 4.1}},
        {"seq": 2, "op": "formation", "vehicle": None, "fields": {"phases": {"usv2": 3.14}, "tick": 256}}]
    assert got["phases"] == dict(PHASES) and got["link"] == {"loss": 0.1}
    assert (got["total"], got["unreadable"]) == (3, 0)


def test_a_change_that_does_not_decode_is_left_out_and_counted():
    changes = [(None, b"\xc1"), ("nobody", encode_control("gains", gains={"k": 2.0}, tick=1, seq=0)),
               (None, encode_control("grant", until=5)),  # not a run-time change
               (None, encode_control("gains", gains={"k": 2.0}, tick=1, seq=-1)),
               (None, encode_control("gains", gains={"k": 2.0}, tick=1, seq=4))]
    got = decode_settings(encode_settings(changes, PHASES, {}), IDS)
    assert [c["seq"] for c in got["changes"]] == [4] and got["unreadable"] == 4


def test_only_the_newest_changes_are_sent_and_the_total_says_how_many_there_were():
    changes = [(None, encode_control("gains", gains={"c": 1.0}, tick=j, seq=j)) for j in range(MAX_SETTINGS_CHANGES + 5)]
    got = decode_settings(encode_settings(changes, PHASES, {}), IDS)
    assert got["total"] == MAX_SETTINGS_CHANGES + 5 and len(got["changes"]) == MAX_SETTINGS_CHANGES
    assert got["changes"][0]["seq"] == 5


def test_values_json_cannot_hold_are_made_plain_and_bad_fields_refused():
    link = {"loss": math.nan, "delay": {"base": math.inf, "deep": {"a": {"b": {"c": {"d": {"e": {"f": 1}}}}}}},
            "big": 2**64 - 1, "name": "\x1b[31mred"}
    got = decode_settings(encode_settings([], PHASES, link), IDS)
    json.dumps(got, allow_nan=False)
    assert got["link"]["loss"] is None and got["link"]["delay"]["base"] is None and got["link"]["big"] is None
    assert "\x1b" not in got["link"]["name"]
    base = msgpack.unpackb(encode_settings([], PHASES, {}), raw=False)
    for field, value, reason in [("v", 2, "version"), ("phases", [["usv1", math.nan]], "phases"),
                                 ("phases", [["nobody", 1.0]], "phases"), ("phases", {"usv1": 1.0}, "type"),
                                 ("link", [], "type"), ("total", -1, "type"), ("changes", None, "type")]:
        assert decode_settings(msgpack.packb({**base, field: value}, use_bin_type=True), IDS) == Rejected(reason), field
    assert decode_settings(b"\xc1") == Rejected("malformed") and decode_settings(msgpack.packb([1])) == Rejected("malformed")
    assert decode_settings(b"\x00" * (1 << 22 + 1)) == Rejected("oversized")


_leaf = hs.one_of(hs.none(), hs.booleans(), hs.integers(-2**63, 2**64 - 1), hs.floats(), hs.text(max_size=8),
                  hs.binary(max_size=16))
_values = hs.recursive(_leaf, lambda inner: hs.lists(inner, max_size=4) | hs.dictionaries(hs.text(max_size=4), inner,
                                                                                          max_size=4), max_leaves=30)


@settings(max_examples=300, deadline=None)
@given(hs.dictionaries(hs.sampled_from(["v", "changes", "phases", "link", "total", "x"]), _values, max_size=6))
def test_any_settings_payload_decodes_to_plain_values_or_a_reason_never_raises(obj):
    got = decode_settings(msgpack.packb(obj, use_bin_type=True), IDS)
    assert isinstance(got, Rejected) or json.dumps(got, allow_nan=False)


def test_plain_values_keep_their_kind_their_depth_and_their_size():
    from cdus.wire.replies import _PLAIN_DEPTH, _plain
    from cdus.wire.text import printable

    assert [_plain(x) for x in (True, False, None, 0, 2**63 - 1, -(2**63), 2**63, 1.5, math.nan, b"x")] == \
        [True, False, None, 0, 2**63 - 1, None, None, 1.5, None, None]
    assert _plain([math.inf, "a\x1b", [1.0]]) == [None, "a\\x1b", [1.0]]
    assert _plain("x" * 300) == printable("x" * 300, 256) and len(_plain("x" * 300)) == 257  # 256 and the ellipsis
    assert list(_plain({"k" * 100: 1})) == [printable("k" * 100, 64)]
    deep: object = 1.0
    for _ in range(_PLAIN_DEPTH):
        deep = [deep]
    assert _plain(deep) == deep  # as deep as it may be: whole
    nested = _plain({"a": deep})
    inner = nested["a"]
    for _ in range(_PLAIN_DEPTH - 1):
        inner = inner[0]
    assert inner == [None]  # one level too deep: left out


def test_what_the_decoder_takes_at_most():
    base = msgpack.unpackb(encode_settings([], PHASES, {}), raw=False)

    def packed(**over) -> bytes:
        return msgpack.packb({**base, **over}, use_bin_type=True)

    assert encode_settings([], PHASES, {}, total=50) and \
        decode_settings(encode_settings([], PHASES, {}, total=50), IDS)["total"] == 50
    from cdus.wire.schemas import MAX_COUNT
    assert decode_settings(packed(total=MAX_COUNT), IDS) == Rejected("type")
    assert decode_settings(packed(total=MAX_COUNT - 1), IDS)["total"] == MAX_COUNT - 1
    assert decode_settings(packed(changes=[[None, b"\x00" * 4097]]), IDS) == Rejected("malformed")  # a command is small
    assert decode_settings(packed(link={"name": "x" * 4097}), IDS) == Rejected("malformed")
    assert decode_settings(packed(link={str(j): j for j in range(4097)}), IDS) == Rejected("malformed")
    assert decode_settings(packed(link={"x": msgpack.ExtType(1, b"a")}), IDS) == Rejected("malformed")
    assert decode_settings(packed(changes=[None] * 10_001, total=10_001), IDS) == Rejected("malformed")
    assert decode_settings(packed(changes=[None] * 10_000, total=10_000), IDS)["unreadable"] == 10_000
    assert decode_settings(packed(link={"k": "x" * 4096}), IDS)["link"]["k"] == printable_256("x" * 4096)


def printable_256(s: str) -> str:
    from cdus.wire.text import printable
    return printable(s, 256)
