"""cdus.commands.gains: the gains rule, written once."""

from __future__ import annotations

import math

import pytest

from cdus.commands.base import Applied, Rejected
from cdus.commands.gains import MAX_AXES, Gains, expand_k, gains_table

from .common import RecordedNode


def test_expand_k_is_the_one_per_axis_expansion():
    assert expand_k(2.0, 3) == (2.0, 2.0, 2.0) and expand_k((1.0, 2.0), 2) == (1.0, 2.0) and expand_k(2, 2) == (2.0, 2.0)
    assert type(expand_k(2, 2)[0]) is float


@pytest.mark.parametrize("raw, one, out", [
    ({"k": 2}, False, (2.0, None)),
    ({"c": 0.5}, False, (None, 0.5)),
    ({"k": [1, 2]}, True, ((1.0, 2.0), None)),
    ({"k": [1, 2, 3]}, True, ((1.0, 2.0, 3.0), None)),
    ({"k": 1e300, "c": 1e-300}, False, (1e300, 1e-300)),
    (None, False, Rejected("must be a table of k and/or c, e.g. { k = 2.0, c = 0.5 }, got None", "gains")),
    ({}, False, Rejected("changes nothing; give k=... and/or c=...", "gains")),
    ({"x": 1}, False, Rejected("unknown gain; gains are k (a number or, for one vehicle, one per axis) and c", "x")),
    ({"k": [1, 2]}, False, Rejected("one value per axis needs one vehicle named (--vehicle): boats have 2 axes, "
                                    "drones 3; a single number sets every axis", "k")),
    ({"k": []}, True, Rejected("must be 1 to 3 finite numbers > 0 (one per axis), got []", "k")),
    ({"k": [1, 1, 1, 1]}, True, Rejected("must be 1 to 3 finite numbers > 0 (one per axis), got [1, 1, 1, 1]", "k")),
    ({"k": [1, -1]}, True, Rejected("must be 1 to 3 finite numbers > 0 (one per axis), got [1, -1]", "k")),
    ({"k": 0}, False, Rejected("must be a finite number > 0, got 0", "k")),
    ({"k": True}, False, Rejected("must be a finite number > 0, got True", "k")),
    ({"k": math.inf}, False, Rejected("must be a finite number > 0, got inf", "k")),
    ({"c": 0.0}, False, Rejected("must be a finite number > 0, got 0", "c")),
    ({"c": "1"}, False, Rejected("must be a finite number > 0, got '1'", "c")),
])
def test_the_gains_table(raw, one, out):
    assert gains_table(raw, one_vehicle=one) == out
    assert MAX_AXES == 3


def test_the_command_reads_its_vehicle_and_says_its_fields():
    assert Gains.parse({"gains": {"k": 2}, "vehicle": ""}) == Gains(2.0, None, None)
    assert Gains.parse({"gains": {"k": 2}}) == Gains(2.0, None, None)
    assert Gains.parse({"gains": {"k": [1, 2]}, "vehicle": "usv1"}) == Gains((1.0, 2.0), None, "usv1")
    assert Gains.parse({"gains": {"k": 2}, "vehicle": "a b"}).field == "vehicle"
    assert Gains.parse({"gains": {"k": 2}, "x": 1}).field == "x"
    assert Gains.parse({"gains": 3}).field == "gains"
    assert Gains((1.0, 2.0), 0.5, "usv1").fields() == {"gains": {"k": [1.0, 2.0], "c": 0.5}, "vehicle": "usv1"}
    assert Gains(2.0, None).fields() == {"gains": {"k": 2.0}, "vehicle": ""}
    assert Gains(None, 0.5).fields() == {"gains": {"c": 0.5}, "vehicle": ""}


def test_the_vehicle_rule():
    g = Gains((1.0, 2.0), None, "usv1")
    assert g.for_vehicle(3, (1.0, 1.0, 1.0), 1.0) == Rejected("must be 3 numbers > 0 for this vehicle, got [1.0, 2.0]", "k")
    assert g.for_vehicle(2, (5.0, 5.0), 0.7) == ((1.0, 2.0), 0.7)
    assert Gains(3.0, None).for_vehicle(3, (5.0, 5.0, 5.0), 0.7) == ((3.0, 3.0, 3.0), 0.7)
    too = Gains(100.0, None).for_vehicle(2, (1.0, 1.0), 1.0, control_hz=10.0)
    assert isinstance(too, Rejected) and too.field is None and too.reason.startswith("k = 100 is too large")
    assert Gains(19.0, None).for_vehicle(2, (1.0, 1.0), 1.0, control_hz=10.0) == ((19.0, 19.0), 1.0)
    assert Gains(None, 0.3).for_vehicle(2, (1.0, 1.0), 1.0, control_hz=10.0) == ((1.0, 1.0), 0.3)
    assert Gains(None, 6.0).for_vehicle(2, (1.0, 1.0), 1.0, control_hz=10.0, weight_sum=2.0).reason.startswith("c = 6")
    assert Gains(5.0, None).for_vehicle(2, (1.0, 1.0), 1.0, control_hz=10.0, plant="usv_3dof",
                                        physics_hz=2.0).reason.startswith("k = 5 is too large for the physics rate")


def test_applied_to_a_node():
    n = RecordedNode()
    assert Gains(2.0, None).apply(n, 8) == Applied(8) and n.calls == [("gains", (2.0, 2.0), 1.0, 8)]
    assert isinstance(Gains(50.0, None).apply(n, 9), Rejected) and len(n.calls) == 1  # k·T >= 2 at 10 Hz
    assert Gains(50.0, None).apply(n, 9, {"control_hz": 100.0}) == Applied(9)
    assert n.calls[-1] == ("gains", (50.0, 50.0), 1.0, 9)
    n.table.links = (type("L", (), {"weight": 4.0})(),)
    assert Gains(None, 3.0).apply(n, 10).reason.startswith("c = 3 is too large")  # rate / Σa = 10 / 4
