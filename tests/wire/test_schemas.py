"""The fleet's reports (cdus.wire.schemas): round trips, and every malformed field rejected
with its reason, never raised."""

from __future__ import annotations

import math
import random

import msgpack
import pytest

from dataclasses import replace

from cdus.wire import schemas
from cdus.wire.schemas import BurstReport
from cdus.wire.schemas import (
    EVENT_KINDS, MAX_TEXT, SCHEMA_VERSION, STATUS_KEYS, AgentStats, FleetEvent, decode_event, decode_stats,
    decode_status, encode_event, encode_stats, encode_status, event_from_dict,
)
from cdus.wire.rejected import Rejected
from cdus.wire.status import WorldStatus


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
    assert decode_event(long).text == "y" * MAX_TEXT + "…"  # cut by printable(), marked


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
    assert decode_event(pack(d)) == Rejected(reason)


def test_a_missing_event_field_is_rejected():
    for field in ("v", "t", "kind", "text"):
        d = {k: x for k, x in GOOD_EVENT.items() if k != field}
        assert decode_event(pack(d)) == Rejected("version" if field == "v" else "type"), field


def test_event_payloads_that_are_not_a_map_or_too_big_are_rejected():
    assert decode_event(b"\xc1") == Rejected("malformed")
    assert decode_event(pack([1, 2, 3])) == Rejected("malformed")
    assert decode_event(pack({**GOOD_EVENT, "text": "z" * 5000})) == Rejected("oversized")
    assert event_from_dict("not a dict") == Rejected("malformed")


# ---------------------------------------------------------------------- agent stats


IDS = ("usv1", "usv2", "uav1")


def block(sent=10, dropped=2) -> dict:
    return {"sent": sent, "dropped": dropped, "dropped_by": {"loss": dropped, "burst": 0, "down": 0, "partition": 0},
            "duplicated": 0, "delayed": 1}


def faults() -> dict:
    return {"total": block(20, 4), "links": {"usv1->uav1": block(), "usv2->uav1": block()},
            "state_changes": [{"t": 2.0, "link": "usv1->uav1", "state": "down"}]}


def burst() -> dict:
    return FleetEvent.of(3.0, "link_burst", "link usv1->uav1: 12 messages dropped in a row (2.50-3.00 s)",
                         link="usv1->uav1").as_dict()


def stats() -> AgentStats:
    return AgentStats(id="uav1", tick=500, sent_to_me=1000, delivered=990, dropped=10, duplicated=2,
                      rejected=3, rejected_by_reason={"stale": 1, "sender": 2}, missed_deadlines=4,
                      joined_at=100, latencies_ms=(0.25, 1.5), faults=faults(), bursts=(burst(),))


def test_agent_stats_round_trip_into_typed_bursts_and_rebuilt_faults():
    s = stats()
    got = decode_stats(encode_stats(s), IDS)
    assert got.bursts == (BurstReport(3.0, 2.5, "usv1", "uav1", 12),)
    assert got.bursts[0].event().as_dict() == burst()  # the same text cdus.core.link writes
    assert got.faults == faults() and got.faults is not s.faults
    assert replace(got, bursts=s.bursts) == s
    assert decode_stats(encode_stats(got)) == got
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
    assert decode_stats(pack(d)) == Rejected(reason)


@pytest.mark.parametrize("bursts", [
    [{"t": "x"}], [5], ["x"], [{"t": 1.0}],
    [{**burst(), "text": "link usv1->uav1: \x1b[31m12 messages dropped"}],
    [{**burst(), "link": "usv2->uav1"}],  # the text names another link
    [{**burst(), "kind": "fleet"}],
    [{**burst(), "t": float("inf")}],
    [{**burst(), "extra": 1}],
    [burst()] * 200,
])
def test_a_stats_message_with_any_malformed_burst_is_rejected_whole(bursts):
    d = {"v": SCHEMA_VERSION, **stats().as_dict(), "bursts": bursts}
    assert decode_stats(pack(d)) == Rejected("bursts")


def test_bursts_and_links_must_name_known_vehicles_when_the_receiver_knows_them():
    assert isinstance(decode_stats(encode_stats(stats())), AgentStats)
    assert decode_stats(encode_stats(stats()), ("usv1", "uav1")) == Rejected("faults")  # usv2->uav1 in links
    assert decode_stats(encode_stats(replace(stats(), faults=None)), ("usv1", "uav1")).bursts
    assert decode_stats(encode_stats(replace(stats(), id="ghost")), IDS) == Rejected("unknown_sender")


@pytest.mark.parametrize("bad", [
    {"state_changes": 5},
    {"total": {"sent": 1000}},
    {"total": {**block(), "dropped_by": {"loss": 1}}},
    {"total": {**block(), "sent": -1}},
    {"total": {**block(), "sent": 2**60}},
    {"links": {"usv1": block()}},
    {"links": {"usv1->usv1": block()}},
    {"links": [block()]},
    {"state_changes": [{"t": "x", "link": "usv1->uav1", "state": "down"}]},
    {"state_changes": [{"t": 1.0, "link": "usv1->uav1", "state": "exploded"}]},
    {"state_changes": [{"t": 1.0, "link": "usv1->uav1", "state": "down", "x": 1}]},
    {"state_changes": [{"t": 1.0, "link": "usv1->uav1", "state": "down"}] * 100},
    {"extra": {}},
])
def test_faults_must_have_the_link_emulators_exact_shape(bad):
    d = {"v": SCHEMA_VERSION, **stats().as_dict()}
    d["faults"] = {**faults(), **bad}
    assert decode_stats(pack(d)) == Rejected("faults")
    d["faults"] = {k: x for k, x in faults().items() if k != "links"}
    assert decode_stats(pack(d)) == Rejected("faults")


def test_the_fault_shape_is_the_link_emulators():
    from cdus.core.link import LinkFaultCounters
    assert set(LinkFaultCounters().as_dict()) == {*schemas.FAULT_COUNTERS, "dropped_by"}


def test_stats_payloads_that_are_not_a_map_or_too_big_are_rejected():
    assert decode_stats(b"") == Rejected("malformed")
    assert decode_stats(pack("stats")) == Rejected("malformed")
    big = {"v": SCHEMA_VERSION, **stats().as_dict(), "latencies_ms": [1.0] * 4000}
    assert isinstance(decode_stats(pack(big)), AgentStats)  # 36 kB: within the limit
    assert decode_stats(pack({**big, "latencies_ms": [1.0] * 8000})) == Rejected("oversized")


# ---------------------------------------------------------------------- world status


def status(**over) -> bytes:
    args = dict(t=12.0, duration=250.0, clock="lockstep", alive=["usv1", "uav1"], ids=["usv1", "uav1", "uav2"],
                path_error_max=0.05, coord_error_max=0.01,
                events=[FleetEvent.of(10.0, "vehicle_lost", "vehicle uav2 lost", vehicle="uav2")], paused=False)
    args.update(over)
    return encode_status(**args)


def test_world_status_round_trips():
    st = decode_status(status())
    assert set(STATUS_KEYS) <= set(WorldStatus.__dataclass_fields__)  # every field a status carries, typed
    with pytest.raises(TypeError):  # no map view: a reader takes the typed fields (it offered st["t"] too)
        st["t"]
    assert st.t == 12.0 and st.duration == 250.0 and st.clock == "lockstep"
    assert st.alive == ["usv1", "uav1"] and st.ids == ["usv1", "uav1", "uav2"]
    assert st.path_error_max == 0.05 and st.coord_error_max == 0.01
    assert st.events == [FleetEvent.of(10.0, "vehicle_lost", "vehicle uav2 lost", vehicle="uav2")]
    assert st.paused is False
    assert decode_status(status(paused=True)).paused is True


def test_status_of_an_empty_run_carries_no_errors():
    st = decode_status(status(path_error_max=None, coord_error_max=float("nan"), events=[]))
    assert st.path_error_max is None and st.coord_error_max is None and st.events == []


def test_status_drops_malformed_events_but_keeps_the_rest():
    d = msgpack.unpackb(status(), raw=False)
    d["events"].append({"t": "soon", "kind": "fleet", "text": "?"})
    st = decode_status(pack(d))
    assert len(st.events) == 1


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
    assert decode_status(pack(d)) == Rejected(reason)


def test_status_payloads_that_are_not_a_map_or_too_big_are_rejected():
    assert decode_status(b"\x91") == Rejected("malformed")
    assert decode_status(b"\x00" * ((1 << 16) + 1)) == Rejected("oversized")


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
            assert isinstance(out, (Rejected, FleetEvent, AgentStats, WorldStatus))
            if isinstance(out, FleetEvent):
                assert math.isfinite(out.t) and out.kind in EVENT_KINDS


# ---------------------------------------------------------------------- property-based

from hypothesis import given, settings, strategies as hs  # noqa: E402

_scalars = hs.one_of(hs.none(), hs.booleans(), hs.integers(min_value=-2**64, max_value=2**64),
                     hs.floats(allow_nan=True, allow_infinity=True), hs.text(max_size=40), hs.binary(max_size=20))
_values = hs.recursive(_scalars, lambda inner: hs.one_of(hs.lists(inner, max_size=5),
                                                          hs.dictionaries(hs.text(max_size=12), inner, max_size=5)),
                       max_leaves=30)
_FIELDS = [*AgentStats.__dataclass_fields__, *STATUS_KEYS, "v", "kind", "text", "severity", "vehicle", "link",
           "origin", "t"]


def _mutated(base: dict):
    return hs.dictionaries(hs.sampled_from(_FIELDS), _values, max_size=4).map(lambda over: {**base, **over})


@settings(max_examples=400, deadline=None)
@given(hs.one_of(_mutated({"v": SCHEMA_VERSION, **stats().as_dict()}),
                 _mutated(msgpack.unpackb(status(), raw=False)), _mutated(GOOD_EVENT)),
       hs.sampled_from([None, IDS]))
def test_no_decoder_raises_and_what_passes_is_typed_and_bounded(d, ids):
    try:
        payload = pack(d)
    except (TypeError, ValueError, OverflowError):
        return
    for decode in (decode_event, decode_stats, decode_status):
        out = decode(payload, ids)
        if isinstance(out, Rejected):
            assert out.reason.isidentifier()
        elif isinstance(out, FleetEvent):
            assert math.isfinite(out.t) and out.kind in EVENT_KINDS and "\x1b" not in out.text
        elif isinstance(out, AgentStats):
            assert all(isinstance(b, BurstReport) and math.isfinite(b.t) for b in out.bursts)
            assert out.faults is None or set(out.faults) == {"total", "links", "state_changes"}
            assert ids is None or out.id in ids
            assert all(type(x) is int and 0 <= x < 2**53 for x in out.rejected_by_reason.values())
        else:  # a status whose every field is what WorldStatus says: a reader needs no check of its own
            assert isinstance(out, WorldStatus)
            assert math.isfinite(out.t) and -1 <= out.t <= 1e9 and out.clock in ("lockstep", "realtime")
            assert set(out.alive) <= set(out.ids) and all(isinstance(e, FleetEvent) for e in out.events)
            assert all(x is None or math.isfinite(x) and x >= 0 for x in (out.path_error_max, out.coord_error_max))
            assert type(out.paused) is bool and (out.roster is None or set(out.roster) <= set(out.ids))


@settings(max_examples=300, deadline=None)
@given(hs.binary(max_size=300))
def test_no_decoder_raises_on_arbitrary_bytes(payload):
    for decode in (decode_event, decode_stats, decode_status):
        assert isinstance(decode(payload), (Rejected, FleetEvent, AgentStats, WorldStatus))


def test_an_event_text_from_the_wire_comes_out_escaped():
    e = decode_event(pack({**GOOD_EVENT, "text": "\x1b[2J\x1b[31mfake\nt = 1.00 s: forged"}))
    assert "\x1b" not in e.text and "\n" not in e.text and "\\x1b" in e.text
    assert decode_event(pack({**GOOD_EVENT, "vehicle": "usv9"}), IDS) == Rejected("unknown_sender")
    assert decode_event(pack({**GOOD_EVENT, "t": 1e308})) == Rejected("range")
    assert decode_status(status(t=1e308)) == Rejected("range")


def test_agent_stats_as_dict_is_asdict_with_its_containers_copied():
    # as_dict is built field by field (dataclasses.asdict deep-copied every leaf: the most of an
    # agent's once-a-second report); it must give what asdict gave, and share no container
    import dataclasses

    from cdus.wire.schemas import AgentStats

    faults = {"total": {"sent": 3, "dropped_by": {"loss": 1}}, "links": {"a->b": {"sent": 3}},
              "state_changes": [{"t": 0.5, "link": "a->b", "state": "down"}]}
    burst = {"t": 1.0, "kind": "link_burst", "text": "x"}
    s = AgentStats(id="a", tick=7, rejected_by_reason={"stale": 2}, latencies_ms=(1.0, 2.5), faults=faults,
                   bursts=(burst,), interventions=1, incarnation=9)
    d = s.as_dict()
    ref = dataclasses.asdict(s)
    ref["latencies_ms"] = list(s.latencies_ms)
    ref["bursts"] = [burst]
    ref["odometry_gaps"] = []  # a robot's spells, as their own as_dict writes them (tests/ros2/test_robot.py)
    assert d == ref and list(d) == list(ref)
    d["rejected_by_reason"]["stale"] = 99
    d["faults"]["total"]["dropped_by"]["loss"] = 99
    d["faults"]["state_changes"].append({})
    assert s.rejected_by_reason == {"stale": 2} and faults["total"]["dropped_by"]["loss"] == 1
    assert len(faults["state_changes"]) == 1
    assert AgentStats(id="b", tick=0).as_dict()["faults"] is None


@settings(max_examples=200, deadline=None)
@given(interventions=hs.integers(0, 2**53 - 1), deflected=hs.integers(0, 2**53 - 1))
def test_stats_with_more_deflected_steps_than_interventions_are_refused(interventions, deflected):
    """An obstacle deflects a vehicle only at a step its filter changed the reference
    (cdus.core.vehicle): a ``deflected`` above ``interventions`` is forged, and dropped whole
    (it would have set the metrics' deflected_s; tests/world_sim/test_world.py counts it)."""
    got = decode_stats(encode_stats(replace(stats(), interventions=interventions, deflected=deflected)), IDS)
    if deflected <= interventions:
        assert isinstance(got, AgentStats) and (got.interventions, got.deflected) == (interventions, deflected)
    else:
        assert got == Rejected("deflected")
