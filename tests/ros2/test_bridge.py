"""cdus.ros2.bridge.Republisher: the fleet's samples into ROS 2 messages, and hostile ones counted
and dropped (Hypothesis), without a Zenoh session."""

from __future__ import annotations

import json

from hypothesis import given, settings, strategies as st

from cdus.ros2 import cdr, fleet as rf
from cdus.ros2.bridge import Republisher
from cdus.scenario.config import load_scenario
from cdus.wire import keys
from cdus.wire.messages import StateMsg, encode_states
from cdus.wire.schemas import FleetEvent, encode_event
from tests.e2e.conftest import ROOT

SC = load_scenario(ROOT / "configs" / "lake_circle.toml", {"ros2.enabled": True, "ros2.rate": 25.0})
T = 1 / 50.0


def republisher():
    out: list[tuple] = []
    return Republisher(SC, "f", lambda which, value: out.append((which, value))), out


def row(sender: int, tick: int, q=(1.0, 2.0), t=None) -> StateMsg:
    return StateMsg(sender, tick, tick * T if t is None else t, q, 0.5, 1.5, 3.0, -1.0, 0.1)


def test_rows_become_clock_once_per_tick_and_vehicle_topics_at_the_rate():
    r, out = republisher()
    for tick in range(4):
        for j, vid in enumerate(SC.ids[:2]):
            r.handle(keys.state("f", vid), encode_states([row(j, tick)]))
    clocks = [v["clock"] for w, v in out if w == (None, "clock")]
    assert clocks == [rf.stamp(n * T) for n in range(4)]  # one per tick, whoever reports it first
    assert [w for w, _ in out if w[0] == "usv2"] == [("usv2", f) for f in ("pose", "odom", "omega", "omega_rate")] * 2
    for which, value in out:  # every message encodes as its topic's type
        cdr.encode({t.field: t.type_name for t in rf.topics(SC.ros2, SC.ids)}[which[1]], value)
    assert r.rejected == {}


def test_an_event_is_published_as_json():
    r, out = republisher()
    e = FleetEvent.of(1.5, "fleet", "fleet paused by gs")
    r.handle(keys.world_events("f"), encode_event(e))
    assert [(w, json.loads(v["data"])) for w, v in out] == [((None, "events"), e.as_dict())]


def test_forged_rows_are_counted_and_dropped():
    r, out = republisher()
    r.handle(keys.state("f", "usv1"), encode_states([row(1, 3)]))  # usv2's row on usv1's key
    r.handle(keys.state("f", "nobody"), encode_states([row(0, 3)]))
    r.handle(keys.state("f", "usv1"), encode_states([row(0, 12_501)]))  # past the last tick (250 s): it would stop /clock
    r.handle(keys.state("f", "usv1"), encode_states([row(0, 5, t=99.0)]))
    r.handle(keys.state("f", "usv1"), encode_states([row(0, 2**40, t=2**40 * T)]))  # past int32 seconds
    assert out == []
    assert r.rejected == {"state wrong_sender": 1, "state unknown_sender": 1, "state tick_time": 3}
    r.handle(keys.state("f", "usv1"), encode_states([row(0, 1)]))
    r.handle(keys.state("f", "usv2"), encode_states([row(1, 1)]))
    assert [v for w, v in out if w == (None, "clock")] == [{"clock": rf.stamp(T)}]


def test_one_vehicle_cannot_move_or_freeze_the_clock():
    """A vehicle's own credentials may publish its own telemetry. Before, one row of it at the
    run's last tick (within the run, the time its tick's) became /clock, and /clock never
    published again (seen on a secured realtime lake_circle: 75 /clock messages in the 2 s
    before, 0 in the 2.8 s after). /clock now waits for a second live vehicle."""
    r, out = republisher()
    clocks = lambda: [v["clock"] for w, v in out if w == (None, "clock")]  # noqa: E731
    r.handle(keys.state("f", "usv1"), encode_states([row(0, 12_000)]))  # forged, before anyone else reports
    assert clocks() == [] and r.rejected == {}
    for tick in range(3):
        for j, vid in enumerate(SC.ids[:3]):
            r.handle(keys.state("f", vid), encode_states([row(j, tick)]))
    assert clocks() == [rf.stamp(n * T) for n in range(3)]  # the fleet's ticks, not the forged one
    for vid in SC.ids[1:5]:  # all but usv1 and uav3 killed: two live, still the second newest
        r.gone(vid)
    r.handle(keys.state("f", "uav3"), encode_states([row(5, 3)]))
    assert clocks()[-1] == rf.stamp(3 * T)
    r.gone("uav3")  # usv1 alone is the fleet: its clock is the fleet's
    assert clocks()[-1] == rf.stamp(12_000 * T)


@settings(max_examples=200, deadline=None)
@given(payload=st.binary(max_size=300), events=st.booleans(),
       vid=st.sampled_from(list(SC.ids) + ["x"]))
def test_any_bytes_never_raise(payload, events, vid):
    r, out = republisher()
    r.handle(keys.world_events("f") if events else keys.state("f", vid), payload)
    assert out == [] or r.rejected == {}
    assert sum(r.rejected.values()) <= 1


@settings(max_examples=100, deadline=None)
@given(tick=st.integers(0, 2**40), t=st.floats(-1e12, 1e12, allow_nan=False),
       q=st.tuples(st.floats(-1e300, 1e300), st.floats(-1e300, 1e300)))
def test_any_finite_row_publishes_or_is_rejected(tick, t, q):
    r, out = republisher()
    r.handle(keys.state("f", "usv1"), encode_states([row(0, tick, q, t)]))
    assert not (out and r.rejected)  # published or rejected, never both
    assert bool(out) or bool(r.rejected) or tick % r.every  # a row of an off-rate tick alone: /clock waits


class _Token:
    def __init__(self, key: str, up: bool):
        self.key_expr, self.kind = key, "SampleKind.PUT" if up else "SampleKind.DELETE"


def test_the_bridge_stops_when_the_worlds_own_tokens_go_not_a_forged_one():
    """The bridge runs until the world is gone. Only tokens exactly as keys.alive makes them are
    the world's (issue 27, broken 4): a wildcard token held then dropped on an open fleet, or
    another process's, must not stop it; the world's last session's token going does."""
    import threading

    from cdus.ros2.bridge import Bridge

    b = Bridge.__new__(Bridge)  # its liveliness handling alone, without a session
    b.cond, b.world_seen, b.world_tokens, b.stop = threading.Condition(), False, set(), False
    world, other = keys.alive("f", keys.WORLD, "a1b2"), keys.alive("f", "usv1", "c3d4")
    for key, up in ((world, True), ("cdus/f/alive/**", True), ("cdus/f/alive/**", False),
                    (other, True), (other, False), ("cdus/f/alive/world", False)):
        b._on_world(_Token(key, up))
        assert not b.stop, key
    b._on_world(_Token(world, False))
    assert b.stop
