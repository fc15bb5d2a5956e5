"""When must the agent's main thread wake? The waker: a small thread that pokes the agent's own
inbox (a session-local put on its ``wake`` key) so a blocking wait returns, at an alarm and when a
signal arrives (``signal.set_wakeup_fd(waker.wfd)``)."""

from __future__ import annotations

import math
import os
import select
import threading
import time
from typing import Callable

import zenoh


class Waker(threading.Thread):
    """Pokes the agent's own inbox (a session-local put) so its blocking wait returns: at every
    tick time ``t0 + n T`` of the realtime clock (when ``t0`` is set), at an ``alarm``, and
    when a signal arrives (``signal.set_wakeup_fd(waker.wfd)``)."""

    def __init__(self, put: Callable[[], None], period: float):
        super().__init__(daemon=True, name="waker")
        self.put = put
        self.period = period
        self.t0: float | None = None  # the realtime clock's origin (wall s), None: no ticking
        self.alarm: float | None = None
        self.closed = False
        self.rfd, self.wfd = os.pipe()
        os.set_blocking(self.wfd, False)

    def interrupt(self) -> None:
        """Re-read t0 and the alarm now."""
        os.write(self.wfd, b"\xff")

    def close(self) -> None:
        self.closed = True
        self.interrupt()

    def _deadline(self, now: float) -> float | None:
        t0, alarm = self.t0, self.alarm
        tick = None if t0 is None else t0 + (math.floor((now - t0) / self.period) + 1) * self.period
        return min((d for d in (tick, alarm) if d is not None), default=None)

    def run(self) -> None:
        while not self.closed:
            now = time.time()
            deadline = self._deadline(now)
            ready, _, _ = select.select([self.rfd], [], [], None if deadline is None else max(0.0, deadline - now))
            if ready:
                data = os.read(self.rfd, 64)
                if data.strip(b"\xff") and not self.poke():  # a signal number: wake the main thread
                    return
                continue
            while time.time() < deadline:  # never early: the main loop compares with the same clock
                time.sleep(deadline - time.time())
            if self.alarm is not None and time.time() >= self.alarm:
                self.alarm = None
            if not self.poke():
                return

    def poke(self) -> bool:
        """Wake the main loop; False once the session is closed (the agent is exiting)."""
        try:
            self.put()
        except zenoh.ZError:
            return False
        return True
