"""cdus.commands.effect: the one effect-tick rule."""

from __future__ import annotations

import pytest

from cdus.commands.effect import LEAD_S, effect_tick, effect_time, lead_ticks, never_applies, tick_of


def test_the_effect_tick_is_one_rule_for_both_clocks():
    assert LEAD_S == 0.5
    assert effect_tick(41, 1) == 42  # lockstep: past the grant
    assert lead_ticks(0.02) == 25 and lead_ticks(1.0) == 1 and lead_ticks(0.5) == 1 and lead_ticks(0.3) == 2
    assert lead_ticks(0.1, 0.05) == 1 and lead_ticks(0.1, 0.3) == 3
    assert effect_tick(100, lead_ticks(0.02)) == 125  # realtime: 0.5 s ahead of the wall clock's tick
    assert effect_tick(0, 0) == 1 and effect_tick(0, 3) == 3
    # nothing granted yet (lockstep's -1), a realtime clock not started (its tick negative): tick 0,
    # as the world's clocks said before they called this rule
    assert effect_tick(-1, 1) == 0 and effect_tick(-40, 25) == 0 and effect_tick(-10, 25) == 15


def test_a_change_named_in_time_never_before_the_effect_tick():
    assert effect_time(None, 41, 1, 0.1) == (pytest.approx(4.2), "")
    assert effect_time(9.0, 41, 1, 0.1) == (9.0, "")
    assert effect_time(4.2, 41, 1, 0.125) == (pytest.approx(5.25), "t = 4.2 s asked had passed: from the first "
                                              "time every vehicle can take it")
    assert effect_time(5.25, 41, 1, 0.125) == (5.25, "")


def test_ticks_of_times_and_the_runs_end():
    assert tick_of(0.3, 0.1) == 3 and tick_of(0.30000000000000004, 0.1) == 3 and tick_of(0.31, 0.1) == 4
    assert tick_of(-5.0, 0.1) == 0
    assert never_applies(10, 10, 0.1) is None
    assert never_applies(11, 10, 0.1).reason == ("the run's last tick is 10 (t = 1.00 s) and the first this change "
                                                 "could apply from is 11: it would never apply (the run is ending)")
