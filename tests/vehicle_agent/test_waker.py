"""vehicle_agent.waker: when the main thread is woken."""

import pytest

from vehicle_agent.waker import Waker


def test_the_waker_deadline_is_the_next_tick_or_the_alarm():
    w = Waker(lambda: None, 0.02)
    assert w._deadline(5.0) is None
    w.t0 = 1.0
    assert w._deadline(1.03) == pytest.approx(1.04)
    w.alarm = 1.035
    assert w._deadline(1.03) == 1.035
