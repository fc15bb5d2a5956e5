"""The wire codecs, branch by branch: each reject has its exact reason, each bound is where it
says it is, and the fixed-layout fast path is what a canonical message takes (found by
mutation testing: `mutmut run`, see pyproject.toml)."""

from __future__ import annotations

import math

import msgpack
import pytest

import cdus.wire.messages as wm
from cdus.wire.messages import (CTL_OPS, COMMAND_OPS, MAX_CONTACTS, MAX_CONTROL_PAYLOAD, MAX_STATE_ROWS, ContactsMsg,
                                Control, OmegaMsg, StateMsg, decode_contacts, decode_control, decode_omega,
                                decode_states, encode_contacts, encode_control, encode_omega, encode_states)
from cdus.wire.rejected import Rejected

GOOD = OmegaMsg(3, 7, 0.14, -2.5, -1.0)


# --------------------------------------------------------------------------- ω


def test_a_canonical_message_takes_the_fixed_layout_fast_path(monkeypatch):
    monkeypatch.setattr(wm, "_decode_omega_any", lambda *a: pytest.fail("slow path for a canonical message"))
    assert decode_omega(encode_omega(GOOD)) == GOOD
    assert decode_omega(encode_omega(OmegaMsg(300, 7, 0.14, -2.5, -1.0))) == OmegaMsg(300, 7, 0.14, -2.5, -1.0)


@pytest.mark.parametrize("sender, size", [(0, 32), (255, 32), (256, 33), (65535, 33)])
def test_the_sender_width_switches_at_256_and_stays_fixed_to_65535(sender, size):
    p = encode_omega(OmegaMsg(sender, 1, 0.02, 0.0, -1.0))
    assert len(p) == size and decode_omega(p) == OmegaMsg(sender, 1, 0.02, 0.0, -1.0)


def test_past_the_fixed_layout_it_is_plain_msgpack():
    p = encode_omega(OmegaMsg(65536, 1, 0.02, 0.0, -1.0))
    assert msgpack.unpackb(p) == [1, 65536, 1, 0.02, 0.0, -1.0]
    p = encode_omega(OmegaMsg(1, 2**32, 0.02, 0.0, -1.0))
    assert msgpack.unpackb(p)[2] == 2**32


def _corrupt(payload: bytes, at: int, value: int) -> bytes:
    b = bytearray(payload)
    b[at] = value
    return bytes(b)


@pytest.mark.parametrize("at", [0, 2, 4, 9, 18, 27])
def test_a_fixed_layout_with_a_wrong_marker_is_read_by_the_slow_path_and_rejected(at):
    p = encode_omega(GOOD)
    bad = _corrupt(p, at, 0xc1)  # never valid msgpack
    assert decode_omega(bad) == Rejected("malformed")


def test_a_wrong_version_in_the_fixed_layout_is_a_version_reject():
    assert decode_omega(_corrupt(encode_omega(GOOD), 1, 2)) == Rejected("version")


@pytest.mark.parametrize("at", [9, 18])
def test_a_fixed_layout_whose_float_markers_spell_other_types_is_a_type_reject(at):
    # 0xca (float32) where a float64 is expected: the slow path reads other widths
    b = bytearray(encode_omega(GOOD))
    b[at] = 0xcc  # a uint8 then 8 more bytes: no longer a 6-element array of that length
    assert decode_omega(bytes(b)) in (Rejected("malformed"), Rejected("type"))


def test_expected_sender_and_vehicle_count_reach_the_checks_on_both_paths():
    fast = encode_omega(GOOD)
    slow = msgpack.packb([1, 3, 7, 0.14, -2.5, -1.0])
    for p in (fast, slow):
        assert decode_omega(p, expected_sender=3, n_vehicles=4) == GOOD
        assert decode_omega(p, expected_sender=2) == Rejected("unknown_sender")
        assert decode_omega(p, n_vehicles=3) == Rejected("unknown_sender")


@pytest.mark.parametrize("payload, reason", [
    (msgpack.packb([1, 3, 7, 0.14, -2.5]), "malformed"),  # 5 elements
    (msgpack.packb({"v": 1}), "malformed"),
    (msgpack.packb([1, 3, 7, 0.14, -2.5, b"x"]), "oversized" if len(msgpack.packb([1, 3, 7, 0.14, -2.5, b"x"])) > 33
     else "malformed"),
    (msgpack.packb([2, 3, 7, 0.14, -2.5, -1.0]), "version"),
    (msgpack.packb([1.0, 3, 7, 0.14, -2.5, -1.0]), "oversized"),  # 39 bytes
    (msgpack.packb([True, 3, 7, 0.14, -2.5, -1.0]), "version"),
    (msgpack.packb([1, 3, 7, 0.14, -2.5, None]), "type"),
    (msgpack.packb([1, 3, 7, 1, -2.5, -1.0]), "type"),
    (msgpack.packb([1, 3, 7, 0.14, -2.5, math.nan]), "non_finite"),
    (msgpack.packb([1, -1, 7, 0.14, -2.5, -1.0]), "unknown_sender"),
    (msgpack.packb([1, 3, -7, 0.14, -2.5, -1.0]), "unknown_sender"),
    (b"\x96" + b"\xc4\x01x" * 5 + b"\x01", "malformed"),  # bin inside the array
    (b"\x96\xa1x\x03\x07\xcb" + b"\x00" * 8 + b"\x01\x01", "malformed"),  # a str
    (b"\x96\xd4\x00\x00" + b"\x01" * 5, "malformed"),  # an ext
    (b"\x96\x81\x01\x01\x01\x01\x01\x01\x01", "malformed"),  # a map
])
def test_each_slow_path_reject_has_its_reason(payload, reason):
    assert decode_omega(payload) == Rejected(reason)


def test_33_and_34_bytes_bound_the_slow_path():
    assert decode_omega(b"\x01" * 34) == Rejected("oversized")
    assert decode_omega(b"\xc1" * 33) == Rejected("malformed")


# --------------------------------------------------------------------------- telemetry


def _row(tick=5, q=(1.0, 2.0)):
    return StateMsg(2, tick, tick * 0.02, q, 0.5, 1.0, -3.0, -1.0, 0.1)


def test_states_round_trip_and_every_reject_reason():
    rows = [_row(5), _row(6, (1.0, 2.0, 3.0))]
    assert decode_states(encode_states(rows), n_vehicles=3) == rows
    assert decode_states(encode_states(rows), n_vehicles=2) == Rejected("unknown_sender")
    ok_row = [5, 0.1, [1.0, 2.0], 0.5, 1.0, -3.0, -1.0, 0.1]
    cases = {
        "version": [2, 2, [ok_row]],
        "type": [1, 2.0, [ok_row]],
        "malformed": [1, 2, [ok_row[:7]]],
        "non_finite": [1, 2, [[5, math.inf, [1.0, 2.0], 0.5, 1.0, -3.0, -1.0, 0.1]]],
    }
    for reason, obj in cases.items():
        assert decode_states(msgpack.packb(obj)) == Rejected(reason), reason
    assert decode_states(msgpack.packb([1, 2, []])) == Rejected("type")  # no rows
    assert decode_states(msgpack.packb([1, -1, [ok_row]])) == Rejected("unknown_sender")
    assert decode_states(msgpack.packb([1, 2, [[-1, *ok_row[1:]]]])) == Rejected("type")
    assert decode_states(msgpack.packb([1, 2, [[5, 0.1, [1.0], *ok_row[3:]]]])) == Rejected("type")
    assert decode_states(msgpack.packb([1, 2, [[5, 0.1, [1.0, 2.0], 1, *ok_row[4:]]]])) == Rejected("type")
    assert decode_states(msgpack.packb([1, 2, [ok_row], 0])) == Rejected("malformed")
    assert decode_states(msgpack.packb({"v": 1})) == Rejected("malformed")
    assert decode_states(b"\xc1") == Rejected("malformed")


def test_states_bounds():
    full = [_row(j) for j in range(MAX_STATE_ROWS)]
    assert len(decode_states(encode_states(full))) == MAX_STATE_ROWS
    assert decode_states(encode_states(full + [_row(99)])) in (Rejected("malformed"), Rejected("oversized"))
    assert decode_states(b"\x00" * (96 * MAX_STATE_ROWS + 1)) == Rejected("oversized")


# --------------------------------------------------------------------------- contacts


def test_contacts_bounds_and_share():
    full = ContactsMsg(4, tuple((k, 0.5, (1.0, 2.0, 3.0)) for k in range(MAX_CONTACTS)))
    assert decode_contacts(encode_contacts(full)) == full
    assert len(encode_contacts(full)) <= 48 * MAX_CONTACTS + 16
    assert decode_contacts(b"\x00" * (48 * MAX_CONTACTS + 17)) == Rejected("oversized")
    assert decode_contacts(encode_contacts(ContactsMsg(4, ((1, 1.0, (0.0, 0.0)),)))) is not None
    assert decode_contacts(msgpack.packb([1, 4, [[1, 0.0, [0.0, 0.0]]]])) == Rejected("share")
    assert decode_contacts(msgpack.packb([1, 4, [[1, 1.5, [0.0, 0.0]]]])) == Rejected("share")
    assert decode_contacts(msgpack.packb([1, 4, [[1, 1.0, [0.0, 0.0]]]])) == ContactsMsg(4, ((1, 1.0, (0.0, 0.0)),))
    assert decode_contacts(msgpack.packb([1, 4, [[1, 1, [0.0, 0.0]]]])) == Rejected("type")
    assert decode_contacts(msgpack.packb([1, 4, [[1, 0.5, 5]]])) == Rejected("type")
    assert decode_contacts(msgpack.packb([1, 4, [[1.0, 0.5, [0.0, 0.0]]]])) == Rejected("type")
    assert decode_contacts(msgpack.packb([2, 4, []])) == Rejected("version")


# --------------------------------------------------------------------------- control maps


def test_control_round_trip_and_ints_taken_as_floats():
    assert decode_control(encode_control("grant", until=5), CTL_OPS) == Control("grant", {"until": 5})
    assert decode_control(encode_control("start", t0=3), CTL_OPS) == Control("start", {"t0": 3.0})
    got = decode_control(encode_control("link", link={"loss": 0.1, "delay": {"base": 0.2}}, at=1.5), COMMAND_OPS)
    assert got == Control("link", {"link": {"loss": 0.1, "delay": {"base": 0.2}}, "at": 1.5})
    assert isinstance(got.fields["at"], float)
    assert decode_control(encode_control("set_gains", gains={"k": [1.0, 2.0]}, vehicle="usv1"), COMMAND_OPS) == \
        Control("set_gains", {"gains": {"k": [1.0, 2.0]}, "vehicle": "usv1"})


def test_a_world_command_carries_its_number_and_a_bad_one_is_refused():
    """``seq`` on the world's run-time commands to the vehicles (replays applied once)."""
    for op, fields in [("link", {"link": {"loss": 0.1}, "at": 1.0}), ("gains", {"gains": {"c": 2.0}, "tick": 3}),
                       ("formation", {"phases": {"usv1": 1.0}, "tick": 3}), ("radio", {"radio": {}, "at": 1.0}),
                       ("path", {"vehicle": "usv1", "path": {}, "tick": 3})]:
        assert decode_control(encode_control(op, **fields, seq=7), CTL_OPS) == Control(op, {**fields, "seq": 7})
        assert decode_control(encode_control(op, **fields), CTL_OPS) == Control(op, fields)  # optional
        for bad in (-1, 2**53, True, 1.0, "1", None, [1]):
            assert decode_control(encode_control(op, **fields, seq=bad), CTL_OPS) == Rejected("seq"), (op, bad)
    # not a field of anything else: ignored there, as any other unknown key
    assert decode_control(encode_control("grant", until=5, seq="x"), CTL_OPS) == Control("grant", {"until": 5})
    got = decode_control(encode_control("link", link={}, at=1.0, seq=3), COMMAND_OPS)
    assert got == Control("link", {"link": {}, "at": 1.0})


def test_control_keys_are_text_on_the_wire():
    raw = msgpack.unpackb(encode_control("kill", vehicle="usv1"), raw=True)
    assert raw[b"op"] == b"kill" and raw[b"vehicle"] == b"usv1"
    # written as str, not bin: a receiver that insists on text takes it
    assert encode_control("kill", vehicle="usv1").count(b"\xc4") == 0


@pytest.mark.parametrize("obj, reason", [
    ({"v": 2, "op": "grant", "until": 1}, "version"),
    ({"v": 1.0, "op": "grant", "until": 1}, "version"),
    ({"v": True, "op": "grant", "until": 1}, "version"),
    ({"op": "grant", "until": 1}, "version"),
    ({"v": 1, "op": "nope"}, "unknown_op"),
    ({"v": 1, "op": 3}, "unknown_op"),
    ({"v": 1, "op": "grant", "until": 1.0}, "type"),
    ({"v": 1, "op": "grant"}, "type"),
    ({"v": 1, "op": "start", "t0": math.inf}, "non_finite"),
    ({"v": 1, "op": "start", "t0": "now"}, "type"),
    ([1, "grant"], "malformed"),
])
def test_each_control_reject_has_its_reason(obj, reason):
    assert decode_control(msgpack.packb(obj), CTL_OPS) == Rejected(reason)


@pytest.mark.parametrize("payload", [
    msgpack.packb({"v": 1, "op": "link", "link": {"x": b"bin"}, "at": 1.0}, use_bin_type=True),  # bin
    msgpack.packb({"v": 1, "op": "link", "link": {"x": msgpack.ExtType(1, b"e")}, "at": 1.0}),  # ext
    msgpack.packb({"v": 1, "op": "link", "link": {"x": "s" * 257}, "at": 1.0}),  # long str
    msgpack.packb({"v": 1, "op": "link", "link": {"x": list(range(65))}, "at": 1.0}),  # long array
    msgpack.packb({"v": 1, "op": "link", "link": {str(j): j for j in range(65)}, "at": 1.0}),  # big map
    b"\xc1",
])
def test_control_maps_past_their_bounds_are_malformed(payload):
    assert decode_control(payload, COMMAND_OPS) == Rejected("malformed")


def test_control_size_bound_is_inclusive():
    def sized(n: int) -> bytes:
        link = {f"k{j}": "x" * 200 for j in range(19)}
        for fill in range(0, 256):
            p = msgpack.packb({"v": 1, "op": "link", "at": 1.0, "link": {**link, "z": "y" * fill}})
            if len(p) >= n:
                return p
        raise AssertionError(n)

    assert len(sized(MAX_CONTROL_PAYLOAD)) == MAX_CONTROL_PAYLOAD
    assert isinstance(decode_control(sized(MAX_CONTROL_PAYLOAD), COMMAND_OPS), Control)
    assert len(sized(MAX_CONTROL_PAYLOAD + 1)) == MAX_CONTROL_PAYLOAD + 1
    assert decode_control(sized(MAX_CONTROL_PAYLOAD + 1), COMMAND_OPS) == Rejected("oversized")


def test_contacts_checked_against_the_receiver():
    """Given the receiving vehicle's index and dimension, a contact that is the receiver, one vehicle
    listed twice, or a position of the other domain's dimension is rejected, by reason."""
    two = ContactsMsg(4, ((1, 0.5, (0.0, 0.0)), (2, 1.0, (3.0, 1.0))))
    assert decode_contacts(encode_contacts(two), 5, receiver=0, dim=2) == two
    assert decode_contacts(encode_contacts(two), 5, receiver=1, dim=2) == Rejected("self")
    assert decode_contacts(encode_contacts(two), 5, receiver=0, dim=3) == Rejected("dimension")
    dup = ContactsMsg(4, ((1, 0.5, (0.0, 0.0)), (1, 0.5, (3.0, 1.0))))
    assert decode_contacts(encode_contacts(dup), 5, receiver=0, dim=2) == Rejected("duplicate")
