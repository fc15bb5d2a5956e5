"""The fleet's reports (cdus.wire.schemas): round trips, and every malformed field rejected
with its reason, never raised."""

from __future__ import annotations

import math
import random

import msgpack
import pytest

from cdus.wire.schemas import (
    EVENT_KINDS, MAX_TEXT, SCHEMA_VERSION, STATUS_KEYS, AgentStats, FleetEvent, decode_event, decode_stats,
    decode_status, encode_event, encode_stats, encode_status, event_from_dict,
)


def pack(d) -> bytes:
    return msgpack.packb(d, use_bin_type=True)


# ---------------------------------------------------------------------- events


def test_every_event_kind_round_trips_with_its_default_severity():
    for kind, severity in EVENT_KINDS.items():
        e = FleetEvent.of(12.5, kind, f"something {kind}", vehicle="usv1", link="usv1->uav2")
        assert e.severity == severity
        assert decode_event(encode_event(e)) == e


def test_an_event_keeps_a_severity_given_to_it_and_leaves_out_absent_fields():
    e = FleetEvent.of(1.0, "graph", "cut off", severity="warn")
    assert e.severity == "warn"
    assert e.as_dict() == {"t": 1.0, "kind": "graph", "text": "cut off", "severity": "warn"}
    assert decode_event(encode_event(e)) == e


def test_an_events_text_is_cut_to_the_limit_and_reads_as_a_log_line():
    e = FleetEvent.of(3.0, "fleet", "x" * (MAX_TEXT + 50))
    assert len(e.text) == MAX_TEXT
    assert e.line() == f"t = 3.00 s: {e.text}"
    long = pack({"v": SCHEMA_VERSION, "t": 1.0, "kind": "fleet", "text": "y" * (MAX_TEXT + 5)})
    assert decode_event(long).text == "y" * MAX_TEXT


def test_an_unknown_event_kind_is_a_programming_error():
    with pytest.raises(KeyError):
        FleetEvent.of(0.0, "vehicle_exploded", "boom")


GOOD_EVENT = {"v": SCHEMA_VERSION, "t": 2.0, "kind": "vehicle_lost", "text": "vehicle usv2 lost",
              "severity": "warn", "vehicle": "usv2"}


@pytest.mark.parametrize("field, value, reason", [
    ("v", SCHEMA_VERSION + 1, "version"),
    ("v", None, "version"),
    ("t", "2.0", "type"),
    ("t", float("nan"), "type"),
    ("t", float("inf"), "type"),
    ("t", True, "type"),
    ("kind", "exploded", "type"),
    ("kind", None, "type"),
    ("text", 5, "type"),
    ("severity", "fatal", "type"),
    ("vehicle", 3, "type"),
    ("link", ["a", "b"], "type"),
])
def test_a_malformed_event_field_is_rejected_with_its_reason(field, value, reason):
    assert isinstance(decode_event(pack(GOOD_EVENT)), FleetEvent)
    d = {**GOOD_EVENT, field: value}
    assert decode_event(pack(d)) == reason


def test_a_missing_event_field_is_rejected():
    for field in ("v", "t", "kind", "text"):
        d = {k: x for k, x in GOOD_EVENT.items() if k != field}
        assert decode_event(pack(d)) == ("version" if field == "v" else "type"), field


def test_event_payloads_that_are_not_a_map_or_too_big_are_rejected():
    assert decode_event(b"\xc1") == "malformed"
    assert decode_event(pack([1, 2, 3])) == "malformed"
    assert decode_event(pack({**GOOD_EVENT, "text": "z" * 5000})) == "oversized"
    assert event_from_dict("not a dict") == "malformed"


# ---------------------------------------------------------------------- agent stats


def stats() -> AgentStats:
    return AgentStats(id="uav1", tick=500, sent_to_me=1000, delivered=990, dropped=10, duplicated=2,
                      rejected=3, rejected_by_reason={"stale": 1, "sender": 2}, missed_deadlines=4,
                      joined_at=100, latencies_ms=(0.25, 1.5), faults={"total": {"sent": 1000}},
                      bursts=(FleetEvent.of(3.0, "link_burst", "12 drops", link="usv1->uav1").as_dict(),))


def test_agent_stats_round_trip():
    s = stats()
    assert decode_stats(encode_stats(s)) == s
    empty = AgentStats(id="usv1", tick=0)
    assert decode_stats(encode_stats(empty)) == empty


@pytest.mark.parametrize("field, value, reason", [
    ("v", 0, "version"),
    ("id", 7, "type"),
    ("id", None, "type"),
    ("tick", -1, "type"),
    ("tick", 1.5, "type"),
    ("tick", True, "type"),
    ("sent_to_me", "many", "type"),
    ("delivered", -3, "type"),
    ("dropped", None, "type"),
    ("duplicated", 2.0, "type"),
    ("rejected", -1, "type"),
    ("missed_deadlines", [1], "type"),
    ("joined_at", -5, "type"),
    ("rejected_by_reason", [1, 2], "type"),
    ("rejected_by_reason", {"stale": 1.5}, "type"),
    ("latencies_ms", "fast", "type"),
    ("latencies_ms", [1.0, float("nan")], "type"),
    ("latencies_ms", [1.0, "2"], "type"),
    ("faults", [1], "type"),
    ("bursts", {"a": 1}, "type"),
])
def test_a_malformed_stats_field_is_rejected_with_its_reason(field, value, reason):
    d = {"v": SCHEMA_VERSION, **stats().as_dict()}
    assert isinstance(decode_stats(pack(d)), AgentStats)
    d[field] = value
    assert decode_stats(pack(d)) == reason


def test_bursts_that_are_not_maps_are_left_out():
    d = {"v": SCHEMA_VERSION, **stats().as_dict(), "bursts": [{"t": 1.0}, 5, "x"]}
    assert decode_stats(pack(d)).bursts == ({"t": 1.0},)


def test_stats_payloads_that_are_not_a_map_or_too_big_are_rejected():
    assert decode_stats(b"") == "malformed"
    assert decode_stats(pack("stats")) == "malformed"
    big = {"v": SCHEMA_VERSION, **stats().as_dict(), "latencies_ms": [1.0] * 4000}
    assert isinstance(decode_stats(pack(big)), AgentStats)  # 36 kB: within the limit
    assert decode_stats(pack({**big, "latencies_ms": [1.0] * 8000})) == "oversized"


# ---------------------------------------------------------------------- world status


def status(**over) -> bytes:
    args = dict(t=12.0, duration=250.0, clock="lockstep", alive=["usv1", "uav1"], ids=["usv1", "uav1"],
                path_error_max=0.05, coord_error_max=0.01,
                events=[FleetEvent.of(10.0, "vehicle_lost", "vehicle uav2 lost", vehicle="uav2")], paused=False)
    args.update(over)
    return encode_status(**args)


def test_world_status_round_trips():
    st = decode_status(status())
    assert set(st) == set(STATUS_KEYS)
    assert st["t"] == 12.0 and st["duration"] == 250.0 and st["clock"] == "lockstep"
    assert st["alive"] == ["usv1", "uav1"] and st["ids"] == ["usv1", "uav1"]
    assert st["path_error_max"] == 0.05 and st["coord_error_max"] == 0.01
    assert st["events"] == [FleetEvent.of(10.0, "vehicle_lost", "vehicle uav2 lost", vehicle="uav2")]
    assert st["paused"] is False
    assert decode_status(status(paused=True))["paused"] is True


def test_status_of_an_empty_run_carries_no_errors():
    st = decode_status(status(path_error_max=None, coord_error_max=float("nan"), events=[]))
    assert st["path_error_max"] is None and st["coord_error_max"] is None and st["events"] == []


def test_status_drops_malformed_events_but_keeps_the_rest():
    d = msgpack.unpackb(status(), raw=False)
    d["events"].append({"t": "soon", "kind": "fleet", "text": "?"})
    st = decode_status(pack(d))
    assert len(st["events"]) == 1


@pytest.mark.parametrize("field, value, reason", [
    ("v", 2, "version"),
    ("t", None, "type"),
    ("t", float("inf"), "type"),
    ("duration", "long", "type"),
    ("clock", 1, "type"),
    ("alive", "usv1", "type"),
    ("alive", ["usv1", 2], "type"),
    ("ids", None, "type"),
    ("events", {"a": 1}, "type"),
])
def test_a_malformed_status_field_is_rejected_with_its_reason(field, value, reason):
    d = msgpack.unpackb(status(), raw=False)
    d[field] = value
    assert decode_status(pack(d)) == reason


def test_status_payloads_that_are_not_a_map_or_too_big_are_rejected():
    assert decode_status(b"\x91") == "malformed"
    assert decode_status(b"\x00" * ((1 << 16) + 1)) == "oversized"


def test_decoders_never_raise_on_random_bytes():
    rng = random.Random(7)
    good = [encode_event(FleetEvent.of(1.0, "fleet", "paused")), encode_stats(stats()), status()]
    for _ in range(2000):
        base = bytearray(rng.choice(good))
        for _ in range(rng.randrange(1, 6)):  # flip a few bytes of a valid payload
            base[rng.randrange(len(base))] = rng.randrange(256)
        payload = bytes(base[: rng.randrange(len(base) + 1)])
        for decode in (decode_event, decode_stats, decode_status):
            out = decode(payload)
            assert isinstance(out, (str, FleetEvent, AgentStats, dict))
            if isinstance(out, FleetEvent):
                assert math.isfinite(out.t) and out.kind in EVENT_KINDS
