"""When must the agent's main thread wake? The waker: a small thread that pokes the agent's own
inbox (a session-local put on its ``wake`` key) so a blocking wait returns, at an alarm and when a
signal arrives (``signal.set_wakeup_fd(waker.wfd)``)."""

from __future__ import annotations

import os
import select
import threading
import time
from typing import Callable

import zenoh


class Waker(threading.Thread):
    """Pokes the agent's own inbox (a session-local put) so its blocking wait returns: at an
    ``alarm`` (wall s) and when a signal arrives (``signal.set_wakeup_fd(waker.wfd)``). The
    realtime loop needs no poke at its tick times: it naps to them (vehicle_agent.realtime)."""

    def __init__(self, put: Callable[[], None]):
        super().__init__(daemon=True, name="waker")
        self.put = put
        self.alarm: float | None = None
        self.closed = False
        self.rfd, self.wfd = os.pipe()
        os.set_blocking(self.wfd, False)

    def interrupt(self) -> None:
        """Re-read the alarm now."""
        os.write(self.wfd, b"\xff")

    def close(self) -> None:
        self.closed = True
        self.interrupt()

    def run(self) -> None:
        while not self.closed:
            now = time.time()
            deadline = self.alarm
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
