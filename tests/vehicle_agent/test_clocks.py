"""vehicle_agent.clocks: the clock's strategy picked once by its name, and what the world has said
about time."""

from __future__ import annotations

import pytest

from cdus.core.schedule import CLOCKS
from vehicle_agent.clocks import STRATEGIES, Clock, pick
from vehicle_agent.lockstep import Lockstep
from vehicle_agent.realtime import Realtime


def test_each_clock_name_picks_its_strategy():
    assert tuple(STRATEGIES) == CLOCKS
    assert type(pick("lockstep", 10.0)) is Lockstep and type(pick("realtime", 10.0)) is Realtime


def test_an_unknown_clock_is_refused_naming_the_choices():
    with pytest.raises(ValueError, match=r"clock must be one of \('lockstep', 'realtime'\), got 'wall'"):
        pick("wall", 10.0)


def test_a_new_clock_has_heard_nothing_from_the_world():
    c = Clock()
    assert (c.begun, c.join, c.granted, c.t0, c.paused, c.stop) == (False, 0, -1, None, False, False)
