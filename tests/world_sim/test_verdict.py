"""world_sim.verdict: what the world made of one command."""

from __future__ import annotations

from world_sim.verdict import LATER, Verdict


def test_a_refusal_is_not_applied_and_carries_its_reason_and_no_tick():
    v = Verdict.no("the fleet is already paused")
    assert (v.applied, v.reason, v.tick, v.t) == (False, "the fleet is already paused", None, None)


def test_an_applied_verdict_keeps_its_tick_and_time_and_is_frozen():
    v = Verdict(True, "", 7, 0.14)
    assert (v.applied, v.tick, v.t) == (True, 7, 0.14)
    try:
        v.tick = 8  # type: ignore[misc]
    except AttributeError:
        pass
    else:
        raise AssertionError("a Verdict must be frozen")


def test_later_is_a_sentinel_told_apart_by_identity_not_by_value():
    same = Verdict(True, "decided when its tick comes")
    assert same == LATER and same is not LATER and LATER.applied
