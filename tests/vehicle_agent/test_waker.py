"""vehicle_agent.waker: when the main thread is woken: at its alarm (never early) and at a signal."""

from __future__ import annotations

import os
import threading
import time

from vehicle_agent.waker import Waker


def _started() -> tuple[Waker, list[float], threading.Event]:
    pokes: list[float] = []
    poked = threading.Event()
    w = Waker(lambda: (pokes.append(time.time()), poked.set()))
    w.start()
    return w, pokes, poked


def test_the_waker_pokes_at_its_alarm_never_before_and_then_forgets_it():
    w, pokes, poked = _started()
    try:
        alarm = time.time() + 0.05
        w.alarm = alarm
        w.interrupt()
        assert poked.wait(30.0)
        assert pokes[0] >= alarm and w.alarm is None
    finally:
        w.close()
        w.join(30.0)


def test_a_signal_number_on_the_wakeup_fd_pokes_at_once_and_an_interrupt_does_not():
    w, pokes, poked = _started()
    try:
        w.interrupt()  # re-read the alarm (none): no poke
        os.write(w.wfd, b"\x0f")  # what signal.set_wakeup_fd writes for SIGTERM
        assert poked.wait(30.0)
        assert len(pokes) == 1
    finally:
        w.close()
        w.join(30.0)
    assert not w.is_alive()
