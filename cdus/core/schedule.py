"""When does what happen? Control ticks, ω broadcasts and message deliveries.

Shared by the in-process fleet and the agents so both follow one timetable:
tick n is at t_n = n T (T = 1 / control rate); vehicles broadcast ω on every
``broadcast_every`` ticks with sequence number n // every; a message sent at tick m with
an emulated delay d is usable from the first tick at or after t_m + d, and never before
tick m + 1 (a message sent after a vehicle's update is used at its neighbours' next one).
"""

from __future__ import annotations

import math
from typing import Any

CLOCKS = ("lockstep", "realtime")  # who drives time in a fleet of processes (docs/architecture.md)


def broadcast_every(rates: Any) -> int:
    """Control ticks per ω broadcast (the broadcast rate rounded to a divisor of the control rate)."""
    return max(1, round(rates.control / rates.broadcast))


def delivery_tick(send_tick: int, delay: float, period: float) -> int:
    """The first control tick at which a message sent at ``send_tick`` with ``delay`` is usable."""
    return max(send_tick + 1, math.ceil(send_tick + delay / period - 1e-9))


def send_tick(t_send: float, period: float) -> int:
    """The tick a message stamped ``t_send`` (simulated seconds) was sent at."""
    return int(round(t_send / period))


def last_broadcast_seq(tick: int, every: int) -> int:
    """Sequence number of the newest broadcast sent at or before ``tick`` (-1: none yet)."""
    return -1 if tick < 0 else tick // every


def total_ticks(duration: float, period: float) -> int:
    """Index of the last tick of a run of ``duration`` (ticks 0..N inclusive)."""
    return int(round(duration / period))
