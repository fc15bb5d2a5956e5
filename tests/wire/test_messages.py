"""The ω message: wire round trip, size bound, every rejection reason, a decode fuzz."""

import math
import random
import struct

import msgpack
import pytest

from cdus.wire.messages import (
    MAX_OMEGA_PAYLOAD, OMEGA_VERSION, OmegaMsg, decode_omega, encode_omega,
)
from cdus.wire.rejected import Rejected


def _f32(x):
    return struct.unpack("<f", struct.pack("<f", x))[0]


def _raw(*items):
    """A payload with chosen element types; floats packed as float32 so that any
    replacement still fits the size bound (these values are exact in float32)."""
    return msgpack.packb(list(items), use_single_float=True)


GOOD = (OMEGA_VERSION, 2, 17, 12.5, -3.25, -1.0)


def test_raw_helper_builds_a_valid_message():
    assert decode_omega(_raw(*GOOD)) == OmegaMsg(2, 17, 12.5, -3.25, -1.0)


@pytest.mark.parametrize("omega", [-1234567.891011121314, 1e-300, 2.0**60 + 0.5, -math.pi * 1e6,
                                   0.1 + 0.2])
def test_round_trip_keeps_omega_exact(omega):
    rate = -1.0049876543210987
    m = OmegaMsg(sender=3, seq=99, t_send=1234.000001, omega=omega, omega_rate=rate)
    got = decode_omega(encode_omega(m), expected_sender=3, n_vehicles=6)
    assert isinstance(got, OmegaMsg)
    assert got.omega == omega  # float64 on the wire, bit for bit
    assert got.t_send == m.t_send
    assert (got.sender, got.seq) == (3, 99)
    assert got.omega_rate == _f32(rate)  # float32 on the wire
    assert got.omega_rate != rate
    assert abs(got.omega_rate - rate) < 1e-7


def test_omega_rate_beyond_float32_is_clamped_not_lost():
    got = decode_omega(encode_omega(OmegaMsg(0, 0, 0.0, 1.0, -1e300)))
    assert isinstance(got, OmegaMsg)
    assert got.omega_rate == _f32(-3.0e38)


@pytest.mark.parametrize("sender, seq, t, w, wd", [
    (127, 2**32 - 1, 1e300, -1e300, -1e300),
    (127, 2**32 - 1, -1e308, 1.7e308, 3e38),
    (255, 2**32 - 1, 1e300, -1e300, 1e-45),
    (0, 0, 0.0, 0.0, 0.0),
])
def test_payload_fits_the_bound_for_extreme_values(sender, seq, t, w, wd):
    payload = encode_omega(OmegaMsg(sender, seq, t, w, wd))
    assert len(payload) <= MAX_OMEGA_PAYLOAD
    assert isinstance(decode_omega(payload), OmegaMsg)


def test_payload_is_32_bytes_up_to_256_vehicles_and_33_beyond():
    assert len(encode_omega(OmegaMsg(255, 2**32 - 1, 1e300, -1e300, -1.0))) == 32
    assert len(encode_omega(OmegaMsg(0, 0, 0.0, 0.0, 0.0))) == 32
    big = OmegaMsg(600, 7, 1.5, -2.5, -1.0)
    assert len(encode_omega(big)) == 33 and decode_omega(encode_omega(big)) == big


def test_any_msgpack_spelling_of_the_array_is_read_and_checked_alike():
    m = OmegaMsg(3, 12, 0.5, -7.25, -1.0)
    minimal = msgpack.packb([1, 3, 12, 0.5, -7.25, -1.0])  # smallest ints, float64 rate
    assert len(minimal) < 32 and decode_omega(minimal) == m
    assert decode_omega(msgpack.packb([1, 3, 12, 0.5, float("nan"), -1.0])) == Rejected("non_finite")
    assert decode_omega(encode_omega(m), expected_sender=4) == Rejected("unknown_sender")


def test_oversized():
    assert decode_omega(b"\x96" + b"\x00" * 40) == Rejected("oversized")
    assert decode_omega(bytes(MAX_OMEGA_PAYLOAD + 1)) == Rejected("oversized")
    # a sequence number past 2**32 no longer fits the bound
    assert decode_omega(encode_omega(OmegaMsg(0, 2**32, 0.0, 0.0, 0.0))) == Rejected("oversized")


@pytest.mark.parametrize("payload", [
    b"",
    b"\xc1",  # never-used msgpack byte
    b"\xff\xfe\xfd garbage",
    encode_omega(OmegaMsg(1, 2, 3.0, 4.0, -1.0))[:-3],  # truncated
    encode_omega(OmegaMsg(1, 2, 3.0, 4.0, -1.0)) + b"\x00",  # trailing bytes
    msgpack.packb({"v": 1}),  # map instead of list
    msgpack.packb({}),
    _raw(*GOOD[:5]),  # wrong length
    _raw(*GOOD, 0.0),
    msgpack.packb([]),
    msgpack.packb(3.5),
    msgpack.packb(list(range(9))),  # beyond max_array_len
    msgpack.packb([1, 2, 3, b"bin", 5.0, 6.0]),  # bin is not allowed
    msgpack.packb([1, 2, 3, "str", 5.0, 6.0]),
])
def test_malformed(payload):
    assert decode_omega(payload) == Rejected("malformed")


@pytest.mark.parametrize("version", [0, 2, 1.0, True, None])
def test_version(version):
    assert decode_omega(_raw(version, *GOOD[1:])) == Rejected("version")


@pytest.mark.parametrize("index, value", [
    (1, 2.0),      # sender as float
    (2, 17.0),     # seq as float
    (1, None),
    (3, 12),       # t_send as int
    (4, -3),       # ω as int: the schema says float64
    (5, None),
])
def test_type(index, value):
    items = list(GOOD)
    items[index] = value
    assert decode_omega(_raw(*items)) == Rejected("type")


@pytest.mark.parametrize("index, value", [(1, True), (2, False), (3, True), (4, False), (5, True)])
def test_bools_are_not_numbers(index, value):
    """msgpack decodes true/false as bool, a subclass of int; `type(x) is int` rejects it."""
    items = list(GOOD)
    items[index] = value
    assert decode_omega(_raw(*items)) == Rejected("type")


@pytest.mark.parametrize("index", [3, 4, 5])
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_non_finite(index, value):
    items = list(GOOD)
    items[index] = value
    assert decode_omega(_raw(*items)) == Rejected("non_finite")


@pytest.mark.parametrize("field", ["t_send", "omega", "omega_rate"])
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_encoded_non_finite_is_rejected(field, value):
    """A diverged sender's message is dropped by every receiver; the float32 clamp of ω̇
    must not turn a NaN or ±inf into a plausible-looking finite rate."""
    m = OmegaMsg(**{"sender": 0, "seq": 1, "t_send": 2.0, "omega": 3.0, "omega_rate": -1.0,
                    field: value})
    assert decode_omega(encode_omega(m)) == Rejected("non_finite")


@pytest.mark.parametrize("kwargs, items", [
    ({"n_vehicles": 2}, GOOD),                     # index 2 of 2 vehicles
    ({"n_vehicles": 6, "expected_sender": 1}, GOOD),  # the key says vehicle 1
    ({}, (1, -1, 17, 12.5, -3.25, -1.0)),            # negative index
    ({}, (1, 2, -5, 12.5, -3.25, -1.0)),             # negative seq
])
def test_unknown_sender(kwargs, items):
    assert decode_omega(_raw(*items), **kwargs) == Rejected("unknown_sender")


def test_expected_sender_and_range_accept_the_right_one():
    got = decode_omega(_raw(*GOOD), expected_sender=2, n_vehicles=3)
    assert isinstance(got, OmegaMsg) and got.sender == 2


def test_float32_fields_are_accepted():
    """Any msgpack float is a float: a sender packing single floats is understood."""
    payload = msgpack.packb([1, 0, 0, 1.5, 2.5, -1.0], use_single_float=True)
    assert decode_omega(payload) == OmegaMsg(0, 0, 1.5, 2.5, -1.0)


REASONS = {"oversized", "malformed", "version", "type", "non_finite", "unknown_sender"}


def test_fuzz_random_bytes_never_raise():
    rng = random.Random(20240611)
    outcomes = {}
    for _ in range(5000):
        n = rng.randrange(0, 40)
        payload = bytes(rng.randrange(256) for _ in range(n))
        got = decode_omega(payload, expected_sender=rng.randrange(4), n_vehicles=4)
        assert isinstance(got, OmegaMsg) or isinstance(got, Rejected) and got.reason in REASONS
        key = "ok" if isinstance(got, OmegaMsg) else got.reason
        outcomes[key] = outcomes.get(key, 0) + 1
    assert outcomes["oversized"] > 0 and outcomes["malformed"] > 0


def test_fuzz_mutated_messages_never_raise():
    """Byte flips of a valid payload reach the deeper checks, not only "malformed"."""
    rng = random.Random(7)
    base = encode_omega(OmegaMsg(1, 42, 10.0, -7.5, -1.0))
    seen = set()
    for _ in range(5000):
        b = bytearray(base)
        for _ in range(rng.randrange(1, 3)):
            b[rng.randrange(len(b))] = rng.randrange(256)
        got = decode_omega(bytes(b), n_vehicles=4)
        assert isinstance(got, OmegaMsg) or isinstance(got, Rejected) and got.reason in REASONS
        seen.add("ok" if isinstance(got, OmegaMsg) else got.reason)
    assert {"ok", "malformed", "version", "type"} <= seen


# --------------------------------------------------------------------------- contacts


def test_contacts_round_trip_is_exact():
    from cdus.wire.messages import ContactsMsg, decode_contacts, encode_contacts
    m = ContactsMsg(1234, ((0, 0.5, (1.0000000000000002, -3.25)), (7, 1.0, (0.1, 0.2, 0.0))))
    assert decode_contacts(encode_contacts(m), 8) == m
    assert decode_contacts(encode_contacts(ContactsMsg(0, ())), 8) == ContactsMsg(0, ())


@pytest.mark.parametrize("obj, reason", [
    ([1, -1, []], "type"), ([1, 0, [[0, 0.5]]], "malformed"), ([1, 0, [[0, 1.5, [1.0, 2.0]]]], "share"),
    ([1, 0, [[3, 0.5, [1.0, 2.0]]]], "unknown_sender"), ([1, 0, [[0, 0.5, [1.0, float("inf")]]]], "non_finite"),
    ([1, 0, [[0, 0.5, [1.0]]]], "type"), ({"v": 1}, "malformed"),
])
def test_bad_contacts_are_rejected_with_a_reason(obj, reason):
    from cdus.wire.messages import decode_contacts
    assert decode_contacts(msgpack.packb(obj), 3) == Rejected(reason)
    assert decode_contacts(b"\x00" * 20000) == Rejected("oversized")


# ------------------------------------------------------------------ properties (issue 15)

from hypothesis import given, settings, strategies as st  # noqa: E402

from cdus.wire.messages import (  # noqa: E402
    COMMAND_OPS, CTL_OPS, LAUNCHER_OPS, ContactsMsg, Control, decode_contacts, decode_control,
    encode_contacts, encode_control,
)

_VALID = [
    encode_omega(OmegaMsg(2, 17, 17 * 0.02, -3.25, -1.0)),
    encode_omega(OmegaMsg(300, 2**32 - 1, 1.0, 1e300, 3e38)),
    encode_contacts(ContactsMsg(12, ((1, 0.5, (1.0, 2.0)), (3, 1.0, (0.0, 1.0, 2.0))))),
    encode_control("grant", until=40),
    encode_control("roster", vehicle="usv2", tick=3, state="gone", fresh=False),
    encode_control("link", link={"delay": {"base": 0.2}, "loss": 0.1}, at=1.0),
    encode_control("gains", gains={"k": [1.0, 2.0], "c": 3.0}, tick=5),
]


def _mutated(data: st.DataObject) -> bytes:
    """A valid payload with bytes flipped, cut, inserted or repeated."""
    p = bytearray(data.draw(st.sampled_from(_VALID)))
    for _ in range(data.draw(st.integers(1, 4))):
        how = data.draw(st.sampled_from(["flip", "cut", "insert", "grow"]))
        i = data.draw(st.integers(0, max(0, len(p) - 1)))
        if how == "flip" and p:
            p[i] = data.draw(st.integers(0, 255))
        elif how == "cut":
            del p[i:]
        elif how == "insert":
            p[i:i] = data.draw(st.binary(max_size=8))
        else:
            p += p[i:][:4096]
    return bytes(p)


def _decoders(p: bytes) -> list:
    return [decode_omega(p), decode_omega(p, expected_sender=2, n_vehicles=3), decode_contacts(p),
            decode_contacts(p, 4), decode_control(p, CTL_OPS), decode_control(p, COMMAND_OPS),
            decode_control(p, LAUNCHER_OPS)]


def _message_or_reason(out) -> bool:
    """A message, or the reason: Rejected from the ω and contacts decoders, a string from decode_control."""
    return isinstance(out, (Rejected, str, OmegaMsg, ContactsMsg, Control))


@settings(max_examples=400, deadline=None)
@given(st.binary(max_size=200))
def test_decoders_never_raise_on_arbitrary_bytes(p):
    assert all(_message_or_reason(x) for x in _decoders(p))


@settings(max_examples=400, deadline=None)
@given(st.data())
def test_decoders_never_raise_on_mutated_valid_payloads(data):
    p = _mutated(data)
    for out in _decoders(p):
        assert _message_or_reason(out)
        if isinstance(out, OmegaMsg):  # what passes is finite: nothing downstream overflows on it
            assert all(math.isfinite(x) for x in (out.t_send, out.omega, out.omega_rate))
        if isinstance(out, Control):
            assert all(math.isfinite(v) for v in out.fields.values() if isinstance(v, float))


@settings(max_examples=200, deadline=None)
@given(st.recursive(st.none() | st.booleans() | st.integers(-2**70, 2**70) | st.floats() | st.text(max_size=20),
                    lambda c: st.lists(c, max_size=5) | st.dictionaries(st.text(max_size=8), c, max_size=5),
                    max_leaves=30))
def test_decoders_never_raise_on_any_msgpack_value(obj):
    try:
        p = msgpack.packb(obj, use_bin_type=True)
    except (OverflowError, ValueError):
        return
    assert all(_message_or_reason(x) for x in _decoders(p))
