"""The radio on the wire: the geometry key, the agent stats' radio counters (checked, rebuilt,
counted as ``radio`` when bad), the radio command ops."""

from __future__ import annotations

import msgpack
import pytest

from cdus.core.radio import RadioCounters
from cdus.wire import keys, schemas
from cdus.wire.access import fleet_acl
from cdus.wire.messages import COMMAND_OPS, CTL_OPS, decode_control, encode_control
from cdus.wire.schemas import AgentStats, decode_stats, encode_stats
from cdus.wire.rejected import Rejected


def test_the_geometry_key_reaches_every_addressed_vehicle_and_the_world_may_put_it():
    key = keys.radio("f", ["usv1", "uav1"])
    assert key == "cdus/f/to/+usv1+uav1+/radio" and keys.leaf(key) == ("radio", "")
    acl = fleet_acl("f", {"usv1": ("uav1",), "uav1": ("usv1",)})
    world_put = next(r for r in acl["rules"] if r["id"] == "world-put")
    assert "cdus/f/to/*/radio" in world_put["key_exprs"]


def test_agent_stats_carry_the_radio_counters_checked():
    c = RadioCounters(sent=10, delivered=6, fault=1, range=2, collision=1, no_geometry=3)
    s = AgentStats("usv1", 5, radio=c.as_dict())
    back = decode_stats(encode_stats(s), ["usv1"])
    assert back.radio == c.as_dict() and RadioCounters.from_dict(back.radio) == c
    assert decode_stats(encode_stats(AgentStats("usv1", 5)), ["usv1"]).radio is None
    d = {"v": 1, **AgentStats("usv1", 5).as_dict()}
    for bad in ({**c.as_dict(), "extra": 1}, {**c.as_dict(), "sent": -1}, {**c.as_dict(), "sent": 1.5},
                {**c.as_dict(), "dropped_by": {"range": 1}}, [1, 2], "x", {**c.as_dict(), "no_geometry": 2**60}):
        assert decode_stats(msgpack.packb({**d, "radio": bad}), ["usv1"]) == Rejected("radio"), bad


@pytest.mark.parametrize("ops", [CTL_OPS, COMMAND_OPS])
def test_the_radio_op_decodes_with_its_table_and_time(ops):
    c = decode_control(encode_control("radio", radio={"tx_power": 3}, at=2), ops)
    assert c.op == "radio" and c.fields == {"radio": {"tx_power": 3}, "at": 2.0}
    assert decode_control(encode_control("radio", radio=[1], at=2.0), ops) == Rejected("type")
    assert decode_control(encode_control("radio", radio={}, at=float("inf")), ops) == Rejected("non_finite")


def test_a_geometry_sample_gives_each_vehicle_its_own_dimension_or_is_rejected():
    from cdus.wire.messages import GeometryMsg, decode_geometry, encode_geometry
    dims = [2, 3, 2]
    good = GeometryMsg(4, ((1.0, 2.0), (3.0, 4.0, 30.0), None))
    assert decode_geometry(encode_geometry(good), 3, dims) == good
    for bad in (((1.0, 2.0, 5.0), (3.0, 4.0, 30.0), None),  # a boat lifted 5 m off the water
                ((1.0, 2.0), (3.0, 4.0), None)):  # a drone put on the water
        assert decode_geometry(encode_geometry(GeometryMsg(4, bad)), 3, dims) == Rejected("dimension")
        assert decode_geometry(encode_geometry(GeometryMsg(4, bad)), 3) == GeometryMsg(4, bad)  # not checked
    assert decode_geometry(encode_geometry(good), None, [2, 3]) == Rejected("count")


def test_the_largest_sample_a_fleet_can_send_decodes():
    """The world's sample for the largest fleet the config takes (MAX_VEHICLES drones, every
    coordinate at the bound) is one every vehicle decodes: raising MAX_VEHICLES past what the
    geometry decoder takes would make each agent refuse the world's own samples and a lockstep
    fleet wait for them for ever."""
    from cdus.scenario.vehicles import MAX_VEHICLES
    from cdus.wire.messages import MAX_COORDINATE, MAX_GEOMETRY_VEHICLES, GeometryMsg, decode_geometry, encode_geometry

    assert MAX_GEOMETRY_VEHICLES >= MAX_VEHICLES
    big = GeometryMsg(2**31 - 1, tuple((-MAX_COORDINATE, MAX_COORDINATE, -MAX_COORDINATE) for _ in range(MAX_VEHICLES)))
    assert decode_geometry(encode_geometry(big), MAX_VEHICLES, [3] * MAX_VEHICLES) == big


def test_each_geometry_reject_has_its_exact_reason():
    """Found by mutmut (cdus.wire.messages.decode_geometry): a reason could be any string, or
    None, and the tests that only read the agent's ``radio_`` prefix passed."""
    import math

    from cdus.wire.messages import MAX_COORDINATE, MAX_GEOMETRY_VEHICLES, GeometryMsg, decode_geometry
    cases = {
        "type": [msgpack.packb([1, -1, []]), msgpack.packb([1, 1.0, []]), msgpack.packb([1, 4, {}]),
                 msgpack.packb([1, 4, [[1.0]]]), msgpack.packb([1, 4, [[1, 2]]]), msgpack.packb([1, 4, [7]])],
        "non_finite": [msgpack.packb([1, 4, [[1.0, math.nan]]])],
        "range": [msgpack.packb([1, 4, [[2 * MAX_COORDINATE, 0.0]]])],
        "count": [msgpack.packb([1, 4, [[1.0, 2.0]]])],
        "version": [msgpack.packb([2, 4, []])],
        "malformed": [b"\xc1", msgpack.packb([1, 4])],
        "oversized": [b"\x00" * (30 * MAX_GEOMETRY_VEHICLES + 33)],
    }
    for reason, payloads in cases.items():
        for p in payloads:
            assert decode_geometry(p, 3 if reason == "count" else None) == Rejected(reason), (reason, p)
    assert decode_geometry(msgpack.packb([1, 0, [[1.0, 2.0], None]])) == GeometryMsg(0, ((1.0, 2.0), None))
    assert decode_geometry(msgpack.packb([1, 4, [[1.0, 2.0]]]), 1) == GeometryMsg(4, ((1.0, 2.0),))
