"""The world's answer to a command (cdus.wire.schemas.CommandReply): versioned, every field
checked, a reject reason for anything else, never an exception."""

from __future__ import annotations

import msgpack
import pytest
from hypothesis import given, settings, strategies as hs

from cdus.wire.rejected import Rejected
from cdus.wire.schemas import REPLY_VERSION, CommandReply, decode_reply, encode_reply


def test_a_reply_goes_through_as_it_was():
    for r in (CommandReply("applied", "pause", "", 41, 0.82, "gs:alice"),
              CommandReply("rejected", "set_gains", "k must be 2 numbers > 0 for this vehicle, got [1, 2, 3]"),
              CommandReply("rejected", "?", "the command could not be read: malformed")):
        assert decode_reply(encode_reply(r)) == r
    assert CommandReply("applied", "stop", tick=3).as_dict() == {"v": 1, "status": "applied", "op": "stop",
                                                                  "reason": "", "tick": 3, "t": None, "by": ""}


def pack(**d) -> bytes:
    return msgpack.packb({"v": REPLY_VERSION, "status": "applied", "op": "pause", "reason": "", "tick": 1, **d})


@pytest.mark.parametrize("payload, reason", [
    (b"\xc1", "malformed"), (msgpack.packb([1, 2]), "malformed"), (b"\x00" * 5000, "oversized"),
    (pack(v=2), "version"), (pack(v=True), "version"), (pack(extra=1), "unknown_field"),
    (pack(status="maybe"), "status"), (pack(op="DROP TABLE"), "op"), (pack(tick=-1), "range"),
    (pack(tick=1.5), "type"), (pack(t=float("nan")), "type"), (pack(t=1e300), "range"),
    (pack(tick=None), "range"),  # applied says when
    (pack(by="a b"), "unknown_sender"), (pack(reason=3), "type"), (pack(status=None), "type"),
])
def test_what_is_not_a_reply_is_rejected_by_reason(payload, reason):
    assert decode_reply(payload) == Rejected(reason)


def test_a_reason_from_the_wire_comes_out_escaped():
    r = decode_reply(pack(status="rejected", tick=None, reason="\x1b[2Jgone"))
    assert isinstance(r, CommandReply) and "\x1b" not in r.reason


values = hs.recursive(hs.none() | hs.booleans() | hs.integers(-2**63, 2**64 - 1) | hs.floats() | hs.text(max_size=30),
                      lambda c: hs.lists(c, max_size=3) | hs.dictionaries(hs.text(max_size=6), c, max_size=3),
                      max_leaves=8)


@settings(max_examples=400, deadline=None)
@given(d=hs.dictionaries(hs.sampled_from(["v", "status", "op", "reason", "tick", "t", "by", "x"]), values),
       junk=hs.binary(max_size=64))
def test_no_payload_makes_the_decoder_raise(d, junk):
    for payload in (msgpack.packb(d), junk):
        r = decode_reply(payload)
        assert isinstance(r, CommandReply) or isinstance(r, Rejected) and r.reason
        if isinstance(r, CommandReply):
            assert r.status in ("applied", "rejected") and (not r.applied or r.tick is not None)
            assert decode_reply(encode_reply(r)) == r
