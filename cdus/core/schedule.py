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

from cdus.core.vocabulary import CLOCKS  # noqa: F401  (the agents and the world take it from here)


def broadcast_every(rates: Any) -> int:
    """Control ticks per ω broadcast (the broadcast rate rounded to a divisor of the control rate)."""
    return max(1, round(rates.control / rates.broadcast))


def delivery_tick(send_tick: int, delay: float, period: float) -> int:
    """The first control tick at which a message sent at ``send_tick`` with ``delay`` is usable."""
    return max(send_tick + 1, math.ceil(send_tick + delay / period - 1e-9))


def delay_floor(delay: Any) -> float:
    """The least delay (s) the link emulator can give one copy of a message under ``delay``
    (a :class:`cdus.core.linkspec.Delay`; cdus.core.link.draw_delay, clipped at 0; per-link FIFO
    only ever adds to it): uniform base - jitter, pareto base, normal base only without jitter
    (its tail is unbounded below, clipped at 0)."""
    if not delay.active:
        return 0.0
    if delay.distribution == "uniform":
        low = delay.base + delay.jitter * -1.0  # draw_delay's expression at u1 = 0, rounded alike
    elif delay.distribution == "pareto":
        low = delay.base
    else:
        low = delay.base if delay.jitter == 0.0 else 0.0
    return low if low > 0.0 else 0.0


def first_seq_at(t: float, every: int, period: float) -> int:
    """The first broadcast seq whose send time ``(seq * every) * period`` is at or after ``t``
    (the emulator puts a message in the epoch starting at or before its send time)."""
    if t <= 0.0 or t != t:
        return 0
    s = max(0, math.ceil(t / (every * period)))
    while s > 0 and (s - 1) * every * period >= t:
        s -= 1
    while s * every * period < t:
        s += 1
    return s


def needed_seq(n: int, every: int, period: float, floors: Any) -> int:
    """The newest broadcast seq of a neighbour that tick ``n`` can use: sent before ``n`` and,
    with the link's guaranteed least delay, usable by ``n`` (:func:`delivery_tick`); -1: none.

    ``floors``: the link's epochs as ``(first seq, least delay s)``, by first seq. A message
    sent at tick m under a least delay f is usable no earlier than ``delivery_tick(m, f)``
    (monotone in the delay and in m), so a message this tick cannot use yet is never waited
    for. Epochs can lower the delay: the newest seq usable is the greatest over the epochs."""
    if n <= 0:
        return -1
    hi = (n - 1) // every
    best = -1
    for first, floor in reversed(floors):
        if hi < first:
            continue
        lag = max(1, math.ceil(floor / period - 1e-9))
        s = max(first - 1, min(hi, (n - lag) // every))
        while s >= first and delivery_tick(s * every, floor, period) > n:
            s -= 1
        while s < hi and delivery_tick((s + 1) * every, floor, period) <= n:
            s += 1
        if s >= first:
            best = max(best, s)
        hi = first - 1
        if hi <= best:
            break
    return best


def send_tick(t_send: float, period: float) -> int:
    """The tick a message stamped ``t_send`` (simulated seconds) was sent at."""
    return int(round(t_send / period))


def last_broadcast_seq(tick: int, every: int) -> int:
    """Sequence number of the newest broadcast sent at or before ``tick`` (-1: none yet)."""
    return -1 if tick < 0 else tick // every


def total_ticks(duration: float, period: float) -> int:
    """Index of the last tick of a run of ``duration`` (ticks 0..N inclusive)."""
    return int(round(duration / period))
