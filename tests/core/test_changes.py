"""The run-time changes of a node and their outcomes (cdus.core.changes): Applied from a tick, or
Refused with the reason, never an exception and never read off a counter."""

from __future__ import annotations

from hypothesis import given, settings, strategies as st

from cdus.core.changes import Applied, Refused
from cdus.core.link import IdealLink, LinkEmulator
from cdus.scenario.paths import make_path
from cdus.scenario.config import parse_scenario
from cdus.sim.build import build_node

RING = {
    "scenario": {"name": "ring2", "duration": 2.0},
    "vehicle": [
        {"id": f"v{j}", "kind": "usv", "phase": 1.0 * j, "path": {"family": "circle", "center": [0, 0], "radius": 10}}
        for j in range(2)
    ],
}
T = 1 / 50


def node(link=None):
    sc = parse_scenario(RING)
    return build_node(sc, "v0", link or IdealLink()), sc


def test_each_change_says_the_tick_it_applies_from():
    n, sc = node()
    for t in range(3):
        n.step(t)
    assert n.set_gains((2.0, 2.0), 1.0, tick=5) == Applied(5)
    assert n.set_gains((2.0, 2.0), 1.0, tick=1) == Applied(3)  # past: the next tick stepped
    assert n.set_formation({1: 0.5}, 4) == Applied(4)
    assert n.set_path(make_path({"family": "circle", "center": [1, 0], "radius": 5.0}), 7) == Applied(7)
    assert n.set_policy("extrapolate", 1.0, 6) == Applied(6)


def test_a_link_change_says_when_it_applies_and_an_ideal_link_refuses_it():
    sc = parse_scenario(RING)
    n = build_node(sc, "v0", LinkEmulator(sc.link, sc.ids, 1))
    assert n.set_link(sc.link, 0.5) == Applied(25, 0.5)
    assert n.set_link(sc.link, 0.1) == Applied(25, 0.5)  # not before the newest change
    refused = node()[0].set_link(sc.link, 0.5)
    assert refused == Refused("this vehicle's link model cannot change at run time") and not refused


def test_refusals_name_the_reason_and_schedule_nothing():
    n, _ = node()
    assert n.set_policy("hodl", 1.0, 2) == Refused(
        "policy: unknown stale-neighbour policy 'hodl'; known: hold, timeout, extrapolate")
    assert n.set_policy("timeout", 0.0, 2) == Refused("the policy's timeout must be > 0 s, got 0.0")
    assert not n.set_gains((1.0, 1.0), -1.0, 2) and not n.set_gains((1.0,), 1.0, 2)
    assert not n.set_path(make_path({"family": "circle", "center": [0, 0, 1], "radius": 3.0}), 2)
    assert not n._policies and not n._gains and not n._paths
    for t in range(4):
        n.step(t)
    assert n.table.policy == "hold" and n.vehicle.c == 2.0


@settings(max_examples=60, deadline=None)
@given(k=st.lists(st.floats(allow_nan=True, allow_infinity=True, width=32), min_size=0, max_size=3),
       c=st.floats(allow_nan=True, allow_infinity=True, width=32), tick=st.integers(0, 100))
def test_a_gains_change_is_applied_exactly_when_its_values_are_valid(k, c, tick):
    n, _ = node()
    outcome = n.set_gains(tuple(k), c, tick)
    valid = len(k) == 2 and all(x > 0 for x in k) and c > 0
    assert bool(outcome) == valid
    assert outcome == (Applied(tick) if valid else outcome) and (valid or isinstance(outcome, Refused))
    assert len(n._gains) == (1 if valid else 0)
